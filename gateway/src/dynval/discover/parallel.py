"""An ordered map over forked worker processes, for the independent fits of a discover round.

Each candidate of a round is fitted and judged on its own, but needs the whole session (the
tests' arrays, the current model, the options). Forked workers inherit it instead of having it
pickled per task: only a task's index goes out and its result (fit values, models, error
tables: small) comes back. The results are those of the serial loop, in the same order: each
task runs the same code on the same inputs in another process. Where fork is not available
(Windows, macOS' default), or with one worker, the map runs in this process.

PointMap is the same for the many small maps of one fit (a Jacobian's columns, one map per
iteration): its workers are forked once per fit, and the vectors come back through memory
shared with them instead of pickled. Inside a task of a map whose last tasks leave cores idle
(a round's longest fit running alone), it runs its points on threads instead (thread_map: the
core simulates without the GIL), as does a fit's residual over its tests wherever cores are
idle (a trial point between two Jacobians)."""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import mmap
import multiprocessing as mp
import os
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from types import TracebackType
from typing import Any, TypeVar

import numpy as np

from dynval.errors import ConfigError

T = TypeVar("T")
R = TypeVar("R")

# the work of the pool being run; set before the fork, read by the workers
_WORK: tuple[Callable[[Any], Any], Sequence[Any]] | None = None
_IN_WORKER = False  # set in a forked worker: a map inside a task runs serially (2 cores, not 4)
# the running map's tasks not finished yet and its cores (set before the fork, shared with the
# workers): a task's PointMap takes the cores its map no longer has work for (idle_threads)
_LEFT: Any = None
_CORES = 0
_BUDGET = 1  # the cores the running discover may use (budget()); 1 outside one
_NESTED = threading.local()  # .on: a thread of thread_map or PointMap (its own work is serial)


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
    try:
        return fn(items[i])
    finally:
        with _LEFT.get_lock():
            _LEFT.value -= 1


@contextlib.contextmanager
def budget(workers: int) -> Iterator[None]:
    """The cores thread_map may use in the block (a discover run's workers)."""
    global _BUDGET
    before, _BUDGET = _BUDGET, max(1, workers)
    try:
        yield
    finally:
        _BUDGET = before


def idle_threads() -> int:
    """Threads a map of small independent computations may use now: 1 on a thread of another
    map; inside a task of ordered_map its own and the cores its map has no task left for (a
    round of five fits, the last one alone for 9 s of the 6-DOF sweep's 23; 1 in a forked
    PointMap worker); else the budget (this process is the only one working: a fit's trial
    point between two Jacobians)."""
    if getattr(_NESTED, "on", False):
        return 1
    if not _IN_WORKER:
        return _BUDGET
    if _LEFT is None:
        return 1
    return max(1, min(_BUDGET, 1 + _CORES - int(_LEFT.value)))


def _nested(fn: Callable[[T], R]) -> Callable[[T], R]:
    def run(x: T) -> R:
        _NESTED.on = True
        return fn(x)
    return run


def thread_map(fn: Callable[[T], R], items: Sequence[T], most: int | None = None
               ) -> Iterable[R]:
    """fn over items, in order, on idle_threads() threads, at most ``most`` (fn thread-safe
    and mostly outside the GIL: the core's simulations); with one, lazily here (a caller may
    stop early)."""
    n = min(idle_threads(), len(items), most or len(items))
    if n <= 1:
        return map(fn, items)
    with cf.ThreadPoolExecutor(n) as ex:
        return list(ex.map(_nested(fn), items))


def _forked_here(workers: int) -> bool:
    """Whether a map on ``workers`` processes forks them (not inside a task, fork available)."""
    return workers > 1 and not _IN_WORKER and "fork" in mp.get_all_start_methods()


