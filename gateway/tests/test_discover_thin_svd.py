"""The fits' thin SVD (fit.thin_svd) against LAPACK's, and a least_squares fit through it."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from dynval.discover import fit


def _tall(cond: float, seed: int, m: int = 20000, n: int = 12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((m, n)))
    w, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (q * np.logspace(0, -np.log10(cond), n)) @ w.T


@pytest.mark.parametrize("cond", [10.0, 1e3, 1e5])  # distinct values: unique vectors
def test_thin_svd_gives_lapacks_singular_values_and_projection(cond: float) -> None:
    a = _tall(cond, seed=int(cond))
    f = np.random.default_rng(1).standard_normal(a.shape[0])
    u, s, vt = fit.thin_svd(a)
    u0, s0, vt0 = scipy.linalg.svd(a, full_matrices=False)
    np.testing.assert_allclose(s, s0, rtol=1e-9 * cond)
    # what trust-region-reflective reads: U^T f with V (signs are the SVD's free choice)
    sign = np.sign(np.sum(vt * vt0, axis=1))
    np.testing.assert_allclose((u.T @ f) * sign, u0.T @ f, rtol=0, atol=1e-9 * cond)
    np.testing.assert_allclose(vt * sign[:, None], vt0, atol=1e-9 * cond)
    np.testing.assert_allclose(u @ np.diag(s) @ vt, a, atol=1e-12)


@pytest.mark.parametrize("shape,cond", [((20000, 12), 1e8), ((30, 12), 1.0)])
def test_thin_svd_leaves_ill_conditioned_or_short_matrices_to_lapack(
        shape: tuple[int, int], cond: float) -> None:
    a = _tall(cond, seed=3, m=shape[0], n=shape[1])
    for got, want in zip(fit.thin_svd(a), scipy.linalg.svd(a, full_matrices=False),
                         strict=True):
        np.testing.assert_array_equal(got, want)


def test_a_bounded_fit_through_it_finds_the_same_minimum() -> None:
    # an exponential decay's amplitude, rate and offset on [0, 1]: 4000 samples, noise 1e-3
    t = np.linspace(0.0, 4.0, 4000)
    y = 0.7 * np.exp(-1.3 * t) + 0.2 + 1e-3 * np.random.default_rng(5).standard_normal(t.size)

    def res(z: np.ndarray) -> np.ndarray:
        return z[0] * np.exp(-3.0 * z[1] * t) + z[2] - y

    def solve() -> np.ndarray:
        sol = scipy.optimize.least_squares(res, [0.5, 0.5, 0.5], bounds=(0.0, 1.0),
                                           method="trf", xtol=1e-12, ftol=1e-12)
        return np.asarray(sol.x)

    with fit._trf_thin_svd():
        assert scipy.optimize._lsq.trf.svd is fit.thin_svd
        z = solve()
    assert scipy.optimize._lsq.trf.svd is scipy.linalg.svd  # restored
    np.testing.assert_allclose(z, solve(), rtol=1e-8)
    np.testing.assert_allclose(z, [0.7, 1.3 / 3.0, 0.2], atol=3e-3)
