"""discover's candidate fits on several processes (discover/parallel.py): the results are the
serial loop's, bit for bit, in the same order, and a worker's exception reaches the caller."""
from __future__ import annotations

import dataclasses
import logging
import multiprocessing as mp
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.optimize._numdiff import approx_derivative
from test_discover_drift import carriage

from dynval import cli
from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import fit as ft
from dynval.discover import loop, parallel, report
from dynval.discover import residual as rs
from dynval.errors import ConfigError


def _pid_and_square(x: int) -> tuple[int, int]:
    return os.getpid(), x * x


def _fails_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three")
    return x


def test_ordered_map_keeps_the_order_and_uses_other_processes() -> None:
    out = parallel.ordered_map(_pid_and_square, list(range(12)), 2)
    assert [sq for _, sq in out] == [x * x for x in range(12)]
    assert {pid for pid, _ in out} - {os.getpid()}  # forked workers did the work


def test_the_workers_take_the_longest_tasks_first_and_the_order_is_kept() -> None:
    taken = mp.get_context("fork").Value("i", 0)  # shared with the forked workers

    def rank(x: int) -> tuple[int, int]:
        with taken.get_lock():
            r = taken.value
            taken.value += 1
        return x, r

    out = parallel.ordered_map(rank, list(range(8)), 2, cost=[float(x) for x in range(8)])
    assert [x for x, _ in out] == list(range(8))
    ranks = {x: r for x, r in out}
    assert ranks[7] <= 1 and ranks[0] >= 6  # the costliest taken first, the cheapest last


def test_one_worker_runs_here() -> None:
    out = parallel.ordered_map(_pid_and_square, [1, 2, 3], 1)
    assert out == [(os.getpid(), 1), (os.getpid(), 4), (os.getpid(), 9)]


def test_a_workers_exception_is_raised_to_the_caller() -> None:
    with pytest.raises(ValueError, match="three"):
        parallel.ordered_map(_fails_on_three, list(range(6)), 2)


def test_the_workers_variable_sets_the_processes(monkeypatch: pytest.MonkeyPatch,
                                                 caplog: pytest.LogCaptureFixture,
                                                 shared_data: Path) -> None:
    monkeypatch.delenv(parallel.WORKERS_ENV, raising=False)
    cores = parallel.available_workers()
    assert cores == len(os.sched_getaffinity(0))
    monkeypatch.setenv(parallel.WORKERS_ENV, " 3 ")
    assert parallel.available_workers() == 3
    for bad in ("0", "-1", "two", "1.5"):
        monkeypatch.setenv(parallel.WORKERS_ENV, bad)
        with pytest.raises(ConfigError, match=f"DYNVAL_WORKERS='{bad}': expected a positive"):
            parallel.available_workers()
    # the command line: one line naming the variable, exit 2
    monkeypatch.setenv(parallel.WORKERS_ENV, "none")
    folder = shared_data / "synthetic" / "lanl4dof-bumper"
    rc = cli.main(["-q", "discover", str(folder / "declared_model.json"), str(folder)])
    err = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert rc == 2 and len(err) == 1 and "DYNVAL_WORKERS='none'" in err[0], err


def test_discover_gives_the_same_report_on_one_and_on_two_processes() -> None:
    truth = gen.Truth(elements=(mdl.Friction(0, 1, 1.5, 1e-3),))
    recs = gen.generate(carriage(), truth, n_tests=4, n_samples=4096, seed=5)
    docs = []
    for workers in (1, 2):
        doc = report.to_json(loop.discover(carriage(), recs, loop.Options(workers=workers)))
        t = doc.pop("timing_s")  # seconds by phase, adding up to the whole run
        parts = [k for k in t if k != "total"]
        assert parts[0] == "setup" and parts[1] == "round_1" and parts[-1] == "final"
        assert "after_round_1" in parts and sum(t[k] for k in parts) == pytest.approx(
            t["total"], rel=0.01, abs=0.01)
        docs.append(doc)
    assert docs[0]["effects"] and docs[0]["effects"][0]["type"] == "friction"
    assert docs[0] == docs[1]


def _pids_inside(x: int) -> list[int]:
    return [pid for pid, _ in parallel.ordered_map(_pid_and_square, [x, x + 1], 2)]


