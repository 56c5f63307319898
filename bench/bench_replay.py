"""Replay pacing on the host: `dynval replay`'s Python scheduler (bus.replay, pacing in
dynval.pacing) beside python-can's MessageSync player on python-can's virtual bus, and the C
pacer `dynval replay` uses on SocketCAN (dv_pacer, firmware_sim/pacer.c; this host has no
SocketCAN, so into its file sink /dev/null: the pacing alone), on the same frames in the same
run, at about 4,300 and 13,000 frames/s. Writes bench/RESULTS.replay.md (bench/run.py appends
it to bench/RESULTS.md). dv_pacer is built with cmake (-DDV_BUILD_SIM=ON, target dv_pacer) or
given as $DV_PACER; without it its rows are left out.

    python3 bench/bench_replay.py [--seconds 60] [--quick]

Each player sends the same frames (5 channels of DV_SAMPLES frames, each due at the time of its
last sample) on its own virtual channel; after the run a receiver on that channel takes what
arrived and compares it with the plan (lost = frames missing or out of order). The receiver
drains after the run, not during it: a receiving thread in the process would share the GIL with
the player, a measure of the bus receiver rather than of the pacing. Error of a frame = the time
bus.send returned minus its due time, start + offset (start: the player's own start).
Drift = least-squares slope of the error over the run, times the run's length. Each player
runs as it is (normal priority) and under SCHED_FIFO (`--realtime`:
dynval.pacing.tight_timing, the same for both players). Host steal = the time the hypervisor
ran other guests on this machine's CPUs during the run (/proc/stat): a stall no player can
avoid.
"""
from __future__ import annotations

import argparse
import logging
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_gateway import _rec  # noqa: E402

from dynval import bus  # noqa: E402
from dynval.pacing import find_pacer, pacer_records, run_pacer, tight_timing  # noqa: E402

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


def run_dv_pacer(plan: bus.Plan, realtime: bool, tag: str) -> dict[str, float]:
    """dv_pacer into /dev/null (what it sends is checked by gateway/tests/test_pacer.py)."""
    exe = find_pacer()
    assert exe is not None
    res = run_pacer(exe, plan.batches(), sink=Path("/dev/null"), realtime=realtime)
    return {**res.timing, "lost": float(plan.n_frames - res.frames_sent)}


PLAYERS = {"dynval": run_dynval, "messagesync": run_messagesync, "dv_pacer": run_dv_pacer}


