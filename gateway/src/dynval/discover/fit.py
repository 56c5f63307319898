"""Fit a candidate effect's parameters through the C simulator and judge it.

The fit minimises the normalised output residual (each channel divided by its measured RMS)
over the fitting tests with scipy's bounded least_squares (trust region reflective, forward
differences), in coordinates scaled to [0, 1] between each parameter's bounds (log-scaled
where the effect says so). Every evaluation is a full open-loop run of dynval's C model and
observer (dynval.model.simulate), so what is fitted is exactly what the updated model file
will reproduce.

Uncertainty: 1-sigma from the Gauss-Newton covariance s^2 (J^T J)^-1 at the optimum, with the
residual's sample count replaced by an effective count that accounts for its autocorrelation
(N_eff = N / (1 + 2 sum of positive autocorrelations up to lag 64)).
"""
from __future__ import annotations

import contextlib
import importlib
import logging
import math
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.discover import effects as fx
from dynval.discover import initial, parallel
from dynval.discover.residual import TestData, predict
from dynval.errors import ConfigError

log = logging.getLogger(__name__)
least_squares: Any = importlib.import_module("scipy.optimize").least_squares
_trf: Any = importlib.import_module("scipy.optimize._lsq.trf")  # its svd: see thin_svd
_stats: Any = importlib.import_module("scipy.stats")

_PENALTY = 1e3  # residual value for a parameter set the core refuses
# a fit stops when a step lowers its error by less than this share: the decisions read gains
# of percents (measured on the sliding-joint test: 19 % fewer Jacobians than at 1e-8, the
# same parameters to 5 digits)
FTOL = 1e-5
# least_squares' step tolerance (relative, on [0, 1]), its status on stopping there, and the
# evaluations left that make a restart from there worth it (_solve)
XTOL = 1e-6
_XTOL_STOP = 3
MIN_RESTART_NFEV = 3
READJUSTED = " (declared, re-adjusted)"  # suffix of a re-adjusted declared parameter's name
# a candidate's fit is stopped when, at its pace per evaluation over its last FUTILE_WINDOW
# iterations, its remaining evaluations could not bring it under the fitting error it must
# beat (a fit that ends above it is refused: its BIC cannot be lower). A trust-region fit's
# pace only slows, so the projection is generous (blind sweep case 17: round 2's six
# candidates crawled 15-30 evaluations above the current model's error, every one refused)
FUTILE_WINDOW = 3


@dataclass
class FitResult:
    cand: fx.Candidate
    names: list[str]
    units: list[str]
    values: list[float]
    sigma: list[float]
    model: mdl.Model
    nsse_fit: float
    nfev: int
    ok: bool
    message: str = ""
    n_eff_factor: float = 1.0
    extra: dict[str, float] = field(default_factory=dict)

    def readjusted(self) -> dict[str, float]:
        """The declared parameters the fit re-adjusted, by their model name, at its values."""
        return {d: v for n, v in zip(self.names, self.values, strict=True)
                if (d := declared_name(n)) is not None}

    def own(self) -> dict[str, float]:
        """The effect's own parameters (not the re-adjusted declared ones), at its values."""
        return {n: v for n, v in zip(self.names, self.values, strict=True)
                if declared_name(n) is None}


def declared_name(name: str) -> str | None:
    """The model's name of a re-adjusted declared parameter's fit name; None for one of the
    effect's own parameters."""
    return name[: -len(READJUSTED)] if name.endswith(READJUSTED) else None


def _to_value(p: fx.Param, z: float) -> float:
    z = min(max(z, 0.0), 1.0)
    if p.signed:  # z = 1/2 is 0; the magnitude in log either way (continuous through 0)
        t = 2.0 * z - 1.0
        return math.copysign(p.lower * ((p.upper / p.lower) ** abs(t) - 1.0), t)
    if p.log:
        return float(p.lower * (p.upper / p.lower) ** z)
    return float(p.lower + (p.upper - p.lower) * z)