def test_a_map_inside_a_workers_task_runs_in_that_worker() -> None:
    # two cores are already busy with the outer map: the inner one must not fork again
    for inner in parallel.ordered_map(_pids_inside, [1, 2, 3], 2):
        assert len(set(inner)) == 1 and inner[0] != os.getpid()


def _pid_vector(z: np.ndarray) -> np.ndarray:
    return np.array([z[0], z[0] ** 2, float(os.getpid())])


def test_a_point_map_keeps_its_workers_and_returns_the_serial_vectors() -> None:
    pts = [np.array([float(i)]) for i in range(5)]
    with parallel.PointMap(_pid_vector, 2) as pm:
        first = pm(pts, 3).copy()
        again = pm(pts[:3], 3).copy()
    assert np.array_equal(first[:, :2], [[i, i * i] for i in range(5)])
    assert np.array_equal(again[:, :2], first[:3, :2])
    pids = set(first[:, 2]) | set(again[:, 2])
    assert os.getpid() not in pids and 1 <= len(pids) <= 2  # the same forked workers
    with parallel.PointMap(_pid_vector, 1) as pm:  # one worker: here, the same numbers
        here = np.asarray(pm(pts, 3))
    assert np.array_equal(here[:, :2], first[:, :2]) and set(here[:, 2]) == {os.getpid()}
    for workers in (1, 2):
        with parallel.PointMap(_pid_vector, workers) as pm, \
                pytest.raises(ValueError, match="shape"):
            pm(pts, 4)  # a vector of another length than announced


def _threads_once_alone(x: int) -> tuple[int, int, bool]:
    """Task 0: the threads it may use while task 1 is unfinished. Task 1: waits for task 0 to
    finish, then maps six slow points: (its spare threads, the threads that ran them, whether
    the vectors are the serial ones)."""
    if x == 0:
        return parallel.idle_threads(), 0, True
    deadline = time.monotonic() + 30.0
    while parallel.idle_threads() < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    ran: set[int] = set()

    def slow_square(z: np.ndarray) -> np.ndarray:
        ran.add(threading.get_ident())
        time.sleep(0.05)  # the other thread takes the next point meanwhile
        return np.array([z[0] ** 2, -z[0]])

    with parallel.PointMap(slow_square, 2) as pm:
        v = np.asarray(pm([np.array([float(i)]) for i in range(6)], 2))
    same = np.array_equal(v, [[i * i, -i] for i in range(6)])
    return parallel.idle_threads(), len(ran), same


def test_a_point_map_in_a_task_takes_the_cores_its_map_has_no_work_for() -> None:
    with parallel.budget(2):  # a discover run's two workers
        (busy, _, _), (alone, threads, same) = parallel.ordered_map(_threads_once_alone,
                                                                    [0, 1], 2)
        assert parallel.idle_threads() == 2  # here, outside the map: the budget
    assert busy == 1  # both tasks unfinished: each keeps to its own core
    assert alone == 2 and threads == 2 and same
    assert parallel.idle_threads() == 1  # outside a discover run


def test_a_residual_over_tests_on_threads_is_the_serial_one(
        monkeypatch: pytest.MonkeyPatch) -> None:
    m = dataclasses.replace(carriage(), elements=(mdl.Friction(0, 1, 1.5, 1e-3),))
    recs = gen.generate(carriage(), gen.Truth(elements=m.elements), n_tests=3, n_samples=2048,
                        seed=4)
    tests = rs.prepare(m, recs)
    tests[1] = rs.segment_split(tests[1:2])[0][0]  # a view counting half its samples
    chans = rs.common_channels(m, tests)
    scales = rs.channel_scales(tests, chans)
    threads: set[int] = set()
    real = ft.predict

    def predict(mm: mdl.Model, t: rs.TestData) -> dict[str, np.ndarray] | None:
        threads.add(threading.get_ident())
        return real(mm, t)

    monkeypatch.setattr(ft, "predict", predict)
    monkeypatch.setattr(rs, "predict", predict)
    out: dict[int, tuple[Any, ...]] = {}
    for workers in (1, 2):
        got = []
        with parallel.budget(workers):
            for run in (lambda: ft.residual_vector(m, tests, chans, scales),
                        lambda: rs.error_table(m, tests, chans, scales)):
                threads.clear()
                got.append(run())
                # this thread alone, or up to two of a pool's (its own, each call)
                assert (threading.get_ident() in threads) == (workers == 1)
                assert 1 <= len(threads) <= workers
        out[workers] = tuple(got)
    (r1, (tab1, res1)), (r2, (tab2, res2)) = out[1], out[2]
    assert r1 is not None and r2 is not None and np.array_equal(r1, r2)
    assert tab1 == tab2 and all(np.array_equal(res1[t][c], res2[t][c])
                                for t in res1 for c in chans)
    assert ft.residual_size(tests, chans) == r1.size < 3 * 2048 * len(chans)


