"""FRF (H1, H2) and coherence by Welch averaging (report 5.3.1, eq. 22-23), and the report's
linearity check (one input/output pair at two excitation levels) and reciprocity check (input
and response locations swapped) reduced to scalars over a band.

The spectra are scipy.signal's (csd, welch): S_uy = csd(u, y) = E[conj(U) Y], so
H1 = S_uy / S_uu, H2 = S_yy / S_yu and coherence |S_uy|^2 / (S_uu S_yy) equals
scipy.signal.coherence. Defaults are the report's EMA settings: Hanning window of 1024 points,
50 % overlap (its Section 5.1: "seven averages of a 1024 point window, with 50% overlap").
"""
from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError

signal: Any = importlib.import_module("scipy.signal")

NPERSEG = 1024
OVERLAP = 0.5
WINDOW = "hann"
# a check fails when its normalised statistic (mean z^2 over the band, about 1 for two
# estimates of one linear FRF: see compare) exceeds this
Z2_LIMIT = 2.0


@dataclass(frozen=True)
class Frf:
    """FRFs of outputs to one input: frequencies (Hz), H1, H2 and coherence (n_freq x n_out,
    column j = output names[j]), the input's auto-spectrum and the number of averages."""

    f_hz: np.ndarray
    h1: np.ndarray
    h2: np.ndarray
    coh: np.ndarray
    suu: np.ndarray
    names: tuple[str, ...]
    n_avg: int

    def band(self, band_hz: tuple[float, float]) -> np.ndarray:
        """Boolean mask of the frequencies in [lo, hi]; ConfigError if it holds none."""
        lo, hi = band_hz
        sel = (self.f_hz >= lo) & (self.f_hz <= hi)
        if not sel.any():
            raise ConfigError(f"band {lo:g}-{hi:g} Hz holds no FRF line (resolution "
                              f"{self.f_hz[1] - self.f_hz[0]:g} Hz, up to {self.f_hz[-1]:g} Hz)")
        return np.asarray(sel)


def n_averages(n: int, nperseg: int, overlap: float) -> int:
    step = nperseg - int(nperseg * overlap)
    return 1 + (n - nperseg) // step


Record = tuple[np.ndarray, Mapping[str, np.ndarray]]  # (input, output name -> samples)


def estimate(u: np.ndarray, y: Mapping[str, np.ndarray], fs_hz: float, *,
             nperseg: int = NPERSEG, overlap: float = OVERLAP, window: str = WINDOW) -> Frf:
    """H1, H2 and coherence of each output y[name] to the input u (Welch, mean-detrended
    segments as scipy's default)."""
    return estimate_records([(u, y)], fs_hz, nperseg=nperseg, overlap=overlap, window=window)


def estimate_records(recs: Sequence[Record], fs_hz: float, *, nperseg: int = NPERSEG,
                     overlap: float = OVERLAP, window: str = WINDOW) -> Frf:
    """H1, H2 and coherence from the spectra averaged over every segment of every record
    (records of one test condition: the report's ten time histories per test)."""
    if not 0.0 <= overlap < 1.0:
        raise ConfigError(f"FRF: overlap {overlap!r} must be in [0, 1)")
    if not recs:
        raise ConfigError("FRF: no records")
    names = tuple(recs[0][1])
    kw = {"fs": fs_hz, "window": window, "nperseg": nperseg,
          "noverlap": int(nperseg * overlap)}
    suu: Any = 0.0
    suy: list[Any] = [0.0] * len(names)
    syy: list[Any] = [0.0] * len(names)
    n_avg = 0
    for u, y in recs:
        u = np.asarray(u, dtype=np.float64)
        if u.ndim != 1 or u.size < nperseg:
            raise ConfigError(f"FRF: the input needs at least nperseg = {nperseg} samples, "
                              f"got {u.size}")
        k = n_averages(u.size, nperseg, overlap)
        f, p = signal.welch(u, **kw)
        suu = suu + k * p
        for j, name in enumerate(names):
            x = np.asarray(y[name], dtype=np.float64)
            if x.shape != u.shape:
                raise ConfigError(f"FRF: output '{name}' has {x.size} samples, the input "
                                  f"{u.size}")
            suy[j] = suy[j] + k * signal.csd(u, x, **kw)[1]
            syy[j] = syy[j] + k * signal.welch(x, **kw)[1]
        n_avg += k
    sy, syy_ = np.column_stack(suy) / n_avg, np.column_stack(syy) / n_avg
    su = np.asarray(suu / n_avg)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        h1, h2 = sy / su, syy_ / np.conj(sy)  # S_yu = conj(S_uy)
        coh = np.abs(sy) ** 2 / (su * syy_)
    return Frf(f, h1, h2, coh, su[:, 0], names, n_avg)


