"""discover's bounded Levenberg-Marquardt (solver.py) against scipy's least_squares and closed
forms: the same minimum, the bounds held, the evaluation budget kept, the Jacobian returned at
the solution, and a parameter without effect or a refused region handled."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from scipy.optimize import least_squares

from dynval.discover import solver

_T = np.linspace(0.0, 1.0, 4000)


def _decay(z: np.ndarray) -> np.ndarray:
    """A damped sine, its amplitude, decay and frequency mapped from [0, 1]."""
    a, k, w = 0.5 + z[0], 1.0 + 9.0 * z[1], 5.0 + 20.0 * z[2]
    return np.asarray(a * np.exp(-k * _T) * np.sin(w * _T))


def _forward_jac(fun: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    def jac(z: np.ndarray) -> np.ndarray:
        f0 = fun(z)
        cols = []
        for i in range(z.size):
            h = 1e-7 if z[i] < 0.5 else -1e-7
            zi = z.copy()
            zi[i] += h
            cols.append((fun(zi) - f0) / h)
        return np.column_stack(cols)
    return jac


@pytest.mark.parametrize("z0", [(0.5, 0.5, 0.5), (0.1, 0.9, 0.2), (0.9, 0.1, 0.8)])
def test_the_same_minimum_as_least_squares_on_a_noisy_damped_sine(
        z0: tuple[float, float, float]) -> None:
    truth = np.array([0.3, 0.6, 0.4])
    y = _decay(truth) + 0.01 * np.random.default_rng(1).standard_normal(_T.size)

    def fun(z: np.ndarray) -> np.ndarray:
        return _decay(z) - y

    jac = _forward_jac(fun)
    ours = solver.solve(fun, jac, np.array(z0), 60, 1e-10, 1e-12)
    ref = least_squares(fun, z0, jac=jac, bounds=(0.0, 1.0), method="trf", xtol=1e-10,
                        ftol=1e-12, gtol=1e-12)
    assert ours.success and ours.nfev <= 60
    assert ours.cost == pytest.approx(ref.cost, rel=1e-9)
    assert np.allclose(ours.x, ref.x, atol=1e-5)
    assert np.allclose(ours.x, truth, atol=2e-3)  # 1 % noise on 4000 samples
    assert np.array_equal(ours.jac, jac(ours.x))  # the Jacobian at the solution
    assert np.array_equal(ours.fun, fun(ours.x))


def test_an_optimum_beyond_a_bound_ends_on_it_with_the_other_coordinate_free() -> None:
    """f = (z0 - 2, 3 (z1 - 0.25)): the bounded minimum is z = (1, 0.25), cost 0.5."""
    def fun(z: np.ndarray) -> np.ndarray:
        return np.array([z[0] - 2.0, 3.0 * (z[1] - 0.25)])

    sol = solver.solve(fun, lambda z: np.diag([1.0, 3.0]), np.array([0.4, 0.9]), 50, 1e-10,
                       1e-14)
    assert sol.x[0] == pytest.approx(1.0, abs=1e-6) and sol.x[0] <= 1.0
    assert sol.x[1] == pytest.approx(0.25, abs=1e-6)
    assert sol.cost == pytest.approx(0.5, rel=1e-9)
    assert np.all((sol.x >= 0.0) & (sol.x <= 1.0))


def test_the_evaluation_budget_is_kept() -> None:
    """Rosenbrock's valley from its far end: 5 evaluations are not enough."""
    def fun(z: np.ndarray) -> np.ndarray:
        return np.array([1.0 - z[0], 10.0 * (z[1] - z[0] ** 2)])

    sol = solver.solve(fun, _forward_jac(fun), np.array([0.05, 0.95]), 5, 1e-12, 1e-14)
    assert sol.status == solver.MAX_NFEV and not sol.success
    assert sol.nfev == 5
    full = solver.solve(fun, _forward_jac(fun), np.array([0.05, 0.95]), 200, 1e-12, 1e-14)
    assert full.success and np.allclose(full.x, 1.0, atol=1e-5)


def test_a_parameter_without_effect_stays_where_it_started() -> None:
    """A zero column makes J'J singular: the damping's floor keeps the step defined."""
    def fun(z: np.ndarray) -> np.ndarray:
        return np.array([z[0] - 0.7, 2.0 * (z[0] - 0.7), 0.1])

    sol = solver.solve(fun, lambda z: np.array([[1.0, 0.0], [2.0, 0.0], [0.0, 0.0]]),
                       np.array([0.2, 0.35]), 50, 1e-10, 1e-14)
    assert sol.x[0] == pytest.approx(0.7, abs=1e-9)
    assert sol.x[1] == 0.35
    assert 2 * sol.cost == pytest.approx(0.01, rel=1e-9)


def test_a_refused_region_stops_the_fit_at_its_edge_on_xtol() -> None:
    """Points with z0 > 0.6 are refused with a large constant residual (fit's penalty for a
    parameter set the core refuses): the steps into it are rejected until the damping has
    shrunk the step to nothing, at the region's edge, and the stop is an xtol one (fit._solve
    restarts from there)."""
    def fun(z: np.ndarray) -> np.ndarray:
        if z[0] > 0.6:
            return np.full(2, 1e3)
        return np.array([z[0] - 0.9, z[1] - 0.5])

    sol = solver.solve(fun, lambda z: np.eye(2), np.array([0.1, 0.5]), 60, 1e-8, 1e-14)
    assert sol.status == solver.XTOL
    assert 0.599 < sol.x[0] <= 0.6
    assert sol.x[1] == 0.5
    assert 2 * sol.cost == pytest.approx(0.09, rel=1e-2)


def test_a_jacobian_that_is_not_finite_ends_the_fit_where_it_is() -> None:
    """No step can be taken: the fit stops at its start, on xtol, without looping."""
    def fun(z: np.ndarray) -> np.ndarray:
        return np.array([z[0] - 0.9])

    sol = solver.solve(fun, lambda z: np.array([[np.inf]]), np.array([0.3]), 40, 1e-8, 1e-14)
    assert sol.status == solver.XTOL and sol.nfev == 1
    assert sol.x[0] == 0.3
