"""Gateway benchmarks (Python; bench/run.py picks them up through compare_gateway.py, and
gateway_bench.py writes bench/RESULTS.gateway.md):

- replay_fidelity: 5 channels x 2560 Hz on python-can's virtual bus, paced by the recorded clock:
  dynval's scheduler (absolute deadlines, sleep then poll the last 0.3 ms) vs python-can's
  MessageSync player on the same frames in the same run; send-time error = return of
  bus.send - due time; a receiver thread counts what arrived (loss).
- replay_asap: frames/s sent as fast as the virtual bus takes them, all received.
- mcap_write: dynval's logger as `dynval log` runs it (the bus reader's AsyncLog.put per frame,
  the writer thread decoding blocks with the C codec, every topic, lz4, chunk CRCs) vs the
  mcap library's raw Writer adding the 8-byte frames (same compression), each in its own
  process (peak RSS), interleaved repeats, medians and the median of the per-pair ratios.
- log_bus_16x5k: 16 channels x 5 kHz paced on python-can's virtual bus into log_bus (the
  reader thread of `dynval log`): frames sent, logged, dropped, sequence gaps in the file.
- log_1h: a synthetic 1-hour test (5 x 640 Hz = 3.84 M sample frames) streamed into the logger:
  peak RSS (ru_maxrss) at 10 % and at the end; bounded = no growth with the length.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import resource
import statistics
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


def _frames(n: int, nch: int = 5) -> list[tuple[int, bytes]]:
    """n DV_SAMPLES frames of nch channels, a random walk in counts (signal-like for zstd)."""
    rng = np.random.default_rng(1)
    raw = (np.cumsum(rng.standard_normal((n, 3)), axis=0) * 50).astype(np.int64) % 30000
    return [bus.encode_samples(k % nch, k // nch, raw[k]) for k in range(n)]


def _write_child(kind: str, n: int, q: Any) -> None:
    """One writer in a fresh process: frames/s, messages/s, MB/s, file MB, peak RSS."""
    import can
    from mcap.writer import Writer

    from dynval.mcap_log import AsyncLog, compression

    frames = _frames(n)
    dt_ns = 78125  # 5 channels x 2560 Hz: a frame every 78 us
    with tempfile.TemporaryDirectory(dir=os.environ.get("DV_BENCH_TMP")) as d:
        p = Path(d) / f"{kind}.mcap"
        _warm_up(Path(d), frames[:2000])
        if kind == "dynval_logger":
            msgs = [can.Message(timestamp=1.7e9 + k * dt_ns / 1e9, arbitration_id=cid,
                                data=data, is_extended_id=False)
                    for k, (cid, data) in enumerate(frames)]
            rss0 = _rss_mb()
            t0 = time.perf_counter()
            lg = McapLog(p, channel_names=[f"c{i}" for i in range(5)])
            lg.on_frame(0, *bus.encode_chcfg(0, 2560, 2.0 ** -10))
            w = AsyncLog(lg)
            for m in msgs:
                w.put(m)
            w.close()
            s = lg.close()
            dt = time.perf_counter() - t0
            msgs_n = float(sum(s["messages"].values()))
        else:
            rss0 = _rss_mb()
            t0 = time.perf_counter()
            with open(p, "wb") as f:
                wr: Any = Writer(f, chunk_size=512 * 1024, compression=compression())
                wr.start()
                sid = wr.register_schema("can", "", b"")
                cid_ = wr.register_channel("/can/raw", "", sid)
                for k, (_cid, data) in enumerate(frames):
                    wr.add_message(cid_, log_time=k * dt_ns, data=data, publish_time=k * dt_ns)
                wr.finish()
            dt = time.perf_counter() - t0
            msgs_n = float(n)
        size = p.stat().st_size
    q.put({"frames_per_s": n / dt, "messages_per_s": msgs_n / dt, "mb_per_s": size / dt / 1e6,
           "file_mb": size / 1e6, "messages": msgs_n, "rss_before_mb": rss0,
           "rss_peak_mb": _rss_mb()})


def _warm_up(d: Path, frames: list[tuple[int, bytes]]) -> None:
    """Both writers once on a few frames before the clock starts (cffi parses each C type on
    first use, ~0.3 s; imports, allocators)."""
    from mcap.writer import Writer

    with McapLog(d / "warm.mcap", channel_names=[f"c{i}" for i in range(5)]) as lg:
        lg.on_frame(0, *bus.encode_chcfg(0, 2560, 2.0 ** -10))
        lg.on_frame(0, *bus.encode_ctrl(bus.CTRL_START, 1))
        for k, (cid, data) in enumerate(frames):
            lg.on_frame(k, cid, data)
    with open(d / "warm_raw.mcap", "wb") as f:
        w: Any = Writer(f)
        w.start()
        c = w.register_channel("/can/raw", "", w.register_schema("can", "", b""))
        for k, (_cid, data) in enumerate(frames):
            w.add_message(c, log_time=k, data=data, publish_time=k)
        w.finish()


def _in_child(kind: str, n: int) -> dict[str, float]:
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    pr = ctx.Process(target=_write_child, args=(kind, n, q))
    pr.start()
    r: dict[str, float] = q.get(timeout=600)
    pr.join()
    return r


def mcap_write(n: int = 60000, reps: int = 5) -> dict[str, dict[str, float]]:
    """dynval's logger and mcap's raw writer, alternating, each rep in fresh processes."""
    runs: dict[str, list[dict[str, float]]] = {"dynval_logger": [], "mcap_raw_writer": []}
    for _ in range(reps):
        for kind in runs:
            runs[kind].append(_in_child(kind, n))
    out = {k: {f: statistics.median(r[f] for r in v) for f in v[0]} for k, v in runs.items()}
    ratios = [a["frames_per_s"] / b["frames_per_s"]
              for a, b in zip(runs["dynval_logger"], runs["mcap_raw_writer"], strict=True)]
    out["dynval_logger"]["ratio_median"] = statistics.median(ratios)
    out["dynval_logger"]["ratio_min"] = min(ratios)
    out["dynval_logger"]["ratio_max"] = max(ratios)
    out["dynval_logger"]["reps"] = float(reps)
    return out


def log_bus_16x5k(seconds: float = 10.0, nch: int = 16, fs: int = 5000,
                  paced: bool = True) -> dict[str, float]:
    """nch x fs Hz on the virtual bus (a sender thread, frames due at their last sample's
    time; unpaced: as fast as it can send) into log_bus (the reader of `dynval log`) in this
    thread."""
    import can

    from dynval.io.mcapfile import iter_messages
    from dynval.mcap_log import log_bus

    n_per = int(seconds * fs) // bus.SAMPLES_PER_FRAME
    rng = np.random.default_rng(3)
    raw = rng.integers(-30000, 30000, size=(4096, 3))
    setup = [(bus.ID_CTRL, bus.encode_ctrl(bus.CTRL_CLEAR)[1])]
    setup += [bus.encode_chcfg(c, fs, 2.0 ** -10) for c in range(nch)]
    setup.append(bus.encode_ctrl(bus.CTRL_START, 1))
    chan = f"bench-16x5k-{os.getpid()}"
    tx = can.Bus(interface="virtual", channel=chan)
    rx = can.Bus(interface="virtual", channel=chan)
    done = threading.Event()
    late_ns: list[int] = []

    def msg(cid: int, data: bytes) -> Any:
        return can.Message(arbitration_id=cid, data=data, is_extended_id=False)

    # every frame made before the clock starts: the sender thread only paces and sends
    first = [msg(*f) for f in setup]
    batches = [[msg(*bus.encode_samples(c, k, raw[(k * nch + c) % 4096])) for c in range(nch)]
               for k in range(n_per)]

    def send() -> None:
        for m in first:
            tx.send(m)
        t0 = time.perf_counter_ns() + 5_000_000
        period = bus.SAMPLES_PER_FRAME * 1e9 / fs
        for k, batch in enumerate(batches):
            due = t0 + int((k + 1) * period)
            if paced:
                bus.wait_until(due)
            for m in batch:
                tx.send(m)
            if paced:
                late_ns.append(time.perf_counter_ns() - due)
        done.set()

    with tempfile.TemporaryDirectory(dir=os.environ.get("DV_BENCH_TMP")) as d:
        p = Path(d) / "16x5k.mcap"
        lg = McapLog(p, channel_names=[f"c{i}" for i in range(nch)])
        rss0 = _rss_mb()
        th = threading.Thread(target=send, daemon=True)
        t0 = time.perf_counter()
        th.start()
        n = log_bus(rx, lg, idle_timeout_s=0.5)
        wall = time.perf_counter() - t0 - 0.5
        th.join()
        s = lg.close()
        tx.shutdown()
        rx.shutdown()
        per = {f"/dv/samples/c{c}": 0 for c in range(nch)}
        for m in iter_messages(p, prefix="/dv/samples/"):
            per[m.topic] += 1
        size = p.stat().st_size
    sent = len(setup) + n_per * nch
    lost = sum(v["lost"] for v in s["sequence"].values())
    return {"channels": float(nch), "fs_hz": float(fs), "seconds": seconds,
            "frames_sent": float(sent), "frames_received": float(n),
            "frames_per_s": n_per * nch / wall, "dropped": float(s["events"].get("logger_overflow", 0)),
            "seq_lost": float(lost), "events": float(sum(s["events"].values())),
            "samples_in_file_min": float(min(per.values())),
            "samples_expected": float(n_per * bus.SAMPLES_PER_FRAME),
            "file_mb": size / 1e6, "rss_peak_mb": _rss_mb(), "rss_before_mb": rss0,
            "send_late_p95_us": float(np.percentile(late_ns, 95)) / 1e3 if late_ns else 0.0}


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


def logger_cpu_split(n: int = 61440, reps: int = 7) -> dict[str, float]:
    """CPU time per frame (process time, the minimum of reps: the least disturbed by other
    jobs) of each part of the logger, run one after the other in this thread: the reader's
    AsyncLog.put, the writer thread's reading of the python-can Messages' fields
    (AsyncLog._log without on_frames), its decoding and record building (McapLog.on_frames,
    chunks not finished) and the I/O thread's finishing of chunks (BlockWriter._write_chunk:
    lz4, CRC, message indexes, the write)."""
    import can

    from dynval.mcap_log import AsyncLog

    frames = _frames(n)
    msgs = [can.Message(timestamp=1.7e9 + k * 78125e-9, arbitration_id=cid, data=data,
                        is_extended_id=False) for k, (cid, data) in enumerate(frames)]
    blocks = [msgs[i:i + AsyncLog.BLOCK_FRAMES] for i in range(0, n, AsyncLog.BLOCK_FRAMES)]
    chunks: list[tuple[Any, ...]] = []
    out: dict[str, list[float]] = {"put": [], "fields": [], "records": [], "chunks": []}

    class Sink:  # on_frames' stand-in: the fields' part alone
        def on_frames(self, *a: Any) -> None:
            pass

    with tempfile.TemporaryDirectory(dir=os.environ.get("DV_BENCH_TMP")) as d:
        for _ in range(reps):
            w = AsyncLog.__new__(AsyncLog)
            w.error, w._block, w._since = None, [], time.monotonic()
            w.hand_off = lambda w=w: setattr(w, "_block", [])  # type: ignore[method-assign]
            t0 = time.process_time()
            for m in msgs:
                w.put(m)
            out["put"].append(time.process_time() - t0)
            w.out = Sink()  # type: ignore[assignment]
            t0 = time.process_time()
            for b in blocks:
                w._log(b)
            out["fields"].append(time.process_time() - t0)
            lg = McapLog(Path(d) / "split.mcap", channel_names=[f"c{i}" for i in range(5)])
            lg.on_frame(0, *bus.encode_chcfg(0, 2560, 2.0 ** -10))
            lg._drain()
            lg._w.sync()
            chunks.clear()
            real = lg._w._write_chunk
            lg._w._write_chunk = lambda p, i: chunks.append((p, i))  # type: ignore[method-assign]
            w.out = lg
            t_fields = out["fields"][-1]
            t0 = time.process_time()
            for b in blocks:
                w._log(b)
            lg._w.flush()
            lg._w.sync()
            out["records"].append(time.process_time() - t0 - t_fields)
            t0 = time.process_time()
            for p, i in chunks:
                real(p, i)
            out["chunks"].append(time.process_time() - t0)
            lg._w._write_chunk = real  # type: ignore[method-assign]
            lg.close()
    return {k: min(v) / n * 1e6 for k, v in out.items()}
