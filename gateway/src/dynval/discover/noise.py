"""The noise floor of each channel: the residual level a right model would leave.

It is taken from what the data offers, best evidence first, and the method is reported:

1. ``stated``: the user's noise RMS per channel (channel units);
2. ``repeats``: tests driven by the same input (a repeated run): whatever the structure does,
   it does twice, so half the variance of the difference of the two outputs is noise;
3. ``periods``: a periodic input in steady state: half the variance of the difference of
   the output one period apart (the first period, the start-up transient, left out);
4. ``input off``: stretches where the input is off (pre-trigger, run-out) once the response
   has died away: the output there is noise (hum and offset included);
5. ``out of band``: the declared model's residual outside the input band (where its
   prediction errors are small) is noise; across the band its PSD is interpolated as a power
   law between the two sides, so 1/f noise counts at its in-band level; where the upper side
   may be rolled off by an anti-alias filter, the level below the band is used flat. On a
   grid of 27 cases (white, 1/f and both; no filter, 2nd- and 8th-order anti-alias at 0.4 fs;
   input bands 20-200, 21-241 and 10-100 Hz at 640 Hz) it reads 0.83-1.47 x the true RMS,
   where the top band alone read 0.00-1.01 x; ``top band`` (0.45-0.5 fs, white-equivalent)
   when there is no room below the input band.
"""
from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

log = logging.getLogger(__name__)
signal: Any = importlib.import_module("scipy.signal")

REPEAT_CORR = 0.999  # inputs this correlated (and of equal RMS within 1 %) are repeats
PERIOD_CORR = 0.995  # a lag whose input autocorrelation reaches this is a period
QUIET_FRACTION = 0.02  # input off: windowed input RMS below this share of the record's RMS
QUIET_MIN_S = 0.25  # input-off stretches shorter than this (after settling) are not used
TOP_BAND = (0.45, 0.5)  # fraction of fs
AA_CORNER = 0.4  # fraction of fs above which a DAQ's anti-alias filter may cut the noise


class Test(Protocol):
    name: str
    fs_hz: float
    u: np.ndarray
    y: dict[str, np.ndarray]


@dataclass
class Floor:
    """Noise RMS of one channel (channel units), how it was found, and a caveat if any."""

    rms: float
    method: str
    detail: str = ""


def estimate(tests: Sequence[Test], chans: Sequence[str],
             residuals: Mapping[str, Mapping[str, np.ndarray]],
             band_hz: tuple[float, float], settle_s: float,
             stated: Mapping[str, float] | None = None) -> dict[str, Floor]:
    """The noise floor of every channel (see the module comment for the order).
    ``residuals``: the declared model's residual records (one per test, for method 5);
    ``settle_s``: how long the structure rings after the input stops (method 4)."""
    out: dict[str, Floor] = {}
    # the input of each residual record, by record (the residuals are keyed by record)
    by_record = {str(id(t.u)): t.u for t in tests}
    for c in chans:
        keys = [k for k, r in residuals.items() if c in r]
        if stated and c in stated:
            out[c] = Floor(float(stated[c]), "stated", "given by the user")
            continue
        floor = (from_repeats(tests, c) or from_periods(tests, c)
                 or from_input_off(tests, c, settle_s)
                 or spectral([residuals[k][c] for k in keys], tests[0].fs_hz, band_hz,
                             [by_record.get(k, tests[0].u) for k in keys]))
        out[c] = floor
        log.info("noise floor of %s: %.4g (%s%s)", c, floor.rms, floor.method,
                 f"; {floor.detail}" if floor.detail else "")
    return out


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b) / den) if den > 0 else 0.0