def _to_z(p: fx.Param, v: float) -> float:
    if p.signed:
        mag = min(abs(v), p.upper - p.lower)
        t = math.log1p(mag / p.lower) / math.log(p.upper / p.lower)
        return 0.5 * (1.0 + math.copysign(t, v))
    v = min(max(v, p.lower), p.upper)
    if p.log:
        return float(math.log(v / p.lower) / math.log(p.upper / p.lower))
    return float((v - p.lower) / (p.upper - p.lower))


def _dv_dz(p: fx.Param, v: float) -> float:
    """The slope of _to_value at the value v."""
    if p.signed:
        return 2.0 * (abs(v) + p.lower) * math.log(p.upper / p.lower)
    return v * math.log(p.upper / p.lower) if p.log else p.upper - p.lower


AT_BOUND = 0.03  # share of a parameter's [0, 1] search range that counts as its bound


def at_bounds(params: Sequence[fx.Param], names: Sequence[str], values: Sequence[float]
              ) -> list[str]:
    """Of the fitted parameters ``names`` (values ``values``), those that ended within
    AT_BOUND of either end of their search range ``params`` (by name; in the fit's [0, 1]
    coordinates, log-scaled where the parameter is): the fit wanted to go further there, so
    the effect's form is stretched (an appendage damped like a dashpot, a story stiffness at
    1/100 of its declared value). Starts are never there (problem() keeps them inside
    0.02..0.98 of the range's ends)."""
    ranges = {p.name: p for p in params}
    return [n for n, v in zip(names, values, strict=True)
            if n in ranges and not AT_BOUND < _to_z(ranges[n], v) < 1.0 - AT_BOUND]


def residual_size(tests: Sequence[TestData], chans: Sequence[str]) -> int:
    """residual_vector's length: the samples that count, over every test and channel."""
    return len(chans) * sum(t.n for t in tests)


def residual_vector(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
                    scales: dict[str, float]) -> np.ndarray | None:
    """(y - prediction) / scale / sqrt(n) of every channel and test, concatenated: its sum of
    squares is the tests' total normalised SSE. None when a prediction fails or that sum is
    over a refused point's (_PENALTY^2, or not finite): a diverging prediction can stay
    finite, 1e300, and overflow every product the fit takes of it (an observer's at a model
    free from the ground)."""
    out = np.empty(residual_size(tests, chans))  # filled in place: no copies
    first = np.cumsum([0, *(len(chans) * t.n for t in tests)])

    def fill(i: int) -> list[float] | None:
        """Test i's part of out, and its channels' sums of squares (None: no prediction)."""
        t = tests[i]
        p = predict(m, t)
        if p is None:
            return None
        sums = []
        for k, c in enumerate(chans):
            r = out[first[i] + k * t.n:first[i] + (k + 1) * t.n]
            if t.mask is None:
                np.subtract(t.y[c], p[c], out=r)
            else:
                r[:] = t.counted(t.y[c] - p[c])
            np.divide(r, scales[c] * math.sqrt(t.n), out=r)
            with np.errstate(over="ignore", invalid="ignore"):
                sums.append(float(r @ r))
        return sums

    total = 0.0  # summed in the tests' and channels' order, on any number of threads
    for sums in parallel.thread_map(fill, range(len(tests))):
        if sums is None:
            return None
        for ss in sums:
            total += ss
            if not total <= _PENALTY ** 2:  # NaN and inf fail it too; serially, later tests unrun
                return None
    return out


def n_eff_factor(r: np.ndarray, maxlag: int = 64) -> float:
    """N / N_eff of a residual sequence from its autocorrelation."""
    x = r - r.mean()
    n = x.size
    if n < 4 * maxlag:
        return 1.0
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: maxlag + 1]
    ac = ac / (ac[0] or 1e-300)
    pos = ac[1:]
    # sum until the first non-positive lag (initial positive sequence)
    stop = np.flatnonzero(pos <= 0)
    s = float(pos[: stop[0]].sum()) if stop.size else float(pos.sum())
    return max(1.0, 1.0 + 2.0 * s)


