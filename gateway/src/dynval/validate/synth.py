"""Synthetic "experiments" for studies and tests: a truth model driven by band-limited random
forces through model.simulate, with test-to-test variation of chosen parameters and of the
force level, and white sensor noise on every channel (force included)."""
from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from dynval import model as mdl
from dynval.io.recording import Channel, Recording


def bandlimited_force(n: int, fs_hz: float, rms: float, band_hz: tuple[float, float],
                      rng: np.random.Generator) -> np.ndarray:
    """White Gaussian noise through a 4th-order Butterworth band-pass (zero phase), scaled to
    the RMS, ramped in over the first 64 samples."""
    sig = importlib.import_module("scipy.signal")
    sos = sig.butter(4, [band_hz[0], band_hz[1]], btype="bandpass", fs=fs_hz, output="sos")
    x = sig.sosfiltfilt(sos, rng.standard_normal(n + 512))[256:256 + n]
    x *= rms / np.sqrt(np.mean(x * x))
    ramp = np.minimum(1.0, np.arange(n) / 64.0)
    return np.asarray(x * ramp)


def make_experiments(truth: mdl.Model, n_tests: int = 20, *, fs_hz: float = 640.0,
                     n_samples: int = 8192, force_rms: float = 12.0,
                     band_hz: tuple[float, float] = (20.0, 200.0), noise: float = 0.01,
                     variation: Mapping[str, float] | None = None, level_var: float = 0.02,
                     force_channel: str = "force_N", seed: int = 0,
                     oversample: int | None = None) -> list[Recording]:
    """n_tests recordings of the truth model. variation: parameter -> relative STD of its
    test-to-test scatter (e.g. {"zeta2": 0.03}); level_var: relative STD of the force RMS;
    noise: sensor noise STD relative to each channel's RMS."""
    rng = np.random.default_rng(seed)
    base = truth.parameters()
    recs = []
    for k in range(n_tests):
        params = {n: base[n] * (1.0 + s * rng.standard_normal())
                  for n, s in (variation or {}).items()}
        m = truth.with_params(params) if params else truth
        f = bandlimited_force(n_samples, fs_hz, force_rms * (1 + level_var * rng.standard_normal()),
                              band_hz, rng)
        y = mdl.simulate(m, f, fs_hz, oversample=oversample)
        chans = [Channel(force_channel, f + noise * np.sqrt(np.mean(f * f))
                         * rng.standard_normal(n_samples), "N", "input")]
        for name, v in y.items():
            rms = float(np.sqrt(np.mean(v * v)))
            chans.append(Channel(name, v + noise * rms * rng.standard_normal(n_samples),
                                 "m/s^2" if name.startswith("acc") else "", "output"))
        recs.append(Recording(f"exp{k + 1:02d}", fs_hz, chans))
    return recs


def write_csv(rec: Recording, path: Path | str) -> None:
    """Write a recording in the shared data's CSV layout (time_s first)."""
    t = np.arange(rec.n_samples) / rec.fs_hz
    cols = ["time_s", *rec.names]
    data = np.column_stack([t, *(c.data for c in rec.channels)])
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")
