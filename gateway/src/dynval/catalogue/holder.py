"""The Holder exponent of report Section 5.3.5 (eq. 25-26): the slope of log |Wx(u, s)| against
log s at every time u, from a continuous wavelet transform (PyWavelets); drop-offs of the
exponent mark singularities such as impacts.

The modulus is normalised by 1/s (not the 1/sqrt(s) of eq. 25) so the slope is the Holder
exponent itself: 0 at a step, -1 at a spike, the wavelet's vanishing moments (2) where the
signal is smooth. The default wavelet is the complex Gaussian derivative 'cgau2': its modulus
has no zero crossings on an oscillation, which with a real wavelet make false drops every half
period; the default scales (2..16 samples) stay above the one-sample scale where sensor noise
(exponent -1/2) rules.

Drop-offs are read only where the transform speaks of the signal: outside the cone of
influence of the largest scale at either end (the wavelet's support there reaches past the
record) and where the largest scale's modulus stands at least GATE x its median over the
record (below, sensor noise rules every scale and pulls the exponent towards -1/2: a harmonic
test recorded from the switch-on had 11 such false drop-offs in its first 0.2 s, the ramp-up,
all of them beyond the 31 ms cone of influence).
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
GATE = 0.2  # drop-offs count where the largest scale's modulus is this fraction of its median


def _pywt() -> Any:
    try:
        return importlib.import_module("pywt")
    except ImportError as e:
        raise ConfigError("the Holder exponent needs PyWavelets (pip install PyWavelets)") from e


def _check(x: np.ndarray, scales: tuple[float, ...]) -> None:
    if np.size(x) < 4 * max(scales):
        raise ConfigError(f"Holder exponent: {np.size(x)} samples for scales up to "
                          f"{max(scales):g}")


def cone_of_influence(scales: tuple[float, ...] = SCALES, wavelet: str = WAVELET) -> int:
    """Samples at each end where the largest scale's wavelet reaches past the record (its
    support: pywt's bounds x the scale; 80 for cgau2 at 16)."""
    w = _pywt().ContinuousWavelet(wavelet)
    return int(np.ceil(max(abs(w.lower_bound), abs(w.upper_bound)) * max(scales)))


def _modulus(x: np.ndarray, scales: tuple[float, ...], wavelet: str) -> np.ndarray:
    """log of the 1/s-normalised wavelet modulus (scales x samples)."""
    s = np.asarray(scales, dtype=np.float64)
    w, _ = _pywt().cwt(np.asarray(x, dtype=np.float64), s, wavelet)
    return np.asarray(np.log(np.abs(w) / np.sqrt(s)[:, None] + 1e-300))


def holder_exponent(x: np.ndarray, scales: tuple[float, ...] = SCALES,
                    wavelet: str = WAVELET) -> np.ndarray:
    """The Holder exponent at every sample of x (eq. 26): least-squares slope of log of the
    1/s-normalised wavelet modulus against log s."""
    _check(x, scales)
    lm = _modulus(x, scales, wavelet)
    ls = np.log(np.asarray(scales)) - np.mean(np.log(np.asarray(scales)))
    return np.asarray(ls @ (lm - lm.mean(axis=0)) / (ls @ ls))


def readable(x: np.ndarray, scales: tuple[float, ...] = SCALES, wavelet: str = WAVELET,
             gate: float = GATE) -> np.ndarray:
    """Where x's exponent is read (boolean per sample): outside the cone of influence and
    where the largest scale's modulus is at least gate x its median (see the module doc)."""
    _check(x, scales)
    top = _modulus(x, (max(scales),), wavelet)[0]
    ok = top >= np.median(top) + np.log(gate)
    coi = cone_of_influence(scales, wavelet)
    ok[:coi] = False
    ok[-coi:] = False
    return np.asarray(ok)


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


def drop_offs(h: np.ndarray, fs_hz: float, z: float = DROP_Z,
              ok: np.ndarray | None = None) -> Drops:
    """Runs of h below median - z x 1.4826 MAD, one drop-off per run, where ok (readable(x);
    default: all but the cone of influence) holds; median and MAD over ok too."""
    if ok is None:
        ok = np.ones(h.size, dtype=bool)
        c = cone_of_influence()
        ok[:c] = False
        ok[-c:] = False
    if not ok.any():
        return Drops(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), float("nan"))
    med = float(np.median(h[ok]))
    spread = 1.4826 * float(np.median(np.abs(h[ok] - med)))
    thr = med - z * spread
    low = (h < thr) & ok
    edges = np.diff(low.astype(np.int8), prepend=0, append=0)
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    idx = np.array([a + int(np.argmin(h[a:b])) for a, b in zip(starts, stops, strict=True)],
                   dtype=np.int64)
    return Drops(idx, idx / fs_hz, med - h[idx] if idx.size else np.zeros(0), thr)


def drops_of(x: np.ndarray, fs_hz: float, z: float = DROP_Z) -> Drops:
    """The drop-offs of x's exponent where it is readable (holder_exponent, readable)."""
    return drop_offs(holder_exponent(x), fs_hz, z, readable(x))


def match_events(found_s: np.ndarray, true_s: np.ndarray, tol_s: float
                 ) -> tuple[int, int]:
    """(hits, false alarms): true events with a found one within tol_s, and found ones with no
    true event within tol_s."""
    f, t = np.asarray(found_s), np.asarray(true_s)
    hits = int(sum(np.any(np.abs(f - e) <= tol_s) for e in t)) if f.size else 0
    fa = int(sum(not np.any(np.abs(t - e) <= tol_s) for e in f)) if t.size else int(f.size)
    return hits, fa
