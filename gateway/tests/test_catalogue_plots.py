"""Issue 19: one figure per catalogue feature (report Figures 27-29, 32-35, 40, 48-53 in
kind), drawn without overlapping tick labels."""
from __future__ import annotations

import numpy as np
import pytest

from dynval import plotting as plot
from dynval.catalogue import signal_plots as plots

pytest.importorskip("matplotlib")
pytest.importorskip("pywt")


def test_each_catalogue_figure_draws_without_overlapping_ticks() -> None:
    rng = np.random.default_rng(1)
    fs = 640.0
    t = np.arange(1024) / fs
    meas = np.sin(2 * np.pi * 54 * t) + 0.1 * np.sin(2 * np.pi * 108 * t) \
        + 0.01 * rng.standard_normal(t.size)
    series = {"measured": meas, "model": np.sin(2 * np.pi * 54 * t)
              + 0.01 * rng.standard_normal(t.size)}
    decay = np.exp(-3 * t) * np.sin(2 * np.pi * 30 * t)
    figs = [plots.plot_distribution(series), plots.plot_decay(decay, fs),
            plots.plot_acf(series, fs), plots.plot_harmonics(series, fs),
            plots.plot_srs(series, fs), plots.plot_cepstrum(series, fs),
            plots.plot_holder(meas, fs, [0.5, 1.0])]
    for fig in figs:
        assert plot.overlapping_ticks(fig) == []
        plot.pyplot().close(fig)