def ordered_map(fn: Callable[[T], R], items: Sequence[T], workers: int,
                cost: Sequence[float] | None = None) -> list[R]:
    """[fn(x) for x in items], on up to ``workers`` forked processes. An exception in a task
    is raised here, as the serial loop would raise it. Inside a task of another map it runs
    serially (the outer map already uses the cores). ``cost``: the tasks' expected durations;
    the workers take the longest first (a pool waits on its last task: a round of five fits
    of 2-13 s), the results still in the items' order."""
    global _WORK, _LEFT, _CORES
    n = min(workers, len(items))
    if not _forked_here(n):
        return [fn(x) for x in items]
    order = (sorted(range(len(items)), key=lambda i: -cost[i]) if cost is not None
             else list(range(len(items))))
    _WORK = (fn, items)
    _LEFT, _CORES = mp.get_context("fork").Value("i", len(items)), workers
    try:
        with cf.ProcessPoolExecutor(max_workers=n, mp_context=mp.get_context("fork")) as ex:
            done = dict(zip(order, ex.map(_run, order), strict=True))
        return [done[i] for i in range(len(items))]
    finally:
        _WORK, _LEFT = None, None


# the work of each open PointMap, by its id; read by its workers, forked while it is set
_POINT_WORK: dict[int, tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]] = {}


def _point_task(key: int, row: int, point: np.ndarray) -> None:
    global _IN_WORKER
    _IN_WORKER = True
    fn, out = _POINT_WORK[key]
    v = np.asarray(fn(point), dtype=np.float64)
    _check_shape(v, out.shape[1:])
    out[row] = v


def _check_shape(v: np.ndarray, shape: tuple[int, ...]) -> None:
    if v.shape != shape:
        raise ValueError(f"a point's vector has shape {v.shape}, expected {shape}")


class PointMap:
    """fn (a point, an array, -> a float vector of ``size`` values) over a list of points: the
    vectors in the points' order, valid until the next call. On up to ``workers`` processes,
    forked at the first call and kept until close (a fit's Jacobians: a pool forked per
    Jacobian cost 100 ms against 150 ms of a 6-DOF fit's 17 columns), each writing its
    vectors into memory shared with this process (rows of one array). The same numbers as
    the serial loop, which runs where ordered_map would (one worker, inside a task, no fork;
    there on the threads thread_map finds idle, fn being thread-safe) and gives fn's own
    arrays, uncopied (stacked, a 6-DOF fit's 16 Jacobian columns of 245 760 values were
    copied once more: 3.7 s of the 6-DOF sweep's 122 in one process)."""

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray], workers: int) -> None:
        self.fn, self.workers = fn, workers
        self._pool: cf.ProcessPoolExecutor | None = None
        self._out = np.empty((0, 0))

    def __call__(self, points: Sequence[np.ndarray], size: int) -> list[np.ndarray] | np.ndarray:
        if not _forked_here(min(self.workers, len(points))):
            out = list(thread_map(self._vector, points, self.workers))
            for v in out:
                _check_shape(v, (size,))
            return out
        if self._pool is None or self._out.shape[0] < len(points) or self._out.shape[1] != size:
            self.close()
            shared = mmap.mmap(-1, max(len(points) * size, 1) * 8)  # MAP_SHARED: forks see it
            self._out = np.frombuffer(shared, dtype=np.float64)[:len(points) * size].reshape(
                len(points), size)
            _POINT_WORK[id(self)] = (self.fn, self._out)
            self._pool = cf.ProcessPoolExecutor(max_workers=self.workers,
                                                mp_context=mp.get_context("fork"))
        done = [self._pool.submit(_point_task, id(self), i, p) for i, p in enumerate(points)]
        for f in done:
            f.result()  # a worker's exception raised here
        return self._out[:len(points)]

    def _vector(self, point: np.ndarray) -> np.ndarray:
        return np.asarray(self.fn(point), dtype=np.float64)

    def close(self) -> None:
        """Stop the workers (the last result stays readable)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        _POINT_WORK.pop(id(self), None)

    def __enter__(self) -> PointMap:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
