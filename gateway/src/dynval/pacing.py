"""Pacing frames at absolute deadlines (one home for how `dynval replay` keeps time).

Deadlines are absolute times of one monotonic clock (time.perf_counter_ns: CLOCK_MONOTONIC on
Linux), start + offset / speed, so a late frame never shifts the later ones (no drift). What was
measured on the virtual bus (bench/bench_replay.py, bench/RESULTS.replay.md) and why:

- sleep to a margin before a deadline, then poll the clock: a sleep alone wakes 50 us to
  milliseconds late (the kernel's timer slack, then the scheduler). The margin is 150 us at
  SCHED_FIFO (RT_MARGIN_NS) but 40 us at normal priority (SLEEP_MARGIN_NS): on a loaded host
  a process that polls more uses more than its share of the CPU and the scheduler holds it
  back (at load 12 on 2 cores, polling 150 us, it fell seconds behind at 4,267 frames/s);
- poll without time.sleep(0) (a nanosleep: 35-90 us here) or os.sched_yield (a syscall, after
  which the sends run colder); a python-can send costs 10-15 us, 30 us after a sleep;
- the thread's timer slack at 1 ns and the interpreter's thread switch interval at 100 us
  while pacing: another Python thread (a bus receiver, a logger) otherwise keeps the GIL for
  up to 5 ms when the deadline comes;
- the cyclic garbage collector off (the pacing loop makes no reference cycles, nor does the
  MCAP logger of `dynval run`: 0 cyclic objects after 20,000 frames): a full
  collection of the interpreter's ~80,000 objects (numpy, python-can) takes ~50 ms, and
  frames queued in memory (python-can's virtual bus) make it longer;
- optionally SCHED_FIFO (realtime=True): other processes then cannot preempt the pacer.

On SocketCAN `dynval replay` hands the frames to dv_pacer (firmware_sim/pacer.c: the same
absolute deadlines with clock_nanosleep(TIMER_ABSTIME), a batch per sendmmsg), fed through a
pipe: run_pacer.
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import logging
import os
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from dynval import _core
from dynval.errors import ConfigError

log = logging.getLogger(__name__)

SLEEP_MARGIN_NS = 40_000  # sleep until this long before a deadline, poll the rest
RT_MARGIN_NS = 150_000  # the same at SCHED_FIFO: the CPU is ours when we want it
SWITCH_INTERVAL_S = 1e-4  # GIL hand-over while pacing (Python's default: 5 ms)
RT_PRIORITY = 10  # SCHED_FIFO priority of a realtime pacer: above every normal process
_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30  # prctl(2)


def wait_until(deadline_ns: int, margin_ns: int = SLEEP_MARGIN_NS) -> None:
    """Return at an absolute perf_counter_ns deadline: sleep to margin_ns before it, then poll
    the clock."""
    rem = deadline_ns - time.perf_counter_ns()
    if rem > margin_ns:
        time.sleep((rem - margin_ns) / 1e9)
    while time.perf_counter_ns() < deadline_ns:
        pass  # not sleep(0) (~40 us) nor sched_yield (a syscall: the next send runs colder)


def _prctl() -> Any:
    """libc's prctl (Linux), or None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    except OSError:
        return None
    return libc.prctl


@contextmanager
def tight_timing(realtime: bool = False) -> Iterator[None]:
    """While pacing in this thread: timer slack 1 ns, GIL switch interval SWITCH_INTERVAL_S,
    the cyclic garbage collector off, and with realtime SCHED_FIFO at RT_PRIORITY (a warning
    if the system refuses it); all restored afterwards."""
    prctl = _prctl()
    slack = int(prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)) if prctl is not None else -1
    if prctl is not None and slack > 0:
        prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    gc_was_on = gc.isenabled()
    gc.disable()
    policy = None
    if realtime:
        try:
            policy = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
        except (AttributeError, OSError) as exc:
            log.warning("realtime pacing refused (%s); pacing at normal priority (needs "
                        "CAP_SYS_NICE or an rtprio limit, see ulimit -r)", exc)
            policy = None
    try:
        yield
    finally:
        if policy is not None:
            os.sched_setscheduler(0, policy[0], policy[1])
        if gc_was_on:
            gc.enable()
        sys.setswitchinterval(interval)
        if prctl is not None and slack > 0:
            prctl(_PR_SET_TIMERSLACK, slack, 0, 0, 0)


