"""Bayesian calibration of model parameters against experimental feature vectors
(report Section 6.1.2.2, 6.2.5.2).

Statistical model (paired). Each of the m training tests k gives a standardised feature vector
z_k (standardised by the experimental baseline) and its measured force drives the model:
eta_k(theta), simulated as measured (measurement.py: the validation input hold, the tests'
sensor noise on the simulated outputs, one draw per test for every theta). The residuals
B (z_k - eta_k(theta*)) are independent N(0, R) in the reduced coordinates (B: the leading
principal directions of the sweep's features, at most 8 and at most m - 2); R holds the
sensor noise of both sides and the test-to-test scatter of the structure; the forces' own
randomness cancels in the pairing. R is not known: it is estimated from the m residuals at
the sweep run closest to the tests (residual_at_best) and integrated out under the Jeffreys
prior, which turns the Gaussian likelihood of the mean residual into a multivariate t:

    log L(theta) = -(m/2) log(1 + Q / (m - 1)) - 1/2 log det Sigma,
    Q = r^T Sigma^-1 r,  r = B (z_obs - eta(theta)),  Sigma = S / m_mean + diag(emulator var)

with S the sample covariance of the m residuals, z_obs and eta the means over the m_mean tests
whose forces drive the simulations. A plug-in Gaussian (the t's limit for many tests) made the
intervals too narrow with 8 tests; the t is what makes the 95 % intervals cover (table in
gateway/docs/validate-error-rates.md). The prior is uniform on the parameter ranges; the
posterior is sampled with emcee (affine-invariant ensemble MCMC) in unit-cube coordinates:

* ``gp``: the report's way. A Latin-hypercube sweep, one scikit-learn GaussianProcessRegressor
  per reduced coordinate (constant x anisotropic RBF + white noise) as the emulator of eta, its
  predictive variance added to Sigma;
* ``direct``: eta from the C model itself at every MCMC step (walkers evaluated in parallel by
  the sweep Runner), with the forces of fewer tests (m_mean is smaller: a wider posterior, the
  price of m_mean simulations per step).
"""
from __future__ import annotations

import importlib
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval.errors import ConfigError
from dynval.validate.doe import ParamRange, Runner, SweepJob, as_sets, latin_hypercube
from dynval.validate.mahalanobis import Baseline, quad
from dynval.validate.sensitivity import pca

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]


def _emcee() -> Any:
    try:
        return importlib.import_module("emcee")
    except ImportError as exc:
        raise ConfigError("calibration needs emcee (pip install 'dynval[validate]')") from exc


@dataclass
class Target:
    """What the calibration matches, in reduced standardised feature units: z_obs, the mean
    feature vector of the m_mean tests whose measured forces drive the simulations; resid_cov
    (q x q), the sample covariance of one test's reduced residual, from m_cov tests; basis B
    (q x p)."""

    baseline: Baseline
    z_obs: np.ndarray
    resid_cov: np.ndarray
    basis: np.ndarray
    m_forces: int
    m_cov: int

    @property
    def q(self) -> int:
        return int(self.basis.shape[0])

    def obs(self) -> np.ndarray:
        return np.asarray(self.basis @ self.z_obs)

    def cov(self) -> np.ndarray:
        return np.asarray(self.resid_cov / self.m_forces)

    def reduce(self, feats_mean: np.ndarray) -> np.ndarray:
        """Raw mean feature vectors (rows) -> reduced standardised coordinates."""
        return np.asarray(self.baseline.standardise(feats_mean) @ self.basis.T)


def choose_basis(base: Baseline, sweep_mean_feats: np.ndarray, m_cov: int,
                 frac: float = 0.999, q_max: int = 8) -> np.ndarray:
    """B: the leading principal directions of the sweep's standardised features, at most
    m_cov - 2 of them (the t likelihood needs m_cov - q >= 2 degrees of freedom)."""
    pc = pca(base.standardise(sweep_mean_feats))
    q = max(1, min(pc.n_for(frac), q_max, base.p, m_cov - 2))
    return np.asarray(pc.components[:q])


