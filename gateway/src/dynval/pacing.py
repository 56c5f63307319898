"""Pacing frames at absolute deadlines (one home for how `dynval replay` keeps time).

Deadlines are absolute times of one monotonic clock (time.perf_counter_ns: CLOCK_MONOTONIC on
Linux), start + offset / speed, so a late frame never shifts the later ones (no drift). What was
measured on the virtual bus (bench/bench_replay.py, bench/RESULTS.replay.md) and why:

- sleep to SLEEP_MARGIN_NS before a deadline, then poll the clock: a sleep alone wakes 50 us to
  milliseconds late (the kernel's timer slack, then the scheduler);
- poll without time.sleep(0) (a nanosleep: 35-90 us here) or os.sched_yield (a syscall, after
  which the sends run colder); a python-can send costs 10-15 us, 30 us after a sleep;
- the thread's timer slack at 1 ns and the interpreter's thread switch interval at 100 us
  while pacing: another Python thread (a bus receiver, a logger) otherwise keeps the GIL for
  up to 5 ms when the deadline comes;
- the cyclic garbage collector off (the pacing loop makes no reference cycles): a full
  collection of the interpreter's ~80,000 objects (numpy, python-can) takes ~50 ms, and
  frames queued in memory (python-can's virtual bus) make it longer;
- optionally SCHED_FIFO (realtime=True): other processes then cannot preempt the pacer.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import gc
import logging
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

log = logging.getLogger(__name__)

SLEEP_MARGIN_NS = 150_000  # sleep until this long before a deadline, poll the rest
SWITCH_INTERVAL_S = 1e-4  # GIL hand-over while pacing (Python's default: 5 ms)
RT_PRIORITY = 10  # SCHED_FIFO priority of a realtime pacer: above every normal process
_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30  # prctl(2)


def wait_until(deadline_ns: int) -> None:
    """Return at an absolute perf_counter_ns deadline: sleep to SLEEP_MARGIN_NS before it,
    then poll the clock."""
    rem = deadline_ns - time.perf_counter_ns()
    if rem > SLEEP_MARGIN_NS:
        time.sleep((rem - SLEEP_MARGIN_NS) / 1e9)
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