def uncertain_params(m: mdl.Model, names: Sequence[str]) -> list[fx.Param]:
    """Declared parameters the user called uncertain (Model.with_params names), free within
    1/3..3 x their declared value (log-scaled); a story stiffness down to 1/100 of it (a
    best-linear declared stiffness may be mostly the nonlinearity's: a friction damper's
    stick phase) and a damping matrix's modal ratio down to 1/10; a negative one (an added
    softening spring's k3, a force offset) keeps its sign, 1/3..3 x its value (linear);
    zero-valued ones within 0..1."""
    cur = m.parameters()
    out = []
    for n in names:
        if n not in cur:
            raise ConfigError(f"uncertain parameter '{n}' is not a parameter of the model "
                              f"(known: {', '.join(cur)})")
        v = float(cur[n])
        unit = mdl.param_unit(n, m)
        if re.fullmatch(r"k\d+", n):  # a best-linear one may be mostly the nonlinearity's
            low = v / 100
        elif m.damping.type == "matrix" and n.startswith("zeta"):
            low = v / 10  # it may hold the dissipation an earlier effect's fit gave it
        else:
            low = v / 3
        if v > 0:
            out.append(fx.Param(n, unit, low, 3 * v, log=True))
        elif v < 0:  # a fitted softening spring's k3, a force offset: the same sign, 1/3..3 x
            out.append(fx.Param(n, unit, 3 * v, v / 3))
        else:
            out.append(fx.Param(n, unit, 0.0, 1.0))
    return out


def screen_scored(m: mdl.Model, cand: fx.Candidate, starts: Sequence[Sequence[float]],
                  tests: Sequence[TestData], chans: Sequence[str],
                  scales: dict[str, float]) -> list[tuple[float, list[float]]]:
    """(normalised SSE, start) of every starting point, best first (one simulation each)."""
    et = fx.by_type(cand.type)
    scored = []
    for st in starts:
        try:
            r = residual_vector(et.apply(m, cand, st), tests, chans, scales)
        except Exception as exc:  # a refused parameter set (validation)
            log.debug("%s: start %s refused: %s", cand.label, st, exc)
            continue
        if r is not None:
            scored.append((float(r @ r), list(st)))
    scored.sort(key=lambda p: p[0])
    return scored


def screen(m: mdl.Model, cand: fx.Candidate, starts: Sequence[Sequence[float]],
           tests: Sequence[TestData], chans: Sequence[str], scales: dict[str, float],
           keep: int = 2) -> list[list[float]]:
    """The ``keep`` starting points with the smallest normalised SSE: an output-error
    objective of a resonance shift has local minima once the shift exceeds the modes'
    bandwidth, so a coarse scan picks the basin before least squares refines."""
    scored = screen_scored(m, cand, starts, tests, chans, scales)
    return [st for _, st in scored[:keep]] or [list(starts[0])]


# a start whose simulation leaves the fitting tests over this many times the normalised SSE of
# the model without the effect lies in no basin of the effect: the evidence's amplitude is a
# first-order reading of a noisy missing force (bench shake-table sweep, round 2 after the
# contact: starts at 40-2500 x the current model's error, each fit crawling through 30-40
# evaluations to end above that error, 20-37 s a candidate)
TEMPER_RATIO = 3.0
TEMPER_FACTORS = (0.3, 0.1, 0.03, 0.01, 0.003)  # of the strength, tried in turn


def temper(m: mdl.Model, cand: fx.Candidate, init: Sequence[float],
           tests: Sequence[TestData], chans: Sequence[str], scales: dict[str, float]
           ) -> list[float]:
    """``init``, or, when the effect there leaves the tests' normalised SSE above TEMPER_RATIO x
    that of ``m`` without it, the start with its strength parameters (Param.null) moved
    toward no effect by TEMPER_FACTORS in turn: the first back under that ratio, else the
    best one tried (one simulation each)."""
    ps = fx.by_type(cand.type).params(m, cand)
    if len(ps) != len(init) or all(p.null is None for p in ps):
        return list(init)
    r0 = residual_vector(m, tests, chans, scales)
    if r0 is None:
        return list(init)
    without = float(r0 @ r0)
    tried: list[tuple[float, list[float]]] = []
    for f in (1.0, *TEMPER_FACTORS):
        st = [v if p.null is None else p.null + f * (v - p.null)
              for p, v in zip(ps, init, strict=True)]
        scored = screen_scored(m, cand, [st], tests, chans, scales)
        if not scored:  # a start the core refuses: the next, weaker one
            continue
        tried.append((scored[0][0], st))
        if scored[0][0] <= TEMPER_RATIO * without:
            if f < 1.0:
                log.info("%s: start's strength x %g (normalised SSE %.3g there, %.3g without "
                         "the effect)", cand.label, f, scored[0][0], without)
            return st
    return min(tried, key=lambda p: p[0])[1] if tried else list(init)