def from_repeats(tests: Sequence[Test], c: str) -> Floor | None:
    """Half the variance of output differences between tests with the same input."""
    halves = []
    pairs = 0
    for i, a in enumerate(tests):
        for b in tests[i + 1:]:
            if a.u.size != b.u.size or c not in a.y or c not in b.y or a.u.size < 64:
                continue
            sa, sb = float(np.std(a.u)), float(np.std(b.u))
            if sa <= 0 or abs(sa - sb) > 0.01 * sa or _corr(a.u, b.u) < REPEAT_CORR:
                continue
            d = a.y[c] - b.y[c]
            halves.append(float(np.var(d)) / 2.0)
            pairs += 1
    if not halves:
        return None
    return Floor(math.sqrt(float(np.mean(halves))), "repeats",
                 f"{pairs} pair(s) of tests with the same input")


def period_of(u: np.ndarray) -> int | None:
    """The input's period in samples, when it repeats at least 3 times (else None)."""
    n = u.size
    if n < 96:
        return None
    x = u - u.mean()
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: n // 3 + 1]
    if ac[0] <= 0:
        return None
    ac = ac / ac[0] * n / (n - np.arange(ac.size))  # unbiased: a repeat reaches 1
    lags = np.flatnonzero(ac[16:] >= PERIOD_CORR)
    return int(lags[0] + 16) if lags.size else None


def from_periods(tests: Sequence[Test], c: str) -> Floor | None:
    """Half the variance of the output's period-to-period difference in steady state."""
    halves = []
    for t in tests:
        p = period_of(t.u)
        if p is None or c not in t.y:
            continue
        y = t.y[c][p:]  # the first period carries the start-up transient
        if y.size < 2 * p:
            continue
        halves.append(float(np.var(y[p:] - y[:-p])) / 2.0)
    if not halves:
        return None
    return Floor(math.sqrt(float(np.mean(halves))), "periods",
                 f"periodic input in {len(halves)} test(s)")


def quiet_mask(u: np.ndarray, fs_hz: float, settle_s: float) -> np.ndarray:
    """Samples where the input has been off for at least ``settle_s`` (and stays off)."""
    w = max(8, int(0.02 * fs_hz))
    ref = float(np.sqrt(np.mean(u * u)))
    if ref <= 0:
        return np.zeros(u.size, dtype=bool)
    ms = np.convolve(u * u, np.ones(w) / w, mode="same")
    off = ms < (QUIET_FRACTION * ref) ** 2
    settle = int(settle_s * fs_hz) + w
    out = np.zeros(u.size, dtype=bool)
    # a stretch counts from settle samples after the input stopped to where it restarts
    edges = np.flatnonzero(np.diff(np.concatenate(([0], off.astype(np.int8), [0]))))
    for start, stop in zip(edges[0::2], edges[1::2], strict=True):
        first = start + (settle if start > 0 else w)  # a pre-trigger stretch needs no settling
        last = stop - w
        if last - first >= QUIET_MIN_S * fs_hz:
            out[first:last] = True
    return out


def from_input_off(tests: Sequence[Test], c: str, settle_s: float) -> Floor | None:
    """The output's RMS (about its mean: an offset is not noise) where the input is off."""
    parts = []
    for t in tests:
        if c not in t.y:
            continue
        q = quiet_mask(t.u, t.fs_hz, settle_s)
        if q.any():
            parts.append(t.y[c][q] - float(np.mean(t.y[c][q])))
    if not parts:
        return None
    v = np.concatenate(parts)
    return Floor(float(np.sqrt(np.mean(v * v))), "input off",
                 f"{v.size} samples where the input is off and the response has died away")


def _level(f: np.ndarray, p: np.ndarray, lo: float, hi: float) -> float | None:
    sel = (f >= lo) & (f <= hi)
    return float(np.median(p[sel])) if np.count_nonzero(sel) >= 4 else None


