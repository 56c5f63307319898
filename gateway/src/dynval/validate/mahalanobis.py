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
"""
from __future__ import annotations

import importlib
import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError

log = logging.getLogger(__name__)


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
        z = np.atleast_2d(self.standardise(x))
        return np.asarray(np.einsum("ij,jk,ik->i", z, self.inv, z))

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


def ledoit_wolf(z: np.ndarray) -> tuple[np.ndarray, float]:
    """Ledoit-Wolf shrunk covariance of the rows of z (scikit-learn) and its shrinkage."""
    try:
        cov_mod = importlib.import_module("sklearn.covariance")
    except ImportError as exc:
        raise ConfigError("shrinkage covariance needs scikit-learn (pip install "
                          "'dynval[validate]')") from exc
    lw = cov_mod.LedoitWolf(assume_centered=False).fit(z)
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
    d = np.einsum("ij,jk,ik->i", z, inv, z)
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


def paired_test(base: Baseline, x_exp: np.ndarray, x_model: np.ndarray,
                level: float = 0.95) -> dict[str, Any]:
    """Hotelling one-sample T^2 test of the paired residuals r_k = z_k - z_k^model (the model
    driven by test k's own measured force, standardised features): H0 "the model has no bias".
    T^2 = n r_bar^T S_r^-1 r_bar, (n - p) / (p (n - 1)) T^2 ~ F(p, n - p). Far more sensitive
    than eq. 41 against the whole baseline, because the force's randomness cancels in the pair.
    Needs n > p tests; else reports pass = None."""
    r = base.standardise(x_exp) - base.standardise(x_model)
    n, p = r.shape
    out: dict[str, Any] = {"test": "paired Hotelling T^2 (model bias = 0)", "n": n, "p": p,
                           "mean_residual": r.mean(axis=0).tolist(), "level": level}
    if n <= p:
        out.update({"pass": None, "note": f"needs more tests than features ({n} <= {p})"})
        return out
    stats = importlib.import_module("scipy.stats")
    rb = r.mean(axis=0)
    s = np.cov(r, rowvar=False, ddof=1).reshape(p, p)
    t2 = float(n * rb @ np.linalg.lstsq(s, rb, rcond=None)[0])
    f = (n - p) / (p * (n - 1)) * t2
    pv = float(stats.f.sf(f, p, n - p))
    out.update({"t2": t2, "f": f, "p_value": pv, "pass": bool(pv >= 1 - level)})
    return out
