"""An ordered map over forked worker processes, for the independent fits of a discover round.

Each candidate of a round is fitted and judged on its own, but needs the whole session (the
tests' arrays, the current model, the options). Forked workers inherit it instead of having it
pickled per task: only a task's index goes out and its result (fit values, models, error
tables: small) comes back. The results are those of the serial loop, in the same order: each
task runs the same code on the same inputs in another process. Where fork is not available
(Windows, macOS' default), or with one worker, the map runs in this process."""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from dynval.errors import ConfigError

T = TypeVar("T")
R = TypeVar("R")

# the work of the pool being run; set before the fork, read by the workers
_WORK: tuple[Callable[[Any], Any], Sequence[Any]] | None = None
_IN_WORKER = False  # set in a forked worker: a map inside a task runs serially (2 cores, not 4)


WORKERS_ENV = "DYNVAL_WORKERS"


def available_workers() -> int:
    """The processes a map may use: DYNVAL_WORKERS when set (a test runner or a batch job that
    already keeps every core busy sets 1: forked pools then only add work, 25 % more CPU for
    a discover run on two cores), else the cores this process may run on."""
    env = os.environ.get(WORKERS_ENV, "").strip()
    if env:
        if not env.isdigit() or int(env) < 1:
            raise ConfigError(f"environment variable {WORKERS_ENV}={env!r}: expected a "
                              f"positive whole number of processes")
        return int(env)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _run(i: int) -> Any:
    global _IN_WORKER
    assert _WORK is not None, "a worker without work (not forked from ordered_map)"
    _IN_WORKER = True
    fn, items = _WORK
    return fn(items[i])


def ordered_map(fn: Callable[[T], R], items: Sequence[T], workers: int) -> list[R]:
    """[fn(x) for x in items], on up to ``workers`` forked processes. An exception in a task
    is raised here, as the serial loop would raise it. Inside a task of another map it runs
    serially (the outer map already uses the cores)."""
    global _WORK
    n = min(workers, len(items))
    if n <= 1 or _IN_WORKER or "fork" not in mp.get_all_start_methods():
        return [fn(x) for x in items]
    _WORK = (fn, items)
    try:
        with cf.ProcessPoolExecutor(max_workers=n, mp_context=mp.get_context("fork")) as ex:
            return list(ex.map(_run, range(len(items))))
    finally:
        _WORK = None