def residual_at_best(base: Baseline, test_feats: np.ndarray, sweep_feats: np.ndarray
                     ) -> tuple[np.ndarray, int]:
    """The standardised paired residuals z_k - eta_k (m, p) at the sweep run closest to the
    tests (smallest Mahalanobis distance of the mean residual): test_feats (m, p) raw,
    sweep_feats (runs, m, p) raw, simulated with the same m forces. Returns (residuals, run)."""
    z = base.standardise(test_feats)
    eta = base.standardise(sweep_feats)
    r_mean = z.mean(axis=0)[None, :] - eta.mean(axis=1)
    d = quad(r_mean, base.inv)
    d[~np.isfinite(d)] = np.inf
    j = int(np.argmin(d))
    return np.asarray(z - eta[j]), j


def make_target(base: Baseline, test_feats: np.ndarray, resid: np.ndarray,
                basis: np.ndarray) -> Target:
    """Target for simulations driven by the forces of the tests whose raw features are the
    rows of test_feats (paired); resid: the residuals (m_cov, p) the covariance comes from."""
    z = base.standardise(test_feats)
    w = resid @ basis.T
    q = basis.shape[0]
    cov = np.cov(w, rowvar=False, ddof=1).reshape(q, q)
    cov = cov + 1e-9 * float(np.trace(cov)) / q * np.eye(q)
    return Target(base, np.asarray(z.mean(axis=0)), cov, basis, int(z.shape[0]),
                  int(resid.shape[0]))


@dataclass
class Posterior:
    method: str
    names: list[str]
    samples: np.ndarray
    acceptance: float
    autocorr: list[float]
    n_model_runs: int
    seconds: float
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def mean(self) -> np.ndarray:
        return np.asarray(self.samples.mean(axis=0))

    @property
    def std(self) -> np.ndarray:
        return np.asarray(self.samples.std(axis=0, ddof=1))

    @property
    def corr(self) -> np.ndarray:
        return np.atleast_2d(np.corrcoef(self.samples, rowvar=False))

    def as_params(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.mean, strict=True)}

    def interval(self, level: float = 0.95) -> np.ndarray:
        """Equal-tailed credible interval of each parameter: (2, k) lower and upper rows."""
        a = 50 * (1 - level)
        return np.asarray(np.percentile(self.samples, [a, 100 - a], axis=0))

    def summary(self, level: float = 0.95) -> dict[str, Any]:
        q = np.percentile(self.samples, [2.5, 50, 97.5], axis=0)
        iv = self.interval(level)
        return {"method": self.method, "interval_level": level, "parameters": {
            n: {"mean": float(self.mean[j]), "std": float(self.std[j]),
                "q2.5": float(q[0, j]), "median": float(q[1, j]), "q97.5": float(q[2, j]),
                "lo": float(iv[0, j]), "hi": float(iv[1, j])}
            for j, n in enumerate(self.names)},
            "correlation": self.corr.tolist(), "n_samples": int(self.samples.shape[0]),
            "acceptance": self.acceptance, "autocorr_steps": self.autocorr,
            "n_model_runs": self.n_model_runs, "seconds": self.seconds, **self.extra}


def _loglik(target: Target, w: np.ndarray, var: np.ndarray | None = None) -> np.ndarray:
    """log L of reduced predictions w (rows) with optional extra diagonal variance rows: the
    multivariate t of the module doc (R integrated out)."""
    r = target.obs()[None, :] - w
    c = np.broadcast_to(target.cov(), (w.shape[0], target.q, target.q)).copy()
    if var is not None:
        idx = np.arange(target.q)
        c[:, idx, idx] += var
    sign, logdet = np.linalg.slogdet(c)
    ok = np.all(np.isfinite(r), axis=1) & (sign > 0)
    out = np.full(w.shape[0], -np.inf)
    if ok.any():
        sol = np.linalg.solve(c[ok], r[ok][:, :, None])[:, :, 0]
        qf = np.sum(r[ok] * sol, axis=1)
        m = target.m_cov
        out[ok] = -0.5 * m * np.log1p(qf / (m - 1)) - 0.5 * logdet[ok]
    return out