@dataclass(frozen=True)
class Comparison:
    """Two FRF estimates of one input/output pair over a band: z2, the mean over the band of
    |H1a - H1b|^2 over the sum of their random-error variances (about 1 when both estimate
    the same linear FRF, growing when they differ); db, the mean |20 log10 |H1a| / |H1b|| (dB);
    dcoh, the mean |coh_a - coh_b|; coh_min, the lower of the two band-mean coherences;
    z2_coh, the mean over the band of the squared difference of the Fisher-transformed
    coherences over its variance (about 1 for one linear structure at one signal-to-noise
    ratio; a nonlinearity lowers the coherence more at the level or location that drives it
    harder); passed: both z2 and z2_coh <= Z2_LIMIT."""

    z2: float
    z2_coh: float
    db: float
    dcoh: float
    coh_min: float
    band_hz: tuple[float, float]

    @property
    def passed(self) -> bool:
        return self.z2 <= Z2_LIMIT and self.z2_coh <= Z2_LIMIT


def h1_variance(h1: np.ndarray, coh: np.ndarray, n_avg: int) -> np.ndarray:
    """Random-error variance of the complex H1 estimate over n averages: twice that of |H1|,
    whose normalised error is sqrt(1 - coh) / sqrt(2 n coh) (Bendat & Piersol)."""
    c = np.clip(coh, 1e-12, 1.0)
    return np.asarray(np.abs(h1) ** 2 * (1.0 - c) / (c * n_avg))


def compare(a: Frf, b: Frf, ja: int, jb: int, band_hz: tuple[float, float]) -> Comparison:
    """Output ja of a against output jb of b over the band (same frequency lines needed)."""
    if a.f_hz.shape != b.f_hz.shape or not np.allclose(a.f_hz, b.f_hz):
        raise ConfigError("FRF comparison: the two estimates have different frequency lines "
                          "(same fs and nperseg needed)")
    sel = a.band(band_hz)
    ha, hb = a.h1[sel, ja], b.h1[sel, jb]
    ca, cb = a.coh[sel, ja], b.coh[sel, jb]
    if not (np.isfinite(ha).all() and np.isfinite(hb).all()):
        raise ConfigError(f"FRF comparison: an FRF is not finite in {band_hz[0]:g}-"
                          f"{band_hz[1]:g} Hz (no input power there?)")
    var = h1_variance(ha, ca, a.n_avg) + h1_variance(hb, cb, b.n_avg)
    z2 = float(np.mean(np.abs(ha - hb) ** 2 / np.maximum(var, 1e-300)))
    # Fisher's transform: atanh(|coherence|) has a variance of about 1 / (2 n) whatever the
    # coherence
    fa, fb = (np.arctanh(np.sqrt(np.clip(c, 0.0, 1.0 - 1e-12))) for c in (ca, cb))
    z2c = float(np.mean((fa - fb) ** 2 / (0.5 / a.n_avg + 0.5 / b.n_avg)))
    db = float(np.mean(np.abs(20 * np.log10(np.abs(ha) / np.abs(hb)))))
    return Comparison(z2, z2c, db, float(np.mean(np.abs(ca - cb))),
                      float(min(np.mean(ca), np.mean(cb))), band_hz)


def linearity(u_hi: np.ndarray, y_hi: np.ndarray, u_lo: np.ndarray, y_lo: np.ndarray,
              fs_hz: float, band_hz: tuple[float, float], **kw: Any) -> Comparison:
    """The linearity check: the FRF of one output to the input at two excitation levels."""
    a = estimate(u_hi, {"y": y_hi}, fs_hz, **kw)
    b = estimate(u_lo, {"y": y_lo}, fs_hz, **kw)
    return compare(a, b, 0, 0, band_hz)


def reciprocity(u_ij: np.ndarray, y_ij: np.ndarray, u_ji: np.ndarray, y_ji: np.ndarray,
                fs_hz: float, band_hz: tuple[float, float], **kw: Any) -> Comparison:
    """The reciprocity check: H_ij (input at i, response at j) against H_ji (input at j,
    response at i); for a linear structure with a symmetric K, C they are equal."""
    a = estimate(u_ij, {"y": y_ij}, fs_hz, **kw)
    b = estimate(u_ji, {"y": y_ji}, fs_hz, **kw)
    return compare(a, b, 0, 0, band_hz)


def band_coherence(frf: Frf, band_hz: tuple[float, float]) -> np.ndarray:
    """Mean coherence over the band per output (the coherence function's scalar)."""
    return np.asarray(np.mean(frf.coh[frf.band(band_hz)], axis=0))
