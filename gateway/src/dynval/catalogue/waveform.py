"""Waveform features of report Section 5.2 beyond the C core's statistics: the normal
probability plot and the kernel density estimate with a two-sample distance (5.2.2), the 10 %
duration and the exponential decay fit of a transient (5.2.4), the autocorrelation function and
the correlation coefficient (5.2.6)."""
from __future__ import annotations

import importlib
import warnings
from typing import Any

import numpy as np

from dynval.errors import ConfigError

stats: Any = importlib.import_module("scipy.stats")
signal: Any = importlib.import_module("scipy.signal")
optimize: Any = importlib.import_module("scipy.optimize")


def npp(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(standard normal quantiles of j/(n+1), the sorted amplitudes): the report's normal
    probability plot; a straight line for Gaussian data, its slope the STD."""
    n = np.size(x)
    return np.asarray(stats.norm.ppf(np.arange(1, n + 1) / (n + 1))), np.sort(x)


def kde(x: np.ndarray, grid: np.ndarray, bw: float | str = "scott") -> np.ndarray:
    """Gaussian kernel density estimate (eq. 9-10) of the amplitudes on grid; bw: scipy's
    bandwidth factor (times the data's STD), the same for records that are compared."""
    return np.asarray(stats.gaussian_kde(x, bw_method=bw)(grid))


def pdf_distance(a: np.ndarray, b: np.ndarray, method: str = "ks") -> float:
    """A two-sample distance between the amplitude distributions of a and b (e.g. measured
    and predicted): 'ks', the Kolmogorov-Smirnov statistic (largest gap between the two
    empirical CDFs, 0..1); 'ad', the Anderson-Darling k-sample statistic (tail-weighted). The
    p-values scipy attaches assume independent samples, which a time history is not: only the
    statistic is used."""
    if method == "ks":
        return float(stats.ks_2samp(a, b, method="asymp").statistic)
    if method == "ad":
        with warnings.catch_warnings():  # the p-value's table capping: not used
            warnings.simplefilter("ignore")
            return float(stats.anderson_ksamp([a, b], variant="midrank").statistic)
    raise ConfigError(f"pdf_distance: unknown method '{method}' (ks, ad)")


def envelope(x: np.ndarray) -> np.ndarray:
    """The Hilbert envelope |x + j H[x]| (the report's decay envelope, Fig. 34)."""
    return np.asarray(np.abs(signal.hilbert(x)))


def duration10(x: np.ndarray, fs_hz: float) -> float:
    """10 % duration (s): from the peak |x| to the last time the Hilbert envelope is still at
    10 % of that peak (linear between samples); ln(10)/sigma for A exp(-sigma t) cos(w t)."""
    i0 = int(np.argmax(np.abs(x)))
    lim = 0.1 * abs(float(x[i0]))
    env = envelope(x)[i0:]
    above = np.flatnonzero(env >= lim)
    j = int(above[-1])
    if j + 1 >= env.size:
        return (env.size - 1) / fs_hz  # never decays to 10 % within the record
    frac = (env[j] - lim) / (env[j] - env[j + 1])
    return float((j + frac) / fs_hz)


def decay_fit(x: np.ndarray, fs_hz: float, floor: float = 0.05) -> tuple[float, float]:
    """(y0, a) of y0 exp(a t) (eq. 13) fitted by least squares to the Hilbert envelope from
    the peak |x| (t = 0) to the last time the envelope is above floor x the peak (below it
    sensor noise, not the decay, sets the envelope)."""
    i0 = int(np.argmax(np.abs(x)))
    env = envelope(x)[i0:]
    above = np.flatnonzero(env >= floor * env[0])
    env = env[:int(above[-1]) + 1]
    if env.size < 3:
        raise ConfigError("decay fit: fewer than 3 samples between the peak and the floor")
    t = np.arange(env.size) / fs_hz
    a0, l0 = np.polyfit(t, np.log(env), 1)  # the log-linear fit starts the nonlinear one
    try:
        p, _ = optimize.curve_fit(lambda tt, y0, a: y0 * np.exp(a * tt), t, env,
                                  p0=(float(np.exp(l0)), float(a0)))
    except RuntimeError as e:  # no convergence: not a decaying transient
        raise ConfigError(f"decay fit: {e}") from e
    return float(p[0]), float(p[1])


def acf(x: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Autocorrelation (eq. 18), lags 0..max_lag (default N/4, the report's rule), biased
    estimate (sum over N - tau products / N) normalised to 1 at lag 0."""
    n = np.size(x)
    lag = n // 4 if max_lag is None else min(max_lag, n - 1)
    d = np.asarray(x, dtype=np.float64) - np.mean(x)
    r = signal.correlate(d, d, mode="full", method="fft")[n - 1:n + lag]
    return np.asarray(r / r[0])


def corrcoef(x: np.ndarray, y: np.ndarray) -> float:
    """Correlation coefficient (eq. 21) of two equally long series, e.g. a measured and a
    predicted time history, or their autocorrelation functions."""
    return float(np.corrcoef(x, y)[0, 1])


def acf_corr(x: np.ndarray, ref: np.ndarray, max_lag: int | None = None) -> float:
    """The correlation coefficient between the autocorrelation functions of x and ref (the
    report's 'metric to quantify the difference in these correlation measures')."""
    a, b = acf(x, max_lag), acf(ref, max_lag)
    k = min(a.size, b.size)
    return corrcoef(a[:k], b[:k])