def test_each_test_prepares_its_input_under_its_own_lock() -> None:
    """A test preparing its input does not hold up another's (a fit of the DAQ filter's
    cutoff prepares an input per test and cutoff, on threads); a copy or a pickled test has
    a lock of its own and gives the same input."""
    import pickle

    m = carriage()
    tests = rs.prepare(m, gen.generate(m, gen.Truth(), n_tests=2, n_samples=1024, seed=2))
    done = threading.Event()
    with tests[0]._lock:  # as if test 0 were preparing on another thread
        threading.Thread(target=lambda: (tests[1].input_for(m), done.set())).start()
        assert done.wait(30.0)
    for copy in (dataclasses.replace(tests[0]), pickle.loads(pickle.dumps(tests[0]))):
        assert copy._lock is not tests[0]._lock
        a, b = copy.input_for(m), tests[0].input_for(m)
        assert a.r == b.r and np.array_equal(a.fine, b.fine)


def _curved(z: np.ndarray) -> np.ndarray:
    return np.array([np.sin(3 * z[0]) * z[1], np.exp(z[1]) - z[0] ** 2, z[0] * z[1] * z[2]])


@pytest.mark.parametrize("workers", [1, 2])
def test_forward_jacobian_is_scipys_two_point_scheme(workers: int) -> None:
    # the same columns as scipy's '2-point' differences with diff_step 1e-3 inside [0, 1]: at 0,
    # inside, and a backward step at the upper bound (z[2] = 0.9995)
    z = np.array([0.3, 0.0, 0.9995])
    with ft.forward_jacobian(_curved, workers) as (fun, jac):
        f0 = fun(z)
        ref = approx_derivative(_curved, z, method="2-point", rel_step=1e-3, f0=f0,
                                bounds=(0.0, 1.0))
        assert np.array_equal(jac(z), ref)
        other = np.array([0.5, 0.25, 0.75])  # a second Jacobian on the same workers
        assert np.array_equal(jac(other), approx_derivative(_curved, other, method="2-point",
                                                            rel_step=1e-3, bounds=(0.0, 1.0)))
        assert not np.array_equal(jac(z), approx_derivative(_curved, z, method="3-point"))


def test_a_restart_at_the_last_jacobians_point_costs_no_evaluation() -> None:
    # _solve restarts a fit where it stopped: fun and the Jacobian there are the kept ones
    # (no call of fun, the same numbers); anywhere else they are computed again
    calls: list[np.ndarray] = []

    def counted(z: np.ndarray) -> np.ndarray:
        calls.append(z.copy())
        return _curved(z)

    with ft.forward_jacobian(counted, 1) as (fun, jac):
        _restart_costs_nothing(fun, jac, calls)


def _restart_costs_nothing(fun: Callable[[np.ndarray], np.ndarray],
                           jac: Callable[[np.ndarray], np.ndarray],
                           calls: list[np.ndarray]) -> None:
    z = np.array([0.3, 0.2, 0.6])
    j = jac(z)
    assert len(calls) == 4  # fun at z, then one column each
    f_again, j_again = fun(z.copy()), jac(z.copy())
    assert len(calls) == 4
    assert np.array_equal(f_again, _curved(z)) and np.array_equal(j_again, j)
    j_again[0, 0] = 99.0  # the caller's copy: the kept one stays
    assert np.array_equal(jac(z), j)
    other = np.array([0.3, 0.2, 0.61])
    assert np.allclose(jac(other), approx_derivative(_curved, other, method="2-point",
                                                     rel_step=1e-3, bounds=(0.0, 1.0)))
    assert len(calls) == 8