def _steal_s() -> float:
    """Steal time of all CPUs so far (Linux /proc/stat), s."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
        return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return math.nan


def measure(seconds: float) -> list[dict[str, Any]]:
    players = {k: v for k, v in PLAYERS.items() if k != "dv_pacer" or find_pacer() is not None}
    rows = []
    for nch, fs in RATES:
        plan = bus.make_plan(_rec(seconds, fs=fs, nch=nch))
        rate = plan.n_sample_frames / (plan.rec.n_samples / fs)
        for realtime in (False, True):
            for who, fn in players.items():
                log.info("%d x %d Hz, %s%s", nch, fs, who, " realtime" if realtime else "")
                load, steal = os.getloadavg()[0], _steal_s()
                r = fn(plan, realtime, f"{fs}-{who}-{realtime}")
                rows.append({"who": who, "realtime": realtime, "nch": nch, "fs": fs,
                             "rate": rate, "load": load, "steal_ms": 1e3 * (_steal_s() - steal),
                             **r})
    return rows


# ---- on a real SocketCAN vcan (inside the QEMU VM of ../shared/vcan: --vcan) ----------------
def _candump(iface: str, path: Path) -> subprocess.Popen[bytes]:
    """candump -L: every frame on iface with its kernel receive time, into path."""
    f = path.open("wb")
    p = subprocess.Popen(["candump", "-L", iface], stdout=f)
    f.close()
    time.sleep(0.5)
    return p


def _vcan_errors(plan: bus.Plan, dump: Path) -> dict[str, float]:
    """Errors of the frames candump saw: receive time minus due time, the due times placed so
    that the player's earliest frame (relative to its due time) is on time: the same rule for
    every player, whose start we do not see. A frame not seen counts as lost (each received
    frame is matched to the next equal planned frame within LOOKAHEAD)."""
    want = [(off, cid, data) for off, frames in plan.batches() for cid, data in frames]
    seen: list[tuple[int, float]] = []  # (plan index, receive time)
    k = 0
    for line in dump.read_text().splitlines():
        ts, _, frame = line.split()
        cid, _, hexdata = frame.partition("#")
        key = (int(cid, 16), bytes.fromhex(hexdata))
        for j in range(k, min(k + LOOKAHEAD, len(want))):
            if want[j][1:] == key:
                seen.append((j, float(ts.strip("()"))))
                k = j + 1
                break
    st = bus.TimingStats()
    if seen:
        t0 = min(t - want[j][0] / 1e9 for j, t in seen)
        for j, t in seen:
            st.add_batch(want[j][0] / 1e9, [round((t - t0 - want[j][0] / 1e9) * 1e9)])
    return {**st.report(), "lost": float(len(want) - len(seen))}


LOOKAHEAD = 5000  # frames


def vcan_run(plan: bus.Plan, who: str, iface: str, tmp: Path) -> dict[str, float]:
    import can

    dump = tmp / f"{who.replace(' ', '')}.log"
    rx = _candump(iface, dump)
    try:
        if who.startswith("dv_pacer"):
            exe = find_pacer()
            assert exe is not None
            res = run_pacer(exe, plan.batches(), interface=iface, realtime=who.endswith("fifo"))
            log.info("dv_pacer's own report: %s", res.timing)
        elif who.startswith("canplayer"):
            log_in = tmp / "in.log"
            with log_in.open("w") as f:
                for off, frames in plan.batches():
                    for cid, data in frames:
                        f.write(f"({off // 10**9}.{off % 10**9 // 1000:06d}) {iface} "
                                f"{cid:03X}#{data.hex().upper()}\n")
            # by default canplayer sends what is due, then sleeps its gap (-g, 1 ms)
            gap = ["-g", "0"] if who.endswith("-g 0") else []
            subprocess.run(["canplayer", *gap, "-I", str(log_in)], check=True)
        else:  # python-can's MessageSync on the socketcan bus
            msgs = [can.Message(timestamp=off / 1e9, arbitration_id=cid, data=data,
                                 is_extended_id=False)
                    for off, frames in plan.batches() for cid, data in frames]
            with can.Bus(interface="socketcan", channel=iface) as tx:
                for m in can.MessageSync(msgs, timestamps=True):
                    tx.send(m)
        time.sleep(0.5)
    finally:
        rx.send_signal(signal.SIGINT)
        rx.wait()
    r = _vcan_errors(plan, dump)
    dump.unlink()  # the VM's tmpfs is small
    return r


def vm_prepare(seconds: float, d: Path, iface: str = "vcan0") -> None:
    """The frames of each rate for bench/replay_vcan_vm.sh: dv_pacer's input (in_FS.bin) and
    the same frames as a candump log for canplayer (in_FS.log)."""
    for nch, fs in RATES:
        plan = bus.make_plan(_rec(seconds, fs=fs, nch=nch))
        with (d / f"in_{fs}.bin").open("wb") as f:
            for block in pacer_records(plan.batches()):
                f.write(block)
        with (d / f"in_{fs}.log").open("w") as f:
            for off, frames in plan.batches():
                for cid, data in frames:
                    f.write(f"({off // 10**9}.{off % 10**9 // 1000:06d}) {iface} "
                            f"{cid:03X}#{data.hex().upper()}\n")


def vm_collect(seconds: float, d: Path) -> list[dict[str, Any]]:
    """The table rows of the dumps bench/replay_vcan_vm.sh left in d."""
    rows = []
    for nch, fs in RATES:
        plan = bus.make_plan(_rec(seconds, fs=fs, nch=nch))
        rate = plan.n_sample_frames / (plan.rec.n_samples / fs)
        for who in ("dv_pacer", "dv_pacer_fifo", "canplayer", "canplayer_g0"):
            dump = d / f"{fs}.{who}.dump"
            if dump.is_file():
                r = _vcan_errors(plan, dump)
                rows.append({"who": who.removesuffix("_fifo").replace("_g0", " -g 0"),
                             "realtime": who.endswith("fifo"), "nch": nch, "fs": fs,
                             "rate": rate, **r})
    return rows


VCAN_PLAYERS = ("dv_pacer", "dv_pacer_fifo", "canplayer", "canplayer -g 0", "messagesync")


def measure_vcan(seconds: float, iface: str) -> list[dict[str, Any]]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for nch, fs in RATES:
            plan = bus.make_plan(_rec(seconds, fs=fs, nch=nch))
            rate = plan.n_sample_frames / (plan.rec.n_samples / fs)
            for who in VCAN_PLAYERS:
                log.info("vcan %d x %d Hz, %s", nch, fs, who)
                r = vcan_run(plan, who, iface, Path(d))
                rows.append({"who": who.removesuffix("_fifo"), "realtime": who.endswith("fifo"),
                             "nch": nch, "fs": fs, "rate": rate, "load": os.getloadavg()[0],
                             "steal_ms": math.nan, **r})
    return rows


def table(rows: list[dict[str, Any]], seconds: float) -> list[str]:
    cpu = platform.processor() or platform.machine()
    L = [f"# Replay pacing ({time.strftime('%Y-%m-%d')}, {cpu}, Python "
         f"{platform.python_version()})", "",
         f"Made by `python3 bench/bench_replay.py --seconds {seconds:g}` (code and method in its "
         f"docstring): {seconds:g} s per run, every player on the same frames in the same run, "
         f"on this {os.cpu_count()}-core host shared with other jobs (load = its 1-minute load "
         "average when the run started). dynval and messagesync: python-can's `virtual` bus, "
         "error = time bus.send returned minus the frame's due time. dv_pacer: the C pacer of "
         "`dynval replay` on SocketCAN, into /dev/null here (no SocketCAN on this host), error "
         "= time its sendmmsg returned minus the due time. Target: p95 <= 100 us, max <= 1 ms, "
         "drift over the run <= 100 us, nothing lost.", "",
         *_rows(rows, host=True)]
    return L


def _rows(rows: list[dict[str, Any]], host: bool) -> list[str]:
    """The table of runs; host adds the load and the hypervisor's steal during each run."""
    extra = " load | host steal ms |" if host else ""
    L = ["| frames/s | channels x Hz | player | priority | frames | mean us | p95 us | max us "
         f"| drift us over run | lost |{extra} target met |",
         "|---" * (13 if host else 11) + "|"]
    for r in rows:
        ok = (r["p95_us"] <= 100 and r["max_us"] <= 1000 and abs(r["drift_us_over_run"]) <= 100
              and r["lost"] == 0)
        more = f" {r['load']:.1f} | {r['steal_ms']:.0f} |" if host else ""
        L.append(f"| {r['rate']:.0f} | {r['nch']} x {r['fs']} | {r['who']} | "
                 f"{'SCHED_FIFO' if r['realtime'] else 'normal'} | {int(r['frames'])} | "
                 f"{r['mean_us']:.1f} | {r['p95_us']:.0f} | {r['max_us']:.0f} | "
                 f"{r['drift_us_over_run']:+.1f} | {int(r['lost'])} |{more} "
                 f"{'yes' if ok else '**no**'} |")
    return L


