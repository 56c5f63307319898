"""Mahalanobis distance against an experimental baseline (report eq. 39-41).

Features are first standardised by the experiments' mean and STD (so that magnitudes do not
dominate, the report's Fig. 74-76 lesson); the covariance S_E of the standardised experimental
vectors is the sample covariance (n - 1) when there are clearly more tests than features, else
a Ledoit-Wolf shrinkage estimate (logged). D is the quadratic form of eq. 39 (not its root).

Threshold for a verdict at level 1 - a (default 95 %):

* ``hotelling`` (sample covariance, n > p): a new vector from the experiments' population has
  D <= p (n-1)(n+1) / (n (n-p)) F_{1-a}(p, n-p) with probability 1 - a (Hotelling T^2
  prediction limit);
* ``chi2`` (shrinkage covariance): chi^2_{1-a}(p), the limit for a known covariance;
* the empirical (1 - a) percentile of the baseline distribution (eq. 40) is reported beside it
  (in-sample distances are smaller than a new test's: it is the stricter figure).

That check (``verdict``) is the size of a model's discrepancy against the test-to-test
scatter, not the study's verdict: the forces' randomness fills that scatter and a wrong model
sits inside it. The verdict is the paired test (``paired_test``): each test's measured
features against the model's driven by the same measured input; the mean residual's
Mahalanobis distance in the residuals' own metric, Hotelling's T^2 or a sign-flip test
(validate/verdict.py, gateway/docs/validate-error-rates.md). ``paired_d`` /
``paired_distance`` give the per-test residual's distance in the experiments' metric, the
size that falls as a model improves (discover's before / after).
"""
from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError

log = logging.getLogger(__name__)


def quad(z: np.ndarray, inv: np.ndarray) -> np.ndarray:
    """The Mahalanobis quadratic form z_i^T inv z_i of each row of z (eq. 39)."""
    return np.asarray(np.einsum("ij,jk,ik->i", z, inv, z))


@dataclass(frozen=True)
class Baseline:
    """The experimental baseline: standardisation, covariance and its inverse."""

    labels: tuple[str, ...]
    mean: np.ndarray
    scale: np.ndarray
    cov: np.ndarray
    inv: np.ndarray
    n: int
    shrinkage: float | None
    baseline_d: np.ndarray
    level: float

    @property
    def p(self) -> int:
        return int(self.mean.size)

    def standardise(self, x: np.ndarray) -> np.ndarray:
        return np.asarray((np.asarray(x, dtype=np.float64) - self.mean) / self.scale)

    def distance(self, x: np.ndarray) -> np.ndarray:
        """D (eq. 41) of each row of x (or of one vector)."""
        return quad(np.atleast_2d(self.standardise(x)), self.inv)

    @property
    def threshold_kind(self) -> str:
        return "chi2" if self.shrinkage is not None or self.n <= self.p else "hotelling"

    @property
    def threshold(self) -> float:
        stats = importlib.import_module("scipy.stats")
        n, p, a = self.n, self.p, self.level
        if self.threshold_kind == "chi2":
            return float(stats.chi2.ppf(a, p))
        f = float(stats.f.ppf(a, p, n - p))
        return p * (n - 1) * (n + 1) / (n * (n - p)) * f

    @property
    def empirical_threshold(self) -> float:
        return float(np.percentile(self.baseline_d, 100 * self.level))

    def summary(self) -> dict[str, Any]:
        return {"n_tests": self.n, "n_features": self.p, "labels": list(self.labels),
                "mean": self.mean.tolist(), "scale": self.scale.tolist(),
                "covariance": "ledoit-wolf" if self.shrinkage is not None else "sample",
                "shrinkage": self.shrinkage, "level": self.level,
                "threshold_kind": self.threshold_kind, "threshold": self.threshold,
                "empirical_threshold": self.empirical_threshold,
                "baseline_d": self.baseline_d.tolist()}


