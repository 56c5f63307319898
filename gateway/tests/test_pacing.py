"""dynval.pacing: deadlines are never early, and tight_timing restores what it changed.
(How close to the deadline is a benchmark's question: bench/bench_replay.py.)"""
from __future__ import annotations

import gc
import os
import sys
import time

import pytest

from dynval import pacing


def test_wait_until_never_returns_before_the_deadline():
    for ahead_ns in (0, -5_000, 50_000, pacing.SLEEP_MARGIN_NS + 300_000):
        deadline = time.perf_counter_ns() + ahead_ns
        pacing.wait_until(deadline)
        assert time.perf_counter_ns() >= deadline


def _slack() -> int:
    prctl = pacing._prctl()
    return int(prctl(pacing._PR_GET_TIMERSLACK, 0, 0, 0, 0)) if prctl is not None else -1


def test_tight_timing_sets_and_restores_the_interpreter_and_thread_state():
    interval, slack = sys.getswitchinterval(), _slack()
    assert gc.isenabled()
    with pacing.tight_timing():
        assert sys.getswitchinterval() == pytest.approx(pacing.SWITCH_INTERVAL_S)
        assert not gc.isenabled()
        if slack > 0:
            assert _slack() == 1
    assert sys.getswitchinterval() == interval
    assert gc.isenabled()
    assert _slack() == slack


def test_tight_timing_restores_on_error_and_keeps_a_disabled_gc_disabled():
    gc.disable()
    try:
        with pytest.raises(RuntimeError), pacing.tight_timing():
            raise RuntimeError("boom")
        assert not gc.isenabled()
    finally:
        gc.enable()


@pytest.mark.skipif(not hasattr(os, "SCHED_FIFO"), reason="no POSIX realtime scheduling")
def test_realtime_is_scheduled_fifo_inside_and_restored_after():
    before = os.sched_getscheduler(0)
    with pacing.tight_timing(realtime=True):
        inside = os.sched_getscheduler(0)
    assert os.sched_getscheduler(0) == before
    # refused without the privilege: then a warning and normal scheduling, never an error
    assert inside in (os.SCHED_FIFO, before)