def vcan_table(rows: list[dict[str, Any]], seconds: float, how: str = "") -> list[str]:
    how = how or f"`python3 bench/bench_replay.py --vcan vcan0 --seconds {seconds:g}`"
    L = ["", f"## On a real SocketCAN vcan ({seconds:g} s per run, QEMU VM)", "",
         f"{how} inside the VM of "
         "../shared/vcan (Debian's kernel, software emulation: TCG, 2 vCPUs, ~3-5x slower than "
         "the host; its clocks and timers are emulated). Every player on the same frames; "
         "error = the kernel receive time of candump -L on vcan0 minus the frame's due time, "
         "due times placed so that each player's earliest frame is on time; lost = not seen by "
         "candump. dv_pacer = `dynval replay` on SocketCAN (SCHED_FIFO = --realtime); "
         "canplayer = can-utils 2020.11 (by default it "
         "sends what is due, then sleeps its gap, -g 1 ms); messagesync = python-can's player "
         "on its socketcan bus.", "",
         *_rows(rows, host=False)]
    return L


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=60.0, help="length of each run")
    ap.add_argument("-o", type=Path,
                    default=Path(__file__).resolve().parent / "RESULTS.replay.md")
    ap.add_argument("--vcan", metavar="IFACE", help="measure on this SocketCAN interface "
                    "(dv_pacer, canplayer, MessageSync; receiver: candump) and append the table "
                    "to -o; run inside the VM: see the module docstring")
    ap.add_argument("--vm-prepare", type=Path, metavar="DIR", help="write the frames for "
                    "bench/replay_vcan_vm.sh (C players only: the VM runs Python too slowly)")
    ap.add_argument("--vm-collect", type=Path, metavar="DIR", help="append the table of the "
                    "dumps bench/replay_vcan_vm.sh left in DIR to -o")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if a.vm_prepare:
        vm_prepare(a.seconds, a.vm_prepare)
        return 0
    if a.vm_collect:
        with a.o.open("a") as f:
            how = (f"`bench_replay.py --seconds {a.seconds:g} --vm-prepare DIR` on the host, "
                   "`bench/replay_vcan_vm.sh DIR OUT build/sim/firmware_sim/dv_pacer`")
            f.write("\n".join(vcan_table(vm_collect(a.seconds, a.vm_collect), a.seconds, how))
                    + "\n\n(then `--vm-collect OUT` on the host)\n")
        return 0
    if a.vcan:
        rows = measure_vcan(a.seconds, a.vcan)
        with a.o.open("a") as f:
            f.write("\n".join(vcan_table(rows, a.seconds)) + "\n")
        return 0
    rows = measure(a.seconds)
    text = "\n".join(table(rows, a.seconds)) + "\n"
    log.info("%s", text)
    a.o.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