DIFF_STEP = 1e-3  # forward-difference step relative to the [0, 1] coordinate's value


@contextlib.contextmanager
def forward_jacobian(fun: Callable[[np.ndarray], np.ndarray], workers: int
                     ) -> Iterator[tuple[Callable[[np.ndarray], np.ndarray],
                                         Callable[[np.ndarray], np.ndarray]]]:
    """(fun remembering its last point, the Jacobian of fun) for least_squares on [0, 1], for
    the with block: scipy's '2-point' differences with rel_step DIFF_STEP (step DIFF_STEP x z,
    sqrt(eps) at z = 0, backward where it would leave the bounds), the same columns, but on
    up to ``workers`` processes (parallel.PointMap, kept for the block) instead of one after
    the other. The value at the point itself is the first's last one (least_squares evaluates
    fun there just before the Jacobian) when the point is the same. The last Jacobian, and
    fun at its point, are kept: a fit restarted from where it stopped (_solve) starts with
    both, the same numbers without recomputing them (the bumper case: 6.8 % of its
    simulations)."""
    last: dict[str, np.ndarray] = {}
    kept: dict[str, np.ndarray] = {}

    def at_kept(z: np.ndarray) -> bool:
        return "z" in kept and np.array_equal(kept["z"], z)

    def remembering(z: np.ndarray) -> np.ndarray:
        f = kept["f"].copy() if at_kept(z) else fun(z)
        last["z"], last["f"] = z.copy(), f
        return f

    with parallel.PointMap(fun, workers) as columns:
        def jac(z: np.ndarray) -> np.ndarray:
            if at_kept(z):
                return kept["j"].copy()
            f0 = last["f"] if "z" in last and np.array_equal(last["z"], z) else fun(z)
            h = DIFF_STEP * z
            h = np.where((z + h) - z == 0, math.sqrt(np.finfo(float).eps), h)
            h = np.where(z + h > 1.0, -h, h)
            steps = []
            for i in range(z.size):
                zi = z.copy()
                zi[i] = z[i] + h[i]
                steps.append(zi)
            cols = columns(steps, f0.size)
            j = np.empty((f0.size, z.size), order="F")  # each column in place: no temporaries
            for i, zi in enumerate(steps):
                np.divide(np.subtract(cols[i], f0, out=j[:, i]), zi[i] - z[i], out=j[:, i])
            # kept as it is: least_squares reads the Jacobian it is given (with bounds it
            # scales a copy), and a copy of 245 760 x 16 cost 7 ms a Jacobian
            kept.update(z=z.copy(), f=f0.copy(), j=j)
            return j

        yield remembering, jac


@dataclass
class Problem:
    """A candidate's least-squares problem in [0, 1] coordinates: the residual fun(z), the
    start z0, the parameters (the effect's, then the re-adjusted declared ones) and the model
    of a parameter vector."""

    fun: Callable[[np.ndarray], np.ndarray]
    z0: np.ndarray
    params: list[fx.Param]
    n_effect: int
    build: Callable[[list[float]], mdl.Model]
    z_others: list[np.ndarray] = field(default_factory=list)  # EffectType.other_starts

    def values(self, z: np.ndarray) -> list[float]:
        return [_to_value(p, float(zi)) for p, zi in zip(self.params, z, strict=True)]


