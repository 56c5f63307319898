"""Issue 19's test types from the generator (dynval.synth): a harmonic test is a steady sine
of the stated RMS and frequency, a hammer test a pulse of the stated peak (its impulse kept by
the DAQ filter), and the contact onsets are where the bumper's gap closes."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from dynval import model as mdl
from dynval import synth
from dynval.catalogue import spectral
from dynval.validate import montecarlo as mc


@pytest.fixture
def declared(shared_data: Path) -> mdl.Model:
    return mdl.load(shared_data / "synthetic" / "lanl4dof-clean" / "declared_model.json")


def test_sine_test_is_steady_at_its_level_and_frequency(declared: mdl.Model) -> None:
    r = synth.generate(declared, synth.Truth(), n_tests=1, levels_n_rms=(5.0,), fs_hz=2560.0,
                       n_samples=8192, excitation=synth.Sine(71.0))[0]
    f = r.channel("force_N").data
    assert np.sqrt(np.mean(f * f)) == pytest.approx(5.0, rel=0.02)  # 1 % noise, DAQ filter
    assert spectral.harmonic_peaks(f, 2560.0).f0_hz == pytest.approx(71.0, abs=0.02)
    a = r.channel("acc4_mps2").data
    thirds = [np.std(a[i * 2730:(i + 1) * 2730]) for i in range(3)]
    assert max(thirds) / min(thirds) < 1.01  # the free transient died out in the lead


@pytest.mark.parametrize(("method", "mid_hz"), [("logarithmic", 50.0), ("linear", 252.5)])
def test_sweep_test_runs_from_f0_to_f1_at_its_level(declared: mdl.Model, method: str,
                                                     mid_hz: float) -> None:
    """A 5 -> 500 Hz swept sine over 4 s: RMS the level, starting and ending at rest (cosine
    ramps), its frequency half-way sqrt(5 x 500) = 50 Hz (logarithmic) or (5 + 500) / 2 Hz
    (linear), read from the zero crossings of 0.2 s around the middle."""
    fs = 2560.0
    r = synth.generate(declared, synth.Truth(), n_tests=1, levels_n_rms=(5.0,), fs_hz=fs,
                       n_samples=10240, noise=0.0, excitation=synth.Sweep(5.0, 500.0, method))[0]
    f = r.channel("force_N").data
    assert np.sqrt(np.mean(f * f)) == pytest.approx(5.0, rel=0.02)
    assert abs(f[0]) < 0.01 and abs(f[-1]) < 0.2  # at rest (the DAQ filter's lag at the end)
    mid = f[5120 - 256:5120 + 256]
    crossings = np.count_nonzero(np.diff(np.signbit(mid)))
    assert crossings / 2 / (512 / fs) == pytest.approx(mid_hz, rel=0.05)


def test_hammer_test_impulse_and_response_start(declared: mdl.Model) -> None:
    """A 300 N, 4 ms half-sine at 0.1 s: impulse 300 x 0.008 / pi = 0.764 N s; nothing moves
    before the hit (1 % noise of a record that is mostly decay)."""
    m = dataclasses.replace(declared, input=mdl.Input("force", 2, "force_N"))
    r = synth.generate(m, synth.Truth(), n_tests=1, levels_n_rms=(300.0,), fs_hz=320.0,
                       n_samples=1024, excitation=synth.Hammer())[0]
    f = r.channel("force_N").data
    assert np.sum(f) / 320.0 == pytest.approx(300 * 0.008 / np.pi, rel=0.02)
    a = r.channel("acc2_mps2").data
    assert np.max(np.abs(a[:30])) < 0.05 * np.max(np.abs(a))
    assert 32 <= int(np.argmax(np.abs(a))) <= 40


def test_contact_onsets_are_where_the_gap_closes(declared: mdl.Model) -> None:
    on: list[np.ndarray] = []
    synth.generate(declared, synth.Truth(elements=(mc.BUMPER,)), n_tests=2,
                   levels_n_rms=(12.0, 7.2), n_samples=4096, onsets=on, seed=5)
    synth.generate(declared, synth.Truth(), n_tests=1, n_samples=4096, onsets=on, seed=5)
    assert len(on) == 3 and on[2].size == 0
    assert on[0].size > on[1].size and np.all((on[0] >= 0) & (on[0] < 4096 / 640.0))
    # the onsets from the truth's displacements: X = x4 - x3 crosses the gap upwards
    rng = np.random.default_rng(0)
    force = synth.band_limited_force(rng, 40960, 10240.0, 12.0)
    t = synth.contact_onsets(declared, synth.Truth(elements=(mc.BUMPER,)), force, 10240.0)
    y = mdl.simulate(synth.truth_model(declared, synth.Truth(elements=(mc.BUMPER,)),
                                       [("disp", 3), ("disp", 4)]), force, 10240.0,
                     oversample=1)
    x = y["__disp4"] - y["__disp3"]
    i = np.round(t * 10240.0).astype(int)
    assert t.size > 0 and np.all(x[i] > mc.BUMPER.gap_m) and np.all(x[i - 1] <= mc.BUMPER.gap_m)
