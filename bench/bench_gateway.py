"""Gateway benchmarks (Python; bench/run.py picks them up through compare_gateway.py, and
gateway_bench.py writes bench/RESULTS.gateway.md):

- replay_fidelity: 5 channels x 2560 Hz on python-can's virtual bus, paced by the recorded clock:
  dynval's scheduler (absolute deadlines, sleep then poll the last 0.3 ms) vs python-can's
  MessageSync player on the same frames in the same run; send-time error = return of
  bus.send - due time; a receiver thread counts what arrived (loss).
- replay_asap: frames/s sent as fast as the virtual bus takes them, all received.
- mcap_write: dynval's logger (decode + raw + decoded topics, JSON, zstd, chunk CRCs) vs the
  mcap library's raw Writer adding the 8-byte frames, same compression and chunk size.
- log_1h: a synthetic 1-hour test (5 x 640 Hz = 3.84 M sample frames) streamed into the logger:
  peak RSS (ru_maxrss) at 10 % and at the end; bounded = no growth with the length.
"""
from __future__ import annotations

import os
import resource
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from dynval import bus
from dynval.io.recording import Channel, Recording
from dynval.mcap_log import McapLog


def _rec(seconds: float, fs: int = 2560, nch: int = 5) -> Recording:
    n = int(seconds * fs)
    rng = np.random.default_rng(7)
    return Recording("bench", float(fs), [Channel(f"c{i}", rng.standard_normal(n))
                                          for i in range(nch)])


class _Rx:
    def __init__(self, channel: str) -> None:
        import can

        self.bus = can.Bus(interface="virtual", channel=channel)
        self.n = 0
        self._stop = threading.Event()
        self.t = threading.Thread(target=self._run, daemon=True)
        self.t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            if self.bus.recv(0.05) is not None:
                self.n += 1

    def close(self) -> int:
        time.sleep(0.3)
        self._stop.set()
        self.t.join()
        self.bus.shutdown()
        return self.n


def replay_fidelity(seconds: float = 4.0) -> dict[str, dict[str, float]]:
    import can

    plan = bus.make_plan(_rec(seconds))
    out: dict[str, dict[str, float]] = {}
    rx = _Rx("bench-fid")
    tx = can.Bus(interface="virtual", channel="bench-fid")
    res = bus.replay(tx, plan)
    got = rx.close()
    out["dynval"] = {**res.timing, "lost": float(res.frames_sent - got)}
    # python-can's player on the same frames, due times as message timestamps
    msgs = []
    for off, frames in plan.batches():
        for cid, data in frames:
            msgs.append(can.Message(timestamp=off / 1e9, arbitration_id=cid, data=data,
                                    is_extended_id=False))
    rx = _Rx("bench-fid2")
    tx2 = can.Bus(interface="virtual", channel="bench-fid2")
    st = bus.TimingStats()
    t0 = None
    for m in can.MessageSync(msgs, timestamps=True):
        tx2.send(m)
        now = time.perf_counter_ns()
        if t0 is None:
            t0 = now - int(m.timestamp * 1e9)
        st.add_batch(m.timestamp, [now - (t0 + int(m.timestamp * 1e9))])
    got = rx.close()
    out["messagesync"] = {**st.report(), "lost": float(len(msgs) - got)}
    tx.shutdown()
    tx2.shutdown()
    return out


def replay_asap(seconds: float = 4.0) -> dict[str, float]:
    import can

    plan = bus.make_plan(_rec(seconds))
    rx = _Rx("bench-asap")
    tx = can.Bus(interface="virtual", channel="bench-asap")
    res = bus.replay(tx, plan, asap=True)
    got = rx.close()
    tx.shutdown()
    return {"frames": float(res.frames_sent), "frames_per_s": res.frames_per_s,
            "lost": float(res.frames_sent - got)}


def _frames(n: int) -> list[tuple[int, bytes]]:
    rng = np.random.default_rng(1)
    raw = rng.integers(-30000, 30000, size=(n, 3))
    return [bus.encode_samples(k % 5, k // 5, raw[k]) for k in range(n)]


def mcap_write(n: int = 60000) -> dict[str, dict[str, float]]:
    from mcap.writer import Writer

    from dynval.mcap_log import compression

    frames = _frames(n)
    out: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "ours.mcap"
        t0 = time.perf_counter()
        lg = McapLog(p, channel_names=[f"c{i}" for i in range(5)])
        lg.on_frame(0, *bus.encode_chcfg(0, 2560, 2.0 ** -10))
        for k, (cid, data) in enumerate(frames):
            lg.on_frame(k * 78125, cid, data)
        s = lg.close()
        dt = time.perf_counter() - t0
        msgs = sum(s["messages"].values())
        out["dynval_logger"] = {"frames_per_s": n / dt, "messages_per_s": msgs / dt,
                                "mb_per_s": p.stat().st_size / dt / 1e6,
                                "file_mb": p.stat().st_size / 1e6, "messages": float(msgs)}
        q = Path(d) / "raw.mcap"
        t0 = time.perf_counter()
        with open(q, "wb") as f:
            w: Any = Writer(f, chunk_size=512 * 1024, compression=compression())
            w.start()
            sid = w.register_schema("can", "", b"")
            cid_ = w.register_channel("/can/raw", "", sid)
            for k, (_cid, data) in enumerate(frames):
                w.add_message(cid_, log_time=k * 78125, data=data, publish_time=k * 78125)
            w.finish()
        dt = time.perf_counter() - t0
        out["mcap_raw_writer"] = {"frames_per_s": n / dt, "messages_per_s": n / dt,
                                  "mb_per_s": q.stat().st_size / dt / 1e6,
                                  "file_mb": q.stat().st_size / 1e6, "messages": float(n)}
    return out


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def log_1h(seconds: float = 3600.0, fs: int = 640, nch: int = 5) -> dict[str, float]:
    """Stream a synthetic test into the logger without holding it: frames are made on the fly."""
    n_frames = int(seconds * fs / 3) * nch
    rng = np.random.default_rng(2)
    block = rng.integers(-30000, 30000, size=(4096, 3))
    rss0 = _rss_mb()
    rss10 = 0.0
    with tempfile.TemporaryDirectory(dir=os.environ.get("DV_BENCH_TMP")) as d:
        p = Path(d) / "1h.mcap"
        t0 = time.perf_counter()
        lg = McapLog(p, channel_names=[f"c{i}" for i in range(nch)])
        for c in range(nch):
            lg.on_frame(0, *bus.encode_chcfg(c, fs, 2.0 ** -10))
        dt_ns = int(3e9 / fs)
        for k in range(n_frames):
            lg.on_frame((k // nch) * dt_ns, *bus.encode_samples(k % nch, k // nch,
                                                                block[k % 4096]))
            if k == n_frames // 10:
                rss10 = _rss_mb()
        lg.close()
        wall = time.perf_counter() - t0
        size = p.stat().st_size
    return {"frames": float(n_frames), "wall_s": wall, "file_mb": size / 1e6,
            "rss_start_mb": rss0, "rss_at_10pct_mb": rss10, "rss_peak_mb": _rss_mb()}
