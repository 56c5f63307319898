"""Replay pacing on python-can's virtual bus: `dynval replay`'s scheduler (bus.replay, pacing in
dynval.pacing) beside python-can's MessageSync player on the same frames in the same run, at
about 4,300 and 13,000 frames/s, and writes bench/RESULTS.replay.md (bench/run.py appends it to
bench/RESULTS.md).

    python3 bench/bench_replay.py [--seconds 60] [--quick]

Each player sends the same frames (5 channels of DV_SAMPLES frames, each due at the time of its
last sample) on its own virtual channel; after the run a receiver on that channel takes what
arrived and compares it with the plan (lost = frames missing or out of order). The receiver
drains after the run, not during it: a receiving thread in the process would share the GIL with
the player, a measure of the bus receiver rather than of the pacing. Error of a frame = the time
bus.send returned minus its due time, start + offset (start: the player's own start).
Drift = least-squares slope of the error over the run, times the run's length. Each player
runs as it is (normal priority) and under SCHED_FIFO (`--realtime`:
dynval.pacing.tight_timing, the same for both players).
"""
from __future__ import annotations

import argparse
import logging
import platform
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_gateway import _rec  # noqa: E402

from dynval import bus  # noqa: E402
from dynval.pacing import tight_timing  # noqa: E402

log = logging.getLogger("bench_replay")
#: (channels, Hz): 5 x 2560 Hz = 4,267 frames/s, 5 x 7800 Hz = 13,000 frames/s
RATES = ((5, 2560), (5, 7800))


def _frames(plan: bus.Plan) -> list[tuple[int, bytes]]:
    return [f for _, frames in plan.batches() for f in frames]


def _lost(rx: Any, want: list[tuple[int, bytes]]) -> float:
    """Frames of want that did not arrive in order on rx (drained now)."""
    got = []
    while (m := rx.recv(0)) is not None:
        got.append((m.arbitration_id, bytes(m.data)))
    rx.shutdown()
    k = 0
    for f in got:  # longest prefix-matching subsequence: order and content
        if k < len(want) and f == want[k]:
            k += 1
    return float(len(want) - k)


def run_dynval(plan: bus.Plan, realtime: bool, tag: str) -> dict[str, float]:
    import can

    rx = can.Bus(interface="virtual", channel=f"br-{tag}")
    tx = can.Bus(interface="virtual", channel=f"br-{tag}")
    res = bus.replay(tx, plan, realtime=realtime)
    tx.shutdown()
    return {**res.timing, "lost": _lost(rx, _frames(plan))}


def run_messagesync(plan: bus.Plan, realtime: bool, tag: str) -> dict[str, float]:
    """python-can's player, the plan's due times as message timestamps."""
    import can

    msgs = [can.Message(timestamp=off / 1e9, arbitration_id=cid, data=data,
                        is_extended_id=False)
            for off, frames in plan.batches() for cid, data in frames]
    rx = can.Bus(interface="virtual", channel=f"br-{tag}")
    tx = can.Bus(interface="virtual", channel=f"br-{tag}")
    st = bus.TimingStats()
    with tight_timing(realtime):
        t0 = time.perf_counter_ns()
        for m in can.MessageSync(msgs, timestamps=True):
            tx.send(m)
            st.add_batch(m.timestamp, [time.perf_counter_ns() - t0 - int(m.timestamp * 1e9)])
    tx.shutdown()
    return {**st.report(), "lost": _lost(rx, _frames(plan))}


PLAYERS = {"dynval": run_dynval, "messagesync": run_messagesync}


def measure(seconds: float) -> list[dict[str, Any]]:
    rows = []
    for nch, fs in RATES:
        plan = bus.make_plan(_rec(seconds, fs=fs, nch=nch))
        rate = plan.n_sample_frames / (plan.rec.n_samples / fs)
        for realtime in (False, True):
            for who, fn in PLAYERS.items():
                log.info("%d x %d Hz, %s%s", nch, fs, who, " realtime" if realtime else "")
                r = fn(plan, realtime, f"{fs}-{who}-{realtime}")
                rows.append({"who": who, "realtime": realtime, "nch": nch, "fs": fs,
                             "rate": rate, **r})
    return rows


def table(rows: list[dict[str, Any]], seconds: float) -> list[str]:
    cpu = platform.processor() or platform.machine()
    L = [f"# Replay pacing ({time.strftime('%Y-%m-%d')}, {cpu}, Python "
         f"{platform.python_version()})", "",
         f"Made by `python3 bench/bench_replay.py --seconds {seconds:g}` (code and method in its "
         "docstring). Host, python-can's `virtual` bus, both players in the same run on the same "
         "frames. Error = time bus.send returned minus the frame's due time; target p95 <= "
         "100 us, max <= 1 ms, drift over the run <= 100 us, no loss.", "",
         "| frames/s | channels x Hz | player | priority | frames | mean us | p95 us | max us "
         "| drift us over run | lost | target met |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ok = (r["p95_us"] <= 100 and r["max_us"] <= 1000 and abs(r["drift_us_over_run"]) <= 100
              and r["lost"] == 0)
        L.append(f"| {r['rate']:.0f} | {r['nch']} x {r['fs']} | {r['who']} | "
                 f"{'SCHED_FIFO' if r['realtime'] else 'normal'} | {int(r['frames'])} | "
                 f"{r['mean_us']:.1f} | {r['p95_us']:.0f} | {r['max_us']:.0f} | "
                 f"{r['drift_us_over_run']:+.1f} | {int(r['lost'])} | "
                 f"{'yes' if ok else '**no**'} |")
    return L


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=60.0, help="length of each run")
    ap.add_argument("-o", type=Path,
                    default=Path(__file__).resolve().parent / "RESULTS.replay.md")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rows = measure(a.seconds)
    text = "\n".join(table(rows, a.seconds)) + "\n"
    log.info("%s", text)
    a.o.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