def problem(m: mdl.Model, cand: fx.Candidate, init: Sequence[float],
            tests: Sequence[TestData], chans: Sequence[str], scales: dict[str, float],
            uncertain: Sequence[str] = (), declared_start: Mapping[str, float] | None = None
            ) -> Problem:
    """The fit's problem (see fit)."""
    et = fx.by_type(cand.type)
    ps = et.params(m, cand)
    xs = uncertain_params(m, uncertain)
    cur = m.parameters()
    now = [float(cur[p.name]) for p in xs]
    given = declared_start or {}
    init_all = [*init, *(given.get(p.name, v) for p, v in zip(xs, now, strict=True))]
    ps_all = [*ps, *xs]
    def to_z(values: Sequence[float]) -> np.ndarray:
        return np.array([min(max(_to_z(p, v), 0.02), 0.98)
                         for p, v in zip(ps_all, values, strict=True)])

    z0 = to_z(init_all)
    z_others = [to_z([*o, *now]) for o in et.other_starts(m, cand, init)]
    n_res = residual_size(tests, chans)
    npar = len(ps)

    def build(v: list[float]) -> mdl.Model:
        base = m.with_params({p.name: x for p, x in zip(xs, v[npar:], strict=True)}) if xs \
            else m
        return et.apply(base, cand, v[:npar])

    def fun(z: np.ndarray) -> np.ndarray:
        try:
            mm = build(pb.values(z))
        except Exception as exc:  # a refused parameter set (validation): penalise
            log.debug("%s: %s", cand.label, exc)
            return np.full(n_res, _PENALTY / math.sqrt(n_res))
        r = residual_vector(mm, tests, chans, scales)
        if r is None:
            return np.full(n_res, _PENALTY / math.sqrt(n_res))
        return r

    pb = Problem(fun, z0, ps_all, npar, build, z_others)  # fun reads pb.values: made first
    return pb


def _declared_jacobian(m: mdl.Model, names: Sequence[str], tests: Sequence[TestData],
                       chans: Sequence[str], scales: dict[str, float], workers: int
                       ) -> tuple[np.ndarray, np.ndarray] | None:
    """(the tests' residual vector, its Jacobian over the declared parameters ``names`` in
    the fits' [0, 1] coordinates) at m; None when the residual is zero."""
    pb = problem(m, fx.NONE.candidates(m)[0], [], tests, chans, scales, names)
    with forward_jacobian(pb.fun, workers) as (fun_at, jac):
        r0 = fun_at(pb.z0)
        if float(r0 @ r0) <= 0:
            return None
        return r0, jac(pb.z0)


def first_order_gain(m: mdl.Model, names: Sequence[str], tests: Sequence[TestData],
                     chans: Sequence[str], scales: dict[str, float], workers: int = 1) -> float:
    """The share of the tests' normalised SSE one Gauss-Newton step on the declared
    parameters ``names`` would remove (the residual's projection on the Jacobian's columns;
    bounds ignored): a screen costing one Jacobian, before a fit costing several."""
    at = _declared_jacobian(m, names, tests, chans, scales, workers)
    if at is None:
        return 0.0
    r0, j = at
    step, *_ = np.linalg.lstsq(j, -r0, rcond=None)
    fitted = r0 + j @ step
    return max(0.0, 1.0 - float(fitted @ fitted) / float(r0 @ r0))


def single_gains(m: mdl.Model, names: Sequence[str], tests: Sequence[TestData],
                 chans: Sequence[str], scales: dict[str, float], workers: int = 1
                 ) -> dict[str, float]:
    """For each declared parameter of ``names`` alone, the share of the tests' normalised SSE
    one Gauss-Newton step on it would remove (first_order_gain of each by itself, all from
    one Jacobian): which one parameter a residual asks to move."""
    at = _declared_jacobian(m, names, tests, chans, scales, workers)
    if at is None:
        return dict.fromkeys(names, 0.0)
    r0, j = at
    rr = float(r0 @ r0)
    jr, jj = j.T @ r0, np.einsum("ij,ij->j", j, j)
    return {n: float(a * a / b / rr) if b > 0 else 0.0
            for n, a, b in zip(names, jr, jj, strict=True)}


