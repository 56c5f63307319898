"""Bounded Levenberg-Marquardt for discover's fits, in coordinates scaled to [0, 1].

scipy's least_squares (trust region reflective, exact solver) takes an SVD of the whole
Jacobian at every iteration. discover's residuals are long: 5 tests x 8192 samples x 6
channels is 245 760 rows for 6-16 parameters, and there that SVD costs 21-52 ms against 2.5-8
ms for the normal equations J'J (measured on this machine, bench/RESULTS.discover.md): a
sixth of a 6-DOF case's time. Here each step solves the damped normal equations with
Marquardt's diagonal scaling, (J'J + lam diag(J'J)) p = -J'f, on the parameters not held at
a bound by the gradient. A step that would leave [0, 1] is cut to THETA of its way to the
nearest bound, or the parameters that would cross are held and the others solved again,
whichever the linearised model favours: the iterates stay inside, and no parameter is
clipped onto a bound and held there (which stopped a blind sweep case's cubic fit at 4 x
least_squares' error: clipping bends the step, and the gradient then held the parameter
there). The damping follows the gain ratio (Nielsen's rule). J'J squares J's condition
number: where that makes the damped matrix numerically singular, the Cholesky factorisation
fails and the damping grows.

The stopping rules are least_squares': ftol on an accepted step's relative decrease (when
the linearised model predicted it well), xtol on the step's length relative to the point's,
gtol on the gradient's largest free component, max_nfev on the residual's evaluations (a
Jacobian is not counted), and a callback that may raise StopIteration. The Jacobian returned
is the one at the solution.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# status codes, as least_squares'
MAX_NFEV, GTOL, FTOL, XTOL, CALLBACK = 0, 1, 2, 3, -2
_MESSAGES = {MAX_NFEV: "the maximum number of function evaluations is exceeded",
             GTOL: "`gtol` termination condition is satisfied",
             FTOL: "`ftol` termination condition is satisfied",
             XTOL: "`xtol` termination condition is satisfied",
             CALLBACK: "stopped because `callback` function raised `StopIteration`"}
_LAM0 = 1e-3  # the first step's damping, relative to J'J's diagonal: close to Gauss-Newton
_LAM_MAX = 1e30  # a damping past this leaves no step
_ACCEPT = 1e-4  # an accepted step achieves at least this share of its predicted decrease
THETA = 0.995  # the share of the way to a bound a step leaving [0, 1] is cut to


@dataclass
class Solution:
    """least_squares' result fields discover reads (cost: half the sum of squares)."""

    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    cost: float
    nfev: int
    status: int

    @property
    def success(self) -> bool:
        return self.status > 0

    @property
    def message(self) -> str:
        return _MESSAGES[self.status]


@dataclass
class Progress:
    """What the callback is given after each accepted step (least_squares' names)."""

    cost: float
    nfev: int


def _damped_step(a: np.ndarray, g: np.ndarray, free: np.ndarray, lam: float
                 ) -> np.ndarray | None:
    """The step on the free parameters from the damped normal equations; None when the
    damped matrix is not numerically positive definite."""
    p = np.zeros_like(g)
    af = a[np.ix_(free, free)]
    d = np.diag(af).copy()
    d = np.maximum(d, 1e-12 * max(float(d.max(initial=0.0)), 1e-300))
    try:
        low = np.linalg.cholesky(af + lam * np.diag(d))
    except np.linalg.LinAlgError:
        return None
    p[free] = -np.linalg.solve(low.T, np.linalg.solve(low, g[free]))
    return p if np.all(np.isfinite(p)) else None


def _inside(z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The step p, cut to THETA of its way to the nearest bound it would cross (a parameter
    already on a bound stays there)."""
    p = np.where(((z <= 0.0) & (p < 0.0)) | ((z >= 1.0) & (p > 0.0)), 0.0, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(p > 0.0, (1.0 - z) / p, np.where(p < 0.0, -z / p, np.inf))
    reach = float(np.min(room, initial=np.inf))
    if reach >= 1.0:
        return p
    return np.asarray(np.clip(z + THETA * reach * p, 0.0, 1.0) - z)


def _predicted(a: np.ndarray, g: np.ndarray, step: np.ndarray) -> float:
    """The decrease of half the sum of squares the linearised model predicts for step."""
    return -float(g @ step + 0.5 * step @ a @ step)


def _step(a: np.ndarray, g: np.ndarray, z: np.ndarray, free: np.ndarray, lam: float
          ) -> np.ndarray | None:
    """The damped step kept inside [0, 1] (_inside), or, where it would cross a bound, the
    step with the parameters that would cross it held and the others solved again, whichever
    the linearised model predicts to lower the sum of squares more: one parameter running
    into its bound does not shorten everyone's step."""
    p = _damped_step(a, g, free, lam)
    if p is None:
        return None
    best = _inside(z, p)
    held = free.copy()
    while True:
        crossing = (z + p < 0.0) | (z + p > 1.0)
        if not crossing.any():
            break
        held &= ~crossing
        q = _damped_step(a, g, held, lam) if held.any() else None
        if q is None:
            break
        p = q
        other = _inside(z, p)
        if _predicted(a, g, other) > _predicted(a, g, best):
            best = other
    return best


def solve(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
          z0: np.ndarray, max_nfev: int, xtol: float, ftol: float, gtol: float = 1e-8,
          callback: Callable[[Progress], None] | None = None) -> Solution:
    """Minimise half the sum of squares of fun(z) over z in [0, 1]^n from z0 (clipped into
    it). fun: the residual vector (finite); jac: its Jacobian at z (rows x n)."""
    z = np.clip(np.asarray(z0, dtype=float), 0.0, 1.0)
    f = fun(z)
    nfev, cost = 1, 0.5 * float(f @ f)
    j = jac(z)
    lam, nu = math.nan, 2.0
    status: int | None = None
    while status is None:
        a, g = j.T @ j, j.T @ f
        free = ~(((z <= 0.0) & (g > 0.0)) | ((z >= 1.0) & (g < 0.0)))
        if not free.any() or float(np.max(np.abs(g[free]))) < gtol:
            status = GTOL
            break
        if math.isnan(lam):
            lam = _LAM0
        accepted = False
        while not accepted and status is None:
            if nfev >= max_nfev:
                status = MAX_NFEV
                break
            step = _step(a, g, z, free, lam)
            if step is None:  # no step at any damping (J'J not finite): as a step of nothing
                lam, nu = lam * nu, nu * 2.0
                if lam > _LAM_MAX:
                    status = XTOL
                continue
            small = float(np.linalg.norm(step)) < xtol * (xtol + float(np.linalg.norm(z)))
            predicted = _predicted(a, g, step)
            f_new = fun(z + step)
            nfev += 1
            cost_new = 0.5 * float(f_new @ f_new)
            decrease = cost - cost_new
            if predicted > 0 and decrease > _ACCEPT * predicted:
                rho = decrease / predicted
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                z, f, accepted = z + step, f_new, True
                if decrease < ftol * cost and rho > 0.25:  # and the model was right
                    status = FTOL
                elif small:
                    status = XTOL
                cost = cost_new
            else:
                lam, nu = lam * nu, nu * 2.0
                if small:  # the damping has shrunk the step to nothing
                    status = XTOL
        if accepted:
            j = jac(z)
            if callback is not None and status is None:
                try:
                    callback(Progress(cost, nfev))
                except StopIteration:
                    status = CALLBACK
    return Solution(z, f, j, cost, nfev, status)