def _run_emcee(logp: Callable[[np.ndarray], np.ndarray], p0: np.ndarray, steps: int,
               seed: int, on_progress: Progress | None) -> tuple[np.ndarray, float, list[float]]:
    emcee = _emcee()
    nw, k = p0.shape
    sampler = emcee.EnsembleSampler(nw, k, logp, vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()  # reproducible moves
    for i, _ in enumerate(sampler.sample(p0, iterations=steps)):
        if on_progress is not None:
            on_progress(i + 1, steps)
    burn = steps // 3
    chain = sampler.get_chain(discard=burn, flat=True)
    try:
        tau = [float(t) for t in sampler.get_autocorr_time(discard=burn, tol=0)]
    except Exception:  # emcee's AutocorrError on very short chains
        tau = [float("nan")] * k
    return np.asarray(chain), float(np.mean(sampler.acceptance_fraction)), tau


def _in_box(u: np.ndarray) -> np.ndarray:
    return np.asarray(np.all((u >= 0.0) & (u <= 1.0), axis=1))


def _init_walkers(u_best: np.ndarray, nw: int, rng: np.random.Generator,
                  spread: float = 0.03) -> np.ndarray:
    """Walkers around the best points (unit cube), clipped inside the box."""
    idx = rng.integers(0, u_best.shape[0], nw)
    p0 = u_best[idx] + spread * rng.standard_normal((nw, u_best.shape[1]))
    return np.asarray(np.clip(p0, 1e-4, 1 - 1e-4))


@dataclass
class Emulator:
    """One GaussianProcessRegressor per reduced coordinate, over unit-cube inputs."""

    gps: list[Any]

    def predict(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mu = np.empty((u.shape[0], len(self.gps)))
        var = np.empty_like(mu)
        for j, gp in enumerate(self.gps):
            m, s = gp.predict(u, return_std=True)
            mu[:, j] = m
            var[:, j] = np.asarray(s) ** 2
        return mu, var


def fit_emulator(u: np.ndarray, w: np.ndarray, seed: int = 0) -> Emulator:
    """Fit the GP emulator of the reduced coordinates w (runs x q) over inputs u (unit cube)."""
    try:
        gpm = importlib.import_module("sklearn.gaussian_process")
        kern = importlib.import_module("sklearn.gaussian_process.kernels")
    except ImportError as exc:
        raise ConfigError("the GP emulator needs scikit-learn (pip install "
                          "'dynval[validate]')") from exc
    warnings = importlib.import_module("warnings")
    ok = np.all(np.isfinite(w), axis=1)
    u, w = u[ok], w[ok]
    k = u.shape[1]
    gps = []
    for j in range(w.shape[1]):
        kernel = (kern.ConstantKernel(1.0, (1e-3, 1e4))
                  * kern.RBF(length_scale=np.full(k, 0.3), length_scale_bounds=(1e-2, 1e2))
                  + kern.WhiteKernel(1e-4, (1e-10, 1e0)))
        gp = gpm.GaussianProcessRegressor(kernel=kernel, normalize_y=True,
                                          n_restarts_optimizer=1, random_state=seed)
        with warnings.catch_warnings():  # bound hits are expected for very smooth responses
            warnings.simplefilter("ignore")
            gp.fit(u, w[:, j])
        gps.append(gp)
    return Emulator(gps)


def _fit_check(emu: Emulator, u: np.ndarray, w: np.ndarray) -> list[float]:
    """RMS of (emulator - sweep) at the sweep points over each coordinate's STD."""
    mu, _ = emu.predict(u)
    ok = np.all(np.isfinite(w), axis=1)
    err = np.sqrt(np.mean((mu[ok] - w[ok]) ** 2, axis=0))
    sd = w[ok].std(axis=0)
    return [float(e / s) if s > 0 else 0.0 for e, s in zip(err, sd, strict=True)]


def to_unit(ranges: Sequence[ParamRange], x: np.ndarray) -> np.ndarray:
    return np.column_stack([r.unit(x[:, j]) for j, r in enumerate(ranges)])


def from_unit(ranges: Sequence[ParamRange], u: np.ndarray) -> np.ndarray:
    return np.column_stack([r.scale(u[:, j]) for j, r in enumerate(ranges)])


def calibrate_gp(target: Target, ranges: Sequence[ParamRange], x_sweep: np.ndarray,
                 sweep_mean_feats: np.ndarray, *, walkers: int = 32, steps: int = 1500,
                 seed: int = 0, on_progress: Progress | None = None
                 ) -> tuple[Posterior, Emulator]:
    """GP emulator over the sweep (x_sweep rows = parameter sets; their features averaged over
    the target's forces) + emcee on the emulator."""
    t0 = time.perf_counter()
    u = to_unit(ranges, x_sweep)
    w = target.reduce(sweep_mean_feats)
    emu = fit_emulator(u, w, seed)
    fit_err = _fit_check(emu, u, w)

    def logp(uu: np.ndarray) -> np.ndarray:
        out = np.full(uu.shape[0], -np.inf)
        inb = _in_box(uu)
        if inb.any():
            mu, var = emu.predict(uu[inb])
            out[inb] = _loglik(target, mu, var)
        return out

    rng = np.random.default_rng(seed)
    ll = _loglik(target, w)
    best = u[np.argsort(-ll)[: max(4, walkers // 4)]]
    chain, acc, tau = _run_emcee(logp, _init_walkers(best, walkers, rng), steps, seed,
                                 on_progress)
    post = Posterior("gp", [r.name for r in ranges], from_unit(ranges, chain), acc, tau,
                     int(x_sweep.shape[0]) * target.m_forces, time.perf_counter() - t0,
                     {"emulator": {"kernels": [str(g.kernel_) for g in emu.gps],
                                   "fit_rms_over_scatter": fit_err},
                      "walkers": walkers, "steps": steps, "burn_in": steps // 3,
                      "reduced_dims": target.q, "forces": target.m_forces})
    return post, emu


def calibrate_direct(target: Target, ranges: Sequence[ParamRange], job: SweepJob,
                     runner: Runner, *, start: np.ndarray | None = None, walkers: int = 16,
                     steps: int = 300, pilot: int = 48, seed: int = 0,
                     on_progress: Progress | None = None) -> Posterior:
    """emcee with the C model in the loop (the job's forces must be the target's tests').
    start: parameter sets (rows) to start the walkers from (e.g. GP posterior samples); else
    around the best runs of a small pilot Latin hypercube."""
    if len(job.forces) != target.m_forces:
        raise ConfigError(f"direct calibration: {len(job.forces)} forces for a target of "
                          f"{target.m_forces} tests")
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed + 1)
    n_runs = 0

    def predict(uu: np.ndarray) -> np.ndarray:
        nonlocal n_runs
        res = runner.run(job, as_sets(ranges, from_unit(ranges, uu)))
        n_runs += uu.shape[0] * len(job.forces)
        return target.reduce(res.mean_features)

    if start is None:
        up = to_unit(ranges, latin_hypercube(ranges, pilot, seed + 7))
        ll = _loglik(target, predict(up))
        p0 = _init_walkers(up[np.argsort(-ll)[: max(4, walkers // 4)]], walkers, rng)
    else:
        us = to_unit(ranges, start)
        p0 = np.clip(us[rng.integers(0, us.shape[0], walkers)], 1e-4, 1 - 1e-4)

    def logp(uu: np.ndarray) -> np.ndarray:
        out = np.full(uu.shape[0], -np.inf)
        inb = _in_box(uu)
        if inb.any():
            out[inb] = _loglik(target, predict(uu[inb]))
        return out

    chain, acc, tau = _run_emcee(logp, p0, steps, seed, on_progress)
    return Posterior("direct", [r.name for r in ranges], from_unit(ranges, chain), acc, tau,
                     n_runs, time.perf_counter() - t0,
                     {"walkers": walkers, "steps": steps, "burn_in": steps // 3,
                      "reduced_dims": target.q, "oversample": job.oversample,
                      "forces": len(job.forces)})


def compare(a: Posterior, b: Posterior) -> dict[str, Any]:
    """Difference of the posterior means in units of the larger posterior STD, STD ratio."""
    sd = np.maximum(a.std, b.std)
    return {n: {"mean_diff": float(a.mean[j] - b.mean[j]),
                "in_std": float((a.mean[j] - b.mean[j]) / sd[j]) if sd[j] > 0 else 0.0,
                "std_ratio": float(a.std[j] / b.std[j]) if b.std[j] > 0 else float("nan")}
            for j, n in enumerate(a.names)}