def out_of_band_power(f: np.ndarray, p: np.ndarray, band_hz: tuple[float, float]) -> float | None:
    """Noise power (variance) from the residual's PSD outside the input band: the measured
    PSD outside it, and inside it a power law between the levels just below and just above
    the band (so 1/f noise counts at the level it has inside the band). Above AA_CORNER x fs,
    or where the top band lies below half the level just above the input band, an anti-alias
    filter may roll the noise off: the level below the band is then taken flat across it.
    None without 3 bins below the band."""
    lo, hi = band_hz
    fs = 2.0 * float(f[-1])
    below = (f >= 0.5 * lo) & (f <= 0.8 * lo) & (f > 0)
    above = (f >= 1.25 * hi) & (f <= min(1.6 * hi, AA_CORNER * fs))
    top = f >= TOP_BAND[0] * fs
    if np.count_nonzero(below) < 3:
        return None
    fb, lb = float(np.median(f[below])), float(np.median(p[below]))
    model = p.copy()
    la = float(np.median(p[above])) if np.count_nonzero(above) >= 3 else 0.0
    if la <= 0 or lb <= 0 or float(np.median(p[top])) < 0.5 * la:
        model[(f >= lo) & (f <= hi)] = lb
    else:
        fa = float(np.median(f[above]))
        inside = (f > fb) & (f < fa)
        model[inside] = lb * (f[inside] / fb) ** (math.log(la / lb) / math.log(fa / fb))
    return float(np.sum(model[1:]) * float(f[1] - f[0]))


MAINS_HZ = (50.0, 60.0)
LINE_RATIO = 10.0  # a mains line stands this far above the residual's local spectrum


def mains_hum(res: Sequence[np.ndarray], inputs: Sequence[np.ndarray], fs_hz: float
              ) -> tuple[float, list[float]]:
    """Power (variance) of mains-hum lines in the residuals: narrow peaks at the harmonics of
    50 or 60 Hz that the input does not have (an electrical pick-up, not the structure's
    response), and their frequencies. A right model leaves them: they are noise."""
    power, lines = [], set()
    for r, u in zip(res, inputs, strict=True):
        f, p = signal.welch(r, fs=fs_hz, nperseg=min(1024, r.size))
        _, pu = signal.welch(u, fs=fs_hz, nperseg=min(1024, r.size))
        df = float(f[1] - f[0])
        total = 0.0
        for f0 in MAINS_HZ:
            for h in range(1, 6):
                k = int(round(h * f0 / df))
                if k < 12 or k + 12 >= f.size:
                    continue
                side = np.r_[k - 12:k - 2, k + 3:k + 13]
                base, base_u = float(np.median(p[side])), float(np.median(pu[side]))
                if p[k] > LINE_RATIO * base and pu[k] < 3 * base_u:
                    total += float(np.sum(p[k - 2:k + 3]) - 5 * base) * df
                    lines.add(h * f0)
        power.append(total)
    return (float(np.median(power)) if power else 0.0), sorted(lines)


def spectral(res: Sequence[np.ndarray], fs_hz: float, band_hz: tuple[float, float],
             inputs: Sequence[np.ndarray] | None = None) -> Floor:
    """The residual's noise power outside the input band (out_of_band_power), or, when the
    band leaves too little room on either side, the top band's white-equivalent level."""
    oob, tops = [], []
    for r in res:
        f, p = signal.welch(r, fs=fs_hz, nperseg=min(1024, r.size))
        top = _level(f, p, TOP_BAND[0] * fs_hz, TOP_BAND[1] * fs_hz)
        if top is not None:
            tops.append(top * fs_hz / 2)
        o = out_of_band_power(f, p, band_hz)
        if o is not None:
            oob.append(o)
    hum, lines = mains_hum(res, inputs, fs_hz) if inputs is not None else (0.0, [])
    with_hum = (f"; plus mains hum at {', '.join(f'{x:g}' for x in lines)} Hz"
                if lines else "")
    if oob and len(oob) == len(res):
        return Floor(math.sqrt(float(np.median(oob)) + hum), "out of band",
                     "the residual's spectrum outside the input band, across it as a power "
                     "law between its two sides (or the lower side's level where an "
                     "anti-alias filter rolls the upper side off)" + with_hum)
    if tops:
        return Floor(math.sqrt(float(np.median(tops))), "top band",
                     "0.45-0.5 fs, white-equivalent: assumes white noise and a steep "
                     "anti-alias filter (the input band leaves no room on either side)")
    return Floor(math.nan, "none", "records too short for a spectrum")