def futility_stop(beat: float, max_nfev: int) -> Callable[[Any], None]:
    """least_squares' callback for a fit that must get under the normalised SSE ``beat``:
    raises StopIteration (scipy's way to stop, keeping the last iterate) once it cannot at
    its pace (FUTILE_WINDOW)."""
    seen: list[tuple[float, int]] = []  # (normalised SSE, evaluations) after each iteration

    def stop(intermediate_result: Any) -> None:  # the name scipy passes the result by
        now = 2.0 * float(intermediate_result.cost)  # cost is half the sum of squares
        nfev = int(intermediate_result.nfev)
        seen.append((now, nfev))
        if now <= beat or len(seen) <= FUTILE_WINDOW:
            return
        # per evaluation, as the budget left is counted: an iteration whose first steps were
        # refused (its trust region shrunk) used more of it than one
        then, at = seen[-1 - FUTILE_WINDOW]
        pace = (then - now) / max(nfev - at, 1)
        left = max_nfev - nfev
        if pace * left < now - beat:
            log.debug("fit stopped: normalised SSE %.4g, %.3g per evaluation, %d evaluations "
                      "left, %.4g to beat", now, pace, left, beat)
            raise StopIteration

    return stop


# the largest condition number thin_svd takes through the Gram matrix: its eigenvalues then
# span at most 1e12, each known to 1e-4 of itself or better in double precision; the 6-DOF
# sweep's 696 trf Jacobians had 1 to 8.6e5 (median 1.5e3)
GRAM_MAX_COND = 1e6


def thin_svd(a: np.ndarray, full_matrices: bool = False, **kw: Any
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """scipy.linalg.svd as trust-region-reflective uses it (U, s, V^T of its Jacobian, then
    only U^T f), for a tall, thin, well-conditioned matrix through the eigenvalues of a^T a:
    U = a V / s. Why: on the fits' 245 777 x 17 Jacobians LAPACK's SVD took 83 ms a call,
    58 s of the 6-DOF sweep's 212 (one process), the Gram matrix 7 ms. Anything else (wide,
    short, conditioned beyond GRAM_MAX_COND, not finite) goes to LAPACK."""
    m, n = a.shape
    if full_matrices or m < 8 * n:
        return _lapack_svd(a, full_matrices=full_matrices, **kw)
    lam, v = np.linalg.eigh(a.T @ a)
    lam, v = lam[::-1], v[:, ::-1]  # descending, as svd gives them
    if not (np.all(np.isfinite(lam)) and lam[-1] > lam[0] / GRAM_MAX_COND ** 2 > 0):
        return _lapack_svd(a, full_matrices=False, **kw)
    s = np.sqrt(lam)
    return a @ (v / s), s, v.T


_lapack_svd: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]] = \
    importlib.import_module("scipy.linalg").svd  # the one trf imports


@contextlib.contextmanager
def _trf_thin_svd() -> Iterator[None]:
    """scipy's trust-region-reflective with thin_svd for the block (its module's svd, the only
    SVD it calls; restored after). A scipy whose trf has no such name runs unchanged."""
    if getattr(_trf, "svd", None) is not _lapack_svd:
        yield
        return
    _trf.svd = thin_svd
    try:
        yield
    finally:
        _trf.svd = _lapack_svd


def _solve(fun_at: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
           z0: np.ndarray, max_nfev: int, beat: float | None) -> Any:
    """least_squares on [0, 1] from z0, restarted once from where it stopped on xtol with the
    evaluations left: an xtol stop is a trust region collapsed on a rough or ill-conditioned
    SSE, not a gradient at zero, and a fresh region often goes on (blind free case 3: the
    cubic's fit stopped there at 1.5 x the truth's SSE, 23 of that run's 35 fits did)."""
    def run(z: np.ndarray, n: int) -> Any:
        with _trf_thin_svd():
            return least_squares(fun_at, z, jac=jac, bounds=(0.0, 1.0), method="trf",
                                 x_scale=1.0, max_nfev=n, xtol=XTOL, ftol=FTOL,
                                 callback=None if beat is None else futility_stop(beat, n))

    sol = run(z0, max_nfev)
    left = max_nfev - int(sol.nfev)
    # a region that collapsed without one step taken would collapse again the same way: the
    # same point, Jacobian (kept) and first radius (a reference fitted from its optimum)
    if sol.status != _XTOL_STOP or left < MIN_RESTART_NFEV or np.array_equal(sol.x, z0):
        return sol
    again = run(sol.x, left)
    best = again if again.cost < sol.cost else sol
    best.nfev = int(sol.nfev) + int(again.nfev)  # every evaluation the fit spent
    return best