# ---- the C pacer (firmware_sim/pacer.c) for SocketCAN ----------------------------------------
#: records of dv_pacer's stdin (struct pacer_in: offset, then Linux's struct can_frame) and
#: stdout (struct pacer_out, one per batch); host byte order
PACER_IN = struct.Struct("=qIB3x8s")
PACER_OUT = np.dtype([("offset_ns", "=i8"), ("error_ns", "=i8"), ("frames", "=u4"),
                      ("failed", "=u4")])
CAN_EFF_FLAG = 0x80000000
PIPE_BYTES = 1 << 20  # dv_pacer's input pipe: ~44,000 frames of read-ahead


def find_pacer(explicit: str | None = None) -> Path | None:
    """dv_pacer: an explicit path, $DV_PACER, on PATH, or a build of the repository this command
    runs in (build/*/firmware_sim/dv_pacer, the newest)."""
    return _core.find_program("dv_pacer", "DV_PACER", explicit)


def pacer_records(batches: Iterable[tuple[int, Sequence[tuple[int, bytes]]]],
                  extended: bool = False) -> Iterator[bytes]:
    """dv_pacer's input for (offset_ns, [(can_id, data)]) batches, a block of records per
    batch; offsets at speed 1 (the pacer divides by its speed)."""
    flag = CAN_EFF_FLAG if extended else 0
    for off, frames in batches:
        yield b"".join(PACER_IN.pack(off, cid | flag, len(data), bytes(data))
                       for cid, data in frames)


def run_pacer(exe: Path, batches: Iterable[tuple[int, Sequence[tuple[int, bytes]]]], *,
              interface: str | None = None, sink: Path | None = None, speed: float = 1.0,
              realtime: bool = False, on_progress: Callable[[int], None] | None = None,
              extended: bool = False) -> Any:
    """Send batches through dv_pacer on a SocketCAN interface (or into a sink file): a thread
    feeds its input pipe while this one reads its per-batch report into the timing statistics.
    extended: the ids are 29-bit.
    Returns a bus.ReplayResult (sample_frames: every frame sent)."""
    import fcntl

    from dynval import bus

    if (interface is None) == (sink is None):
        raise ValueError("run_pacer: give one of interface and sink")
    if not speed > 0:
        raise ConfigError(f"--speed must be > 0, got {speed}")
    cmd = [str(exe), *(("-i", interface) if interface is not None else ("-o", str(sink))),
           "-s", repr(float(speed))]
    if realtime:
        cmd += ["-r", str(RT_PRIORITY)]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdin is not None and proc.stdout is not None and proc.stderr is not None
    for pipe in (proc.stdin, proc.stdout):  # Linux: deeper pipes (read-ahead, report backlog)
        with contextlib.suppress(OSError, AttributeError):
            fcntl.fcntl(pipe.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
    feeder = threading.Thread(target=_feed, args=(proc.stdin, pacer_records(batches, extended)),
                              name="dv-pacer-feed", daemon=True)
    t0 = time.perf_counter()
    feeder.start()
    stats = bus.TimingStats()
    sent = failed = 0
    while chunk := proc.stdout.read(PACER_OUT.itemsize * 512):
        before = sent
        for off, err, n, bad in np.frombuffer(chunk, dtype=PACER_OUT).tolist():
            stats.add_batch(off / 1e9, [err] * n)
            sent += n
            failed += bad
        if on_progress is not None:
            on_progress(sent - before)
    feeder.join()
    err = proc.stderr.read().decode(errors="replace").strip()
    rc = proc.wait()
    wall = time.perf_counter() - t0
    if rc == 2:
        raise bus.BusError(f"dv_pacer ({exe}): {err or 'failed'}")
    if err:
        log.warning("dv_pacer: %s", err)
    return bus.ReplayResult(sent, sent, wall, stats.report(), failed)


def _feed(pipe: IO[bytes], blocks: Iterable[bytes]) -> None:
    try:
        for block in blocks:
            pipe.write(block)
    except BrokenPipeError:  # the pacer stopped (it says why on stderr)
        pass
    finally:
        with contextlib.suppress(BrokenPipeError):
            pipe.close()