def ledoit_wolf(z: np.ndarray, centred: bool = False) -> tuple[np.ndarray, float]:
    """Ledoit-Wolf shrunk covariance of the rows of z (scikit-learn) and its shrinkage;
    centred: z has mean zero by assumption (the second moment about zero is shrunk)."""
    try:
        cov_mod = importlib.import_module("sklearn.covariance")
    except ImportError as exc:
        raise ConfigError("shrinkage covariance needs scikit-learn (pip install "
                          "'dynval[validate]')") from exc
    lw = cov_mod.LedoitWolf(assume_centered=centred).fit(z)
    return np.asarray(lw.covariance_, dtype=np.float64), float(lw.shrinkage_)


def fit(x_exp: np.ndarray, labels: list[str] | tuple[str, ...] = (), *,
        shrink: str = "auto", level: float = 0.95, quiet: bool = False) -> Baseline:
    """Baseline from the experimental feature vectors (rows = tests). shrink: 'auto'
    (Ledoit-Wolf when n <= p + 1, where S_E is singular or nearly so), 'always', 'never'.
    quiet: the shrinkage notice at debug level (for repeated baselines)."""
    x = np.asarray(x_exp, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 2:
        raise ConfigError(f"the baseline needs at least 2 experimental feature vectors, got "
                          f"shape {x.shape}")
    if shrink not in ("auto", "always", "never"):
        raise ConfigError(f"shrink must be auto, always or never, not {shrink!r}")
    n, p = x.shape
    lab = tuple(labels) if labels else tuple(f"f{i}" for i in range(p))
    if not np.all(np.isfinite(x)):
        bad = [lab[j] for j in range(p) if not np.all(np.isfinite(x[:, j]))]
        raise ConfigError(f"non-finite experimental features: {', '.join(bad)}")
    mean = x.mean(axis=0)
    scale = x.std(axis=0, ddof=1)
    flat = [lab[j] for j in range(p) if not scale[j] > 1e-12 * max(1.0, abs(mean[j]))]
    if flat:
        raise ConfigError(f"features constant over the experiments (no baseline spread): "
                          f"{', '.join(flat)}; drop them from the spec")
    z = (x - mean) / scale
    use_lw = shrink == "always" or (shrink == "auto" and n <= p + 1)
    if shrink == "never" and n <= p:
        raise ConfigError(f"{n} tests for {p} features: the sample covariance is singular; "
                          "allow shrinkage or use fewer features")
    alpha: float | None = None
    if use_lw:
        cov, alpha = ledoit_wolf(z)
        if n <= p + 1:
            log.log(logging.DEBUG if quiet else logging.WARNING,
                    "%d experimental tests for %d features: the sample covariance is singular "
                    "or nearly so; using Ledoit-Wolf shrinkage towards a scaled identity "
                    "(shrinkage %.3f) and the chi-square threshold", n, p, alpha)
        else:
            log.info("Ledoit-Wolf covariance (shrinkage %.3f)", alpha)
    else:
        cov = np.cov(z, rowvar=False, ddof=1).reshape(p, p)
    try:
        inv = np.linalg.inv(cov)
    except np.linalg.LinAlgError as exc:
        raise ConfigError(f"the baseline covariance is singular ({exc}); use shrinkage") from None
    inv = 0.5 * (inv + inv.T)
    d = quad(z, inv)
    return Baseline(lab, mean, scale, cov, inv, n, alpha, d, level)


def mean_distance(x_exp: np.ndarray, x_model: np.ndarray,
                  labels: list[str] | tuple[str, ...] = (), quiet: bool = False
                  ) -> tuple[float, float]:
    """Mean distance sqrt(D) of the model's feature vectors (rows of x_model) from the
    experimental baseline fit(x_exp), and the reference a valid model should land near: the
    mean leave-one-out distance of the experimental vectors themselves (each from the baseline
    of the others; NaN with fewer than 3 tests). ConfigError when no baseline can be fitted."""
    x = np.asarray(x_exp, dtype=np.float64)
    d_model = float(np.mean(np.sqrt(fit(x, labels, quiet=quiet).distance(
        np.asarray(x_model)))))
    if x.shape[0] < 3:
        return d_model, float("nan")
    loo = [float(np.sqrt(fit(np.delete(x, i, axis=0), labels, quiet=True).distance(x[i])[0]))
           for i in range(x.shape[0])]
    return d_model, float(np.mean(loo))


def verdict(base: Baseline, d_model: np.ndarray) -> dict[str, Any]:
    """Is the model inside the experimental distribution? Pass when the median of its
    distances (one per test input) is at most the stated threshold."""
    d = np.atleast_1d(np.asarray(d_model, dtype=np.float64))
    med = float(np.median(d))
    thr = base.threshold
    return {"pass": bool(med <= thr), "rule": f"median D of the model <= {base.threshold_kind} "
            f"{100 * base.level:g} % limit", "threshold": thr, "threshold_kind":
            base.threshold_kind, "empirical_threshold": base.empirical_threshold,
            "median_d": med, "fraction_within": float(np.mean(d <= thr)),
            "d": d.tolist()}


PAIRED_MIN_FLIP_TESTS = 6  # 2^6 sign patterns: the smallest p-value is 1/32 < 5 %
EXACT_FLIPS_UP_TO = 14  # all 2^n sign patterns up to this many tests, a random 2^14 beyond


@dataclass(frozen=True)
class PairedTest:
    """The paired test of "the model is right": the measured feature vectors minus the model's
    driven by each test's own measured input (both as measured: sensor noise on the simulated
    outputs too) have mean zero. ``distance`` is the Mahalanobis distance (quadratic form) of
    the mean residual from zero in the metric of the residuals' own scatter; ``p_value`` the
    probability of a distance at least as large when the model is right."""

    method: str
    n: int
    p: int
    distance: float
    p_value: float
    level: float
    mean_residual: np.ndarray
    note: str = ""

    @property
    def reject(self) -> bool | None:
        """True: the model is rejected at the level; None: no test could be made."""
        return None if not np.isfinite(self.p_value) else bool(self.p_value < 1 - self.level)

    def summary(self) -> dict[str, Any]:
        return {"test": self.method, "n": self.n, "p": self.p, "distance": self.distance,
                "p_value": self.p_value, "level": self.level, "reject": self.reject,
                "pass": None if self.reject is None else not self.reject,
                "mean_residual": self.mean_residual.tolist(), "note": self.note}


def _hotelling(r: np.ndarray) -> tuple[float, float]:
    """(r_bar^T S^-1 r_bar, p-value): one-sample Hotelling T^2 = n r_bar^T S^-1 r_bar,
    (n - p) / (p (n - 1)) T^2 ~ F(p, n - p) for Gaussian residuals of mean zero."""
    stats = importlib.import_module("scipy.stats")
    n, p = r.shape
    rb = r.mean(axis=0)
    s = np.cov(r, rowvar=False, ddof=1).reshape(p, p)
    d = float(rb @ np.linalg.lstsq(s, rb, rcond=None)[0])
    f = (n - p) / (p * (n - 1)) * n * d
    return d, float(stats.f.sf(f, p, n - p))


def _sign_patterns(n: int, seed: int) -> np.ndarray:
    if n <= EXACT_FLIPS_UP_TO:
        k = np.arange(2 ** n)[:, None]
        return np.where((k >> np.arange(n)) & 1, -1.0, 1.0)
    rng = np.random.default_rng(seed)
    s = rng.choice([-1.0, 1.0], size=(2 ** EXACT_FLIPS_UP_TO, n))
    s[0] = 1.0
    return np.asarray(s)


def _sign_flip(r: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """(r_bar^T M^-1 r_bar, p-value) by sign flipping: a right model's residuals are symmetric
    about zero, so every pattern of signs is as likely as the one observed. M is the
    Ledoit-Wolf shrunk second moment of the residuals (about zero), which no flip changes: the
    test is exact for any number of features, also more than tests."""
    n, _ = r.shape
    cov, _ = ledoit_wolf(r, centred=True)
    w = np.linalg.cholesky(np.linalg.inv(cov))
    y = r @ w  # whitened: the distance is the squared norm of the mean
    means = _sign_patterns(n, seed) @ y / n
    d_all = np.einsum("ij,ij->i", means, means)
    d = float(np.sum((y.mean(axis=0)) ** 2))
    return d, float(np.mean(d_all >= d * (1 - 1e-12)))


def paired_test_residuals(r: np.ndarray, level: float = 0.95, seed: int = 0) -> PairedTest:
    """The paired test of residual vectors r (rows = tests, standardised features): Hotelling
    T^2 when there are more than twice as many tests as features (exact for Gaussian
    residuals; with fewer its covariance has too few degrees of freedom to have power), else
    the sign-flip test (exact for symmetric residuals); no test with fewer than 6 tests."""
    r = np.atleast_2d(np.asarray(r, dtype=np.float64))
    n, p = r.shape
    rb = r.mean(axis=0)
    if not np.all(np.isfinite(r)):
        return PairedTest("none", n, p, math.nan, math.nan, level, rb,
                          "non-finite residuals (a simulation failed)")
    if n > 2 * p:
        d, pv = _hotelling(r)
        return PairedTest("hotelling", n, p, d, pv, level, rb)
    if n >= PAIRED_MIN_FLIP_TESTS:
        d, pv = _sign_flip(r, seed)
        return PairedTest("sign-flip", n, p, d, pv, level, rb,
                          f"{n} tests for {p} features (<= 2 x features): sign-flip test with a "
                          "shrunk metric")
    return PairedTest("none", n, p, math.nan, math.nan, level, rb,
                      f"{n} tests: a paired test needs at least {PAIRED_MIN_FLIP_TESTS} tests "
                      f"(or more than twice as many as features, {2 * p})")


def paired_test(base: Baseline, x_exp: np.ndarray, x_model: np.ndarray,
                level: float = 0.95) -> PairedTest:
    """The paired test of the raw feature vectors x_exp (measured, rows = tests) against
    x_model (the model driven by the same tests' inputs, as measured), standardised by the
    baseline (the test is invariant to the scaling; it keeps the numbers readable)."""
    r = base.standardise(x_exp) - base.standardise(x_model)
    return paired_test_residuals(r, level)


def paired_d(base: Baseline, x_exp: np.ndarray, x_model: np.ndarray) -> np.ndarray:
    """D (eq. 39) of each test's residual z_k - z_k^model in the experiments' metric: how far
    the model's features for test k lie from that test's measured ones, in units of the
    test-to-test scatter. A size that falls to the noise level as a model improves (eq. 41's
    distance from the experiments' mean hardly moves: the forces' randomness fills it)."""
    r = base.standardise(x_exp) - base.standardise(x_model)
    return quad(np.atleast_2d(r), base.inv)


def paired_distance(x_meas: np.ndarray, x_model: np.ndarray, labels: Sequence[str] = (),
                    level: float = 0.95) -> dict[str, Any]:
    """A model's feature vectors against the measured ones (rows = tests, the model driven by
    each test's own input, its outputs carrying simulated sensor noise): ``distance``, the
    mean over the tests of sqrt(paired_d) in the measured vectors' metric (comparable between
    models on the same tests: it moves when a model improves), and ``test``, the paired test
    (is what is left more than noise?). For discover's before / after figure."""
    base = fit(x_meas, tuple(labels), quiet=True, level=level)
    d = paired_d(base, x_meas, x_model)
    pt = paired_test(base, x_meas, x_model, level)
    return {"distance": float(np.mean(np.sqrt(d))), "d": d.tolist(), "test": pt.summary()}
