"""Frequency-domain features of report Section 5.3 for single channels: the PSD with the
harmonic peaks of a harmonic test (5.3.2), response spectra of 2 %-damped SDOF oscillators with
a band metric (5.3.3), the cepstrum and its liftered log-spectrum envelope with a metric
(5.3.4). Each metric compares two records processed with the same settings (the report: keep
the signal-processing parameters constant between measured and predicted)."""
from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError

signal: Any = importlib.import_module("scipy.signal")

HARMONIC_DB = 20.0  # a harmonic counts when its PSD stands this far above the local floor
SRS_ZETA = 0.02  # the report's SDOF damping ratio
LIFTER_S = 600 / 2560  # the report's lifter: quefrencies 0..600 samples at 2560 Hz
PEAK_DB = 10.0  # the cepstral metric reads the envelope where it stands this far above median


def psd(x: np.ndarray, fs_hz: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(f, one-sided PSD) by Welch with a Hann window, no overlap; nperseg: the whole record
    by default (the report's harmonic PSDs)."""
    n = np.size(x) if nperseg is None else nperseg
    f, p = signal.welch(x, fs_hz, window="hann", nperseg=n, noverlap=0)
    return np.asarray(f), np.asarray(p)


@dataclass(frozen=True)
class Harmonics:
    """The harmonic peaks of a harmonic test's PSD: the fundamental f0 and its power, the
    orders k >= 2 that stand HARMONIC_DB above the local floor (count, frequencies, powers),
    and the total harmonic distortion over every order below the Nyquist frequency (dB re
    the fundamental, the floor included where no harmonic stands out)."""

    f0_hz: float
    p0: float
    freqs_hz: np.ndarray
    powers: np.ndarray
    thd_db: float

    @property
    def count(self) -> int:
        return int(self.freqs_hz.size)


def _band_power(p: np.ndarray, i: int, half: int) -> float:
    return float(np.sum(p[max(i - half, 0):i + half + 1]))


def harmonic_peaks(x: np.ndarray, fs_hz: float, f0_hz: float | None = None,
                   min_db: float = HARMONIC_DB) -> Harmonics:
    """Harmonic peaks of x's whole-record Hann PSD. f0_hz: the excitation frequency (default:
    the strongest peak, refined by a parabola through the log PSD). A harmonic's power is the
    sum of the PSD over its Hann main lobe (+-2 bins); the floor is the median PSD over
    +-f0/4 around it."""
    f, p = psd(x, fs_hz)
    df = f[1] - f[0]
    i = int(np.argmax(p[1:])) + 1 if f0_hz is None else int(round(f0_hz / df))
    if f0_hz is None and 0 < i < p.size - 1:
        la, lb, lc = np.log(p[i - 1:i + 2])
        den = la - 2 * lb + lc
        f0_hz = (i + (0.5 * (la - lc) / den if den != 0 else 0.0)) * df
    f0 = float(f0_hz if f0_hz is not None else i * df)
    if not 0 < f0 < fs_hz / 2:
        raise ConfigError(f"harmonic peaks: fundamental {f0:g} Hz outside (0, {fs_hz / 2:g})")
    p0 = _band_power(p, int(round(f0 / df)), 2)
    half_floor = max(int(f0 / 4 / df), 8)
    freqs, powers, dist = [], [], 0.0
    for k in range(2, int((fs_hz / 2) / f0)):
        c = int(round(k * f0 / df))
        if c + 2 >= p.size:
            break
        j = c - 2 + int(np.argmax(p[c - 2:c + 3]))
        pk = _band_power(p, j, 2)
        dist += pk
        floor = float(np.median(p[max(c - half_floor, 0):c + half_floor + 1]))
        if p[j] > floor * 10 ** (min_db / 10):
            freqs.append(j * df)
            powers.append(pk)
    return Harmonics(f0, p0, np.array(freqs), np.array(powers),
                     float(10 * np.log10(max(dist, 1e-300) / p0)))


def srs_frequencies(fs_hz: float, f_lo: float = 10.0, per_octave: int = 6) -> np.ndarray:
    """Natural frequencies of the oscillators: per_octave per octave from f_lo to 0.4 fs
    (the anti-alias band)."""
    n = int(np.floor(per_octave * np.log2(0.4 * fs_hz / f_lo))) + 1
    return f_lo * 2.0 ** (np.arange(n) / per_octave)


@functools.lru_cache(maxsize=4096)
def _sdof_filter(fn_hz: float, zeta: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the oscillator's first-order-hold discretisation (cached: scipy's matrix
    exponential takes ~20 ms, the filtering of 8192 samples 0.1 ms)."""
    wn = 2 * np.pi * fn_hz
    b, a, _ = signal.cont2discrete(([2 * zeta * wn, wn * wn], [1.0, 2 * zeta * wn, wn * wn]),
                                   dt_s, method="foh")
    return np.ravel(b), np.asarray(a)


def response_spectrum(x: np.ndarray, fs_hz: float, fn_hz: np.ndarray | None = None,
                      zeta: float = SRS_ZETA) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(fn, peak, RMS) of the absolute acceleration of SDOF oscillators of natural frequency
    fn and damping zeta whose base moves with the acceleration x (report 5.3.3). Each
    oscillator, H(s) = (2 zeta wn s + wn^2) / (s^2 + 2 zeta wn s + wn^2), is discretised with a
    first-order hold (the ramp-invariant filter of Smallwood's shock-response algorithm)."""
    fn = srs_frequencies(fs_hz) if fn_hz is None else np.asarray(fn_hz, dtype=np.float64)
    peak, rms = np.empty(fn.size), np.empty(fn.size)
    for i, f in enumerate(fn):
        y = signal.lfilter(*_sdof_filter(float(f), zeta, 1.0 / fs_hz), x)
        peak[i] = np.max(np.abs(y))
        rms[i] = np.sqrt(np.mean(y * y))
    return fn, peak, rms


def db_distance(s: np.ndarray, s_ref: np.ndarray) -> float:
    """The band metric of two spectra on the same frequencies: the RMS over the band of their
    level difference in dB (0 for equal spectra, 0.83 dB for a uniform 10 % scale)."""
    d = 20 * np.log10(np.asarray(s) / np.asarray(s_ref))
    return float(np.sqrt(np.mean(d * d)))


def cepstrum(x: np.ndarray, window: str | None = "hann") -> np.ndarray:
    """Real cepstrum: the inverse FFT of the natural log of the amplitude spectrum (eq. 24's
    amplitude); quefrency q in samples. Hann window by default (a harmonic test's leakage
    would otherwise fill the log spectrum); None for the bare definition. An echo
    x(t) + a x(t - q0) puts a/2 at q0 and -a^2/4 at 2 q0."""
    w = signal.get_window(window, np.size(x)) if window else 1.0
    spec = np.abs(np.fft.fft(np.asarray(x) * w))
    return np.asarray(np.real(np.fft.ifft(np.log(np.maximum(spec, 1e-300)))))


def liftered_envelope(x: np.ndarray, fs_hz: float, lifter_s: float = LIFTER_S,
                      window: str | None = "hann") -> tuple[np.ndarray, np.ndarray]:
    """(f, dB): the log amplitude spectrum smoothed by keeping only quefrencies below
    lifter_s (the report's 'liftering', Fig. 52), one-sided."""
    c = cepstrum(x, window)
    n = c.size
    q = int(round(lifter_s * fs_hz))
    keep = np.zeros(n)
    keep[:q + 1] = 1.0
    keep[n - q:] = 1.0
    env = np.real(np.fft.fft(c * keep))[:n // 2 + 1]
    return np.arange(n // 2 + 1) * fs_hz / n, env * 20 / np.log(10)


def cepstral_distance(x: np.ndarray, ref: np.ndarray, fs_hz: float,
                      lifter_s: float = LIFTER_S, peak_db: float = PEAK_DB) -> float:
    """The metric on the liftered envelopes: the mean level (dB) of x's envelope above ref's
    where ref's envelope stands peak_db above its median below 0.4 fs (the report's 'spiky
    profile at the peak frequencies': the excitation and its harmonics), the whole band if
    nothing does. Elsewhere the envelopes are the log spectrum's noise floor, whose scatter
    (3.9 dB RMS between two clean 8192-sample harmonic records) would swamp the peaks. The
    records must be equally long."""
    if np.size(x) != np.size(ref):
        raise ConfigError(f"cepstral distance: records of {np.size(x)} and {np.size(ref)} "
                          "samples")
    f, e = liftered_envelope(x, fs_hz, lifter_s)
    _, e_ref = liftered_envelope(ref, fs_hz, lifter_s)
    band = f <= 0.4 * fs_hz
    peaks = band & (e_ref > np.median(e_ref[band]) + peak_db)
    return float(np.mean((e - e_ref)[peaks if peaks.any() else band]))
