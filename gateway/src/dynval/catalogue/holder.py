"""The Holder exponent of report Section 5.3.5 (eq. 25-26): the slope of log |Wx(u, s)| against
log s at every time u, from a continuous wavelet transform (PyWavelets); drop-offs of the
exponent mark singularities such as impacts.

The modulus is normalised by 1/s (not the 1/sqrt(s) of eq. 25) so the slope is the Holder
exponent itself: 0 at a step, -1 at a spike, the wavelet's vanishing moments (2) where the
signal is smooth. The default wavelet is the complex Gaussian derivative 'cgau2': its modulus
has no zero crossings on an oscillation, which with a real wavelet make false drops every half
period; the default scales (2..16 samples) stay above the one-sample scale where sensor noise
(exponent -1/2) rules.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError

WAVELET = "cgau2"
SCALES = tuple(float(s) for s in np.geomspace(2.0, 16.0, 8))
DROP_Z = 4.0  # a drop-off: the exponent this many robust STDs below its median
EDGE = 64  # samples at each end left out (the transform's edge effect at the largest scale)


def _pywt() -> Any:
    try:
        return importlib.import_module("pywt")
    except ImportError as e:
        raise ConfigError("the Holder exponent needs PyWavelets (pip install PyWavelets)") from e


def holder_exponent(x: np.ndarray, scales: tuple[float, ...] = SCALES,
                    wavelet: str = WAVELET) -> np.ndarray:
    """The Holder exponent at every sample of x (eq. 26): least-squares slope of log of the
    1/s-normalised wavelet modulus against log s."""
    if np.size(x) < 4 * max(scales):
        raise ConfigError(f"Holder exponent: {np.size(x)} samples for scales up to "
                          f"{max(scales):g}")
    s = np.asarray(scales, dtype=np.float64)
    w, _ = _pywt().cwt(np.asarray(x, dtype=np.float64), s, wavelet)
    lm = np.log(np.abs(w) / np.sqrt(s)[:, None] + 1e-300)
    ls = np.log(s) - np.mean(np.log(s))
    return np.asarray(ls @ (lm - lm.mean(axis=0)) / (ls @ ls))


@dataclass(frozen=True)
class Drops:
    """Drop-offs of the Holder exponent: sample indices (the minimum of each run below the
    threshold), their times, depths below the median, and the threshold used."""

    index: np.ndarray
    times_s: np.ndarray
    depth: np.ndarray
    threshold: float

    @property
    def count(self) -> int:
        return int(self.index.size)


def drop_offs(h: np.ndarray, fs_hz: float, z: float = DROP_Z, edge: int = EDGE) -> Drops:
    """Runs of h below median - z x 1.4826 MAD (away from the ends), one drop-off per run."""
    med = float(np.median(h[edge:-edge]))
    spread = 1.4826 * float(np.median(np.abs(h[edge:-edge] - med)))
    thr = med - z * spread
    low = h < thr
    low[:edge] = False
    low[-edge:] = False
    edges = np.diff(low.astype(np.int8), prepend=0, append=0)
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    idx = np.array([a + int(np.argmin(h[a:b])) for a, b in zip(starts, stops, strict=True)],
                   dtype=np.int64)
    return Drops(idx, idx / fs_hz, med - h[idx] if idx.size else np.zeros(0), thr)


def match_events(found_s: np.ndarray, true_s: np.ndarray, tol_s: float
                 ) -> tuple[int, int]:
    """(hits, false alarms): true events with a found one within tol_s, and found ones with no
    true event within tol_s."""
    f, t = np.asarray(found_s), np.asarray(true_s)
    hits = int(sum(np.any(np.abs(f - e) <= tol_s) for e in t)) if f.size else 0
    fa = int(sum(not np.any(np.abs(t - e) <= tol_s) for e in f)) if t.size else int(f.size)
    return hits, fa