# Gauss-Newton iterations of at_own_starts per parameter of the element's own (+ 1), and
# the share of the fitting error it must take off (less moves the parameters by their fit's
# noise)
OWN_STARTS_ITERATIONS = 8
OWN_STARTS_GAIN = 0.01


def at_own_starts(m: mdl.Model, names: Sequence[str], tests: Sequence[TestData],
                  chans: Sequence[str], scales: dict[str, float], settle: int,
                  readjusted: Sequence[fx.Param] = (), workers: int = 1
                  ) -> tuple[mdl.Model, float, float] | None:
    """m's positive parameters ``names`` (an accepted element's own) fitted again on
    ``tests`` with each record's initial state estimated under every model tried
    (initial.apply), where some record does not start at rest: (the model, its fitting
    error, m's, both at their own states). A candidate is fitted at the states its start
    puts the records in (initial.starts_under), and an element's parameters then fit those
    states too: blind case 309 (cut from a run), a contact's delta and kb 2.8e-5 m and
    6.7e5 N/m for 5e-5 and 8.8e5, fitting error 0.0254 where the truth's is 0.0223; fitted
    here 5.7e-5 and 7.8e5, 0.0214. The declared parameters the element's fit re-adjusted
    (``readjusted``, in the ranges that fit had: uncertain_params) are fitted again with
    them: they traded with the element at the old states (blind sweep case 8, a friction
    joint that never slides: its dashpot fitted at 2 x the truth's beside a re-adjusted mass
    and modal damping, 3.1 x the ideal held-out error; with them, 0.95 x; unbounded, the
    BRFD damper's k1 went to 1/70 and its beta to 70 x). The Jacobian's columns run on up
    to ``workers`` processes.
    None when no record's state is estimated, no name is positive or the fit lowers the
    error by less than OWN_STARTS_GAIN. The tests keep the states they had
    (initial.kept)."""
    pm = m.parameters()
    own = [n for n in names if pm.get(n, 0.0) > 0]
    ranges = [p for p in readjusted if p.log and pm.get(p.name, 0.0) > 0 and p.name not in own]
    names = [*own, *(p.name for p in ranges)]
    if not own or not m.elements or all(t.start_x0 is None for t in tests):
        return None

    p0 = np.array([pm[n] for n in names])
    lower = [-np.inf] * len(own) + [min(1.0 + math.log(p.lower / pm[p.name]), 1.0)
                                    for p in ranges]
    upper = [np.inf] * len(own) + [max(1.0 + math.log(p.upper / pm[p.name]), 1.0)
                                   for p in ranges]

    def model(z: np.ndarray) -> mdl.Model:
        # z = 1 + log(p / p0): forward_jacobian's steps, 1e-3 x z, are 0.1 % of p near p0
        p = p0 * np.exp(z - 1.0)
        return m.with_params({n: float(v) for n, v in zip(names, p, strict=True)})

    size = residual_size(tests, chans)

    def fun(z: np.ndarray) -> np.ndarray:
        mm = model(z)
        try:
            initial.apply(mm, tests, chans, scales, settle, quiet=True)
        except ConfigError:
            return np.full(size, _PENALTY)
        r = residual_vector(mm, tests, chans, scales)
        return np.full(size, _PENALTY) if r is None else r

    z0 = np.ones(len(names))
    with initial.kept(tests), forward_jacobian(fun, workers) as (fun_at, jac):
        f0 = fun_at(z0)
        # max_nfev counts the steps, not the Jacobians' evaluations
        sol = least_squares(fun_at, z0, jac=jac, bounds=(lower, upper), x_scale=1.0,
                            max_nfev=OWN_STARTS_ITERATIONS * (len(own) + 1))
    before, after = float(f0 @ f0), float(sol.fun @ sol.fun)
    log.info("at each model's own initial states: %s, %d steps, fitting error %.4g -> %.4g",
             ", ".join(names), sol.nfev, before, after)
    return (model(sol.x), after, before) if after < (1 - OWN_STARTS_GAIN) * before else None


