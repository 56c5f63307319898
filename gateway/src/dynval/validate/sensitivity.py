"""Global sensitivity (ANOVA R^2, report eq. 42-44, Table 19) and PCA of feature vectors
(Table 20)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError


def anova_r2(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """R^2 of each feature (columns of y) for each parameter (columns of x), from a design
    whose parameters take a few discrete levels (a full factorial): runs are grouped by the
    level of parameter j and R^2 = 1 - SS_within / SS_total (eq. 44). Returns (p, k)."""
    xa = np.atleast_2d(np.asarray(x, dtype=np.float64))
    ya = np.asarray(y, dtype=np.float64)
    if ya.ndim == 1:
        ya = ya[:, None]
    if xa.shape[0] != ya.shape[0]:
        raise ConfigError(f"anova_r2: {xa.shape[0]} parameter rows for {ya.shape[0]} runs")
    ok = np.all(np.isfinite(ya), axis=1)
    xa, ya = xa[ok], ya[ok]
    out = np.zeros((ya.shape[1], xa.shape[1]))
    sst = np.sum((ya - ya.mean(axis=0)) ** 2, axis=0)
    for j in range(xa.shape[1]):
        levels = np.unique(xa[:, j])
        if levels.size > max(10, xa.shape[0] // 2):
            raise ConfigError("anova_r2 needs a design with discrete levels (a full factorial), "
                              f"parameter {j} has {levels.size} distinct values")
        ssw = np.zeros(ya.shape[1])
        for lv in levels:
            g = ya[xa[:, j] == lv]
            ssw += np.sum((g - g.mean(axis=0)) ** 2, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, j] = np.where(sst > 0, 1.0 - ssw / sst, 0.0)
    return out


def anova_table(x: np.ndarray, y: np.ndarray, params: Sequence[str],
                labels: Sequence[str]) -> list[dict[str, Any]]:
    """Rows {feature, r2: {param: R^2}, share: {param: R^2 / sum R^2}} (Table 19 reports the
    share in percent)."""
    r2 = anova_r2(x, y)
    rows = []
    for i, lab in enumerate(labels):
        tot = float(r2[i].sum())
        rows.append({"feature": lab, "r2": {p: float(r2[i, j]) for j, p in enumerate(params)},
                     "share": {p: float(r2[i, j] / tot) if tot > 0 else 0.0
                               for j, p in enumerate(params)}})
    return rows


@dataclass(frozen=True)
class PCA:
    """Principal components of standardised feature vectors: components (q, p) rows,
    singular values, explained-variance fractions, mean."""

    mean: np.ndarray
    components: np.ndarray
    singular: np.ndarray
    explained: np.ndarray

    def n_for(self, frac: float) -> int:
        """Components needed to hold frac of the variance (Table 20: 2 hold 98 %)."""
        c = np.cumsum(self.explained)
        return int(min(c.size, int(np.searchsorted(c, frac - 1e-12)) + 1))

    def project(self, z: np.ndarray, q: int | None = None) -> np.ndarray:
        comp = self.components if q is None else self.components[:q]
        return np.asarray((np.atleast_2d(z) - self.mean) @ comp.T)

    def summary(self, frac: float = 0.98) -> dict[str, Any]:
        return {"singular_values": self.singular.tolist(),
                "explained": self.explained.tolist(),
                "cumulative": np.cumsum(self.explained).tolist(),
                "n_components_98": self.n_for(frac)}


def pca(z: np.ndarray) -> PCA:
    """PCA (SVD) of the rows of z (already standardised; NaN rows dropped)."""
    za = np.asarray(z, dtype=np.float64)
    za = za[np.all(np.isfinite(za), axis=1)]
    if za.shape[0] < 2:
        raise ConfigError("PCA needs at least 2 finite feature vectors")
    mean = za.mean(axis=0)
    _, s, vt = np.linalg.svd(za - mean, full_matrices=False)
    var = s ** 2
    tot = float(var.sum())
    expl = var / tot if tot > 0 else np.zeros_like(var)
    return PCA(mean, vt, s, expl)
