"""The DAQ's anti-alias filter (Model.daq_filter): the same analog low-pass on every channel.

A linear model commutes with it: driven by the filtered input it predicts the filtered
outputs. A nonlinear element does not: its harmonics of the input band pass the filter on the
rig, but in a simulation driven by the filtered input they are made from a filtered motion and
never pass it. Measured on generated tests (the generator's 8th-order Butterworth at 0.4 fs, no
noise, band-limited x 4), the true model's residual driven by the filtered input against driven
by the input with the filter divided out and read through it: a contact closing under a
shake-table sweep 0.66 -> 0.15 m/s^2 (the sensors' noise at 1 %: 0.16), a bumper 0.023 ->
0.0086 (noise 0.03), a friction joint 0.081 -> 0.054 (noise 0.02: most of its harmonics lie
above the sample rate and alias, which no filtering at the samples can undo). A linear model is
left as it is (applied). The filter is applied by FFT over the whole record; an oversampled
simulation (r x fs) is read through it at its own rate and then sampled, as the DAQ does: a
harmonic above fs/2 aliases only as far as the filter lets it. The true model's residual on the
generator's tests without noise, band-limited x 4, sampled first and then filtered -> filtered
and then sampled: the sweep's contact channels 0.153 / 0.150 -> 0.011 / 0.010 m/s^2, the
friction joint's 0.054 / 0.054 -> 0.010 / 0.009.
"""
from __future__ import annotations

import functools
import importlib
import math
from typing import Any

import numpy as np

from dynval.errors import ConfigError
from dynval.model.schema import DaqFilter, Model

_signal: Any = importlib.import_module("scipy.signal")
_fft: Any = importlib.import_module("scipy.fft")

# the cutoffs taken, as multiples of the sample rate: beyond them the filter's polynomial
# overflows or its ring outgrows any record (a cutoff of 1e-6 Hz: 9e9 samples), and a filter
# outside them does nothing at the samples (above) or leaves nothing to divide out (below)
CUTOFF_RANGE = (0.01, 100.0)
# below this gain the measured input is the filter's stop band (its noise and aliasing): not
# divided out there (at most 20 dB of gain), the input's content there is dropped
INVERSE_FLOOR = 0.1


def cutoff_outside(f: DaqFilter, fs_hz: float) -> str:
    """Why f's cutoff is not taken at the sample rate fs_hz ('' when it is: CUTOFF_RANGE)."""
    lo, hi = CUTOFF_RANGE
    if lo * fs_hz <= f.cutoff_hz <= hi * fs_hz:
        return ""
    return f"{f.cutoff_hz:g} Hz is outside {lo:g}..{hi:g} x the sample rate ({fs_hz:g} Hz)"


def applied(m: Model) -> DaqFilter | None:
    """The DAQ filter m's simulations take part in: its declared one when it has a nonlinear
    element; none for a linear model, which commutes with it (divided out and put back, the
    input's content near fs/2 is interpolated less exactly: 2e-4 to 8e-4 of the signal on a
    cheap DAQ's input, and blind free case 0 took a spurious stiffness change on that)."""
    return m.daq_filter if m.elements else None


def _analog(f: DaqFilter) -> tuple[np.ndarray, np.ndarray]:
    """The filter's analog transfer function (b, a) in rad/s."""
    wc = 2.0 * math.pi * f.cutoff_hz
    ba = (_signal.bessel(f.order, wc, analog=True, norm="mag") if f.type == "bessel"
          else _signal.butter(f.order, wc, analog=True))
    return np.asarray(ba[0]), np.asarray(ba[1])


def response(f: DaqFilter, freqs_hz: np.ndarray) -> np.ndarray:
    """The filter's complex gain at freqs_hz."""
    b, a = _analog(f)
    return np.asarray(_signal.freqs(b, a, worN=2.0 * math.pi * np.asarray(freqs_hz))[1])


@functools.lru_cache(maxsize=64)
def _gain_at_bins(f: DaqFilter, fs_hz: float, nfft: int) -> np.ndarray:
    """response() at the bins of a real FFT of nfft samples at fs_hz (kept: discover measures
    every simulation of a test through the same bins)."""
    h = response(f, _fft.rfftfreq(nfft, 1.0 / fs_hz))
    h.setflags(write=False)
    return h


@functools.lru_cache(maxsize=64)
def ring_samples(f: DaqFilter, fs_hz: float) -> int:
    """Samples over which the filter's impulse response decays (12 time constants of its
    slowest pole, e^-12): the zeros after a record that keep the FFT's wrap off it."""
    _, a = _analog(f)
    slowest = float(np.min(-np.real(np.roots(a))))
    return int(math.ceil(12.0 * fs_hz / slowest)) + 8


def measured(f: DaqFilter, y: np.ndarray, fs_hz: float) -> np.ndarray:
    """y (samples along axis 0), a response from rest at its first sample, as the DAQ reads
    it: through the filter (causal: zeros before the record, and after it while it rings)."""
    n = y.shape[0]
    nfft = _fft.next_fast_len(n + ring_samples(f, fs_hz), real=True)
    h = _gain_at_bins(f, fs_hz, nfft)
    spec = _fft.rfft(y, nfft, axis=0) * (h if y.ndim == 1 else h[:, None])
    return np.asarray(_fft.irfft(spec, nfft, axis=0)[:n])


def unmeasured(f: DaqFilter, u: np.ndarray, fs_hz: float, r: int = 1) -> np.ndarray:
    """The input the DAQ read as u: u with the filter divided out where its gain is at least
    INVERSE_FLOOR (its content beyond dropped). The record is mirrored at both ends over the
    filter's ring (the input went on before and after it). r > 1: at r x fs_hz, interpolated
    exactly band-limited (its spectrum zero above fs_hz / 2: an interpolating filter's images
    just above fs / 2, where the division has raised the input up to 1 / INVERSE_FLOOR, would
    reach the outputs and be read through the filter at the simulation's rate, measured)."""
    u = np.asarray(u, dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(u))
    if bad.size:  # the FFT would spread it over the whole record
        raise ConfigError(f"the DAQ filter cannot be divided out of an input with non-finite "
                          f"samples ({bad.size}, the first at sample {int(bad[0])})")
    n = u.size
    pad = min(ring_samples(f, fs_hz), n - 1)
    x = np.pad(u, pad, mode="reflect") if pad > 0 else u
    nfft = _fft.next_fast_len(x.size + ring_samples(f, fs_hz), real=True)
    h = _gain_at_bins(f, fs_hz, nfft)
    keep = np.abs(h) >= INVERSE_FLOOR
    g = np.zeros_like(h)
    g[keep] = 1.0 / h[keep]
    spec = _fft.rfft(x, nfft) * g
    if r > 1 and nfft % 2 == 0:  # the Nyquist bin, a cosine at fs / 2: halved, it stays one
        spec[-1] *= 0.5
    return np.asarray(_fft.irfft(spec, nfft * r)[pad * r:(pad + n) * r] * r)