def fit(m: mdl.Model, cand: fx.Candidate, init: Sequence[float], tests: Sequence[TestData],
        chans: Sequence[str], scales: dict[str, float], max_nfev: int = 40,
        uncertain: Sequence[str] = (), workers: int = 1, beat: float | None = None,
        declared_start: Mapping[str, float] | None = None) -> FitResult:
    """Fit the candidate's parameters, and with them the declared parameters named in
    ``uncertain`` (re-adjusted jointly, so an effect they had absorbed can show). The
    Jacobian's columns run on up to ``workers`` processes (the same numbers on any count).
    A start far worse than no effect is weakened first (temper). ``beat``: the fitting
    tests' normalised SSE the fit must get under to be of use (a reference's): it is stopped
    where it could not (futility_stop). ``declared_start``: values of some of ``uncertain``
    the start ``init`` takes instead of m's (its other starts, EffectType.other_starts, keep
    m's; the search ranges are m's)."""
    base = m.with_params(dict(declared_start)) if declared_start else m
    # records that do not start at rest start where the candidate at its start puts them
    with initial.starts_under(fx.by_type(cand.type).apply(base, cand, init), tests, chans,
                              scales):
        pb = problem(m, cand, temper(base, cand, init, tests, chans, scales), tests, chans,
                     scales, uncertain, declared_start)
        with forward_jacobian(pb.fun, workers) as (fun_at, jac):
            sol = min((_solve(fun_at, jac, z0, max_nfev, beat) for z0 in (pb.z0, *pb.z_others)),
                      key=lambda s: float(np.sum(s.fun ** 2)))
    ps_all = pb.params
    vals = pb.values(sol.x)
    mm = pb.build(vals)
    r = sol.fun
    nsse = float(np.sum(r * r))
    factor = n_eff_factor(r)
    sig = [math.nan] * len(ps_all)
    try:
        jtj = sol.jac.T @ sol.jac
        if not np.all(np.isfinite(jtj)):  # LAPACK's SVD may not return on overflowed values
            raise ValueError("the Jacobian overflowed")
        s2 = nsse / max(r.size - len(ps_all), 1)
        cov_z = np.linalg.pinv(jtj) * s2 * factor
        # dv/dz
        for i, p in enumerate(ps_all):
            sig[i] = float(abs(_dv_dz(p, vals[i])) * math.sqrt(max(cov_z[i, i], 0.0)))
    except (np.linalg.LinAlgError, ValueError):
        pass
    names = ([p.name for p in ps_all[:pb.n_effect]]
             + [f"{p.name}{READJUSTED}" for p in ps_all[pb.n_effect:]])
    units = [p.unit for p in ps_all]
    return FitResult(cand, names, units, vals, sig, mm, nsse, int(sol.nfev), bool(sol.success),
                     str(sol.message), factor)


def scatter(m: mdl.Model, res: FitResult, tests: Sequence[TestData], chans: Sequence[str],
            scales: dict[str, float], uncertain: Sequence[str] = (), max_nfev: int = 15,
            workers: int = 1) -> list[float]:
    """Model-form uncertainty from the test-to-test scatter: the fit of ``res`` repeated on
    each test alone (from its joint optimum), and the standard error of their mean per
    parameter, std / sqrt(k), widened by t(0.975, k - 1) / z(0.975) so that +-2 of it is the
    Student-t 95 % interval of a mean of k tests (x2.2 for 3 tests; NaN with fewer than 2).
    A model of the right form scatters as its noise says; a wrong form scatters more, and its
    Gauss-Newton sigma alone (which assumes the form right) would be far too small."""
    npar = len(res.values) - len(uncertain)

    def alone(t: TestData) -> list[float] | None:
        try:
            return fit(m, res.cand, res.values[:npar], [t], chans, scales, max_nfev,
                       uncertain).values
        except ConfigError as exc:
            log.debug("%s on %s alone: %s", res.cand.label, t.name, exc)
            return None

    per = [v for v in parallel.ordered_map(alone, tests, workers) if v is not None]
    if len(per) < 2:
        return [math.nan] * len(res.values)
    v = np.array(per)
    k = v.shape[0]
    widen = float(_stats.t.ppf(0.975, k - 1) / _stats.norm.ppf(0.975))
    return [float(x) for x in widen * v.std(axis=0, ddof=1) / math.sqrt(k)]
