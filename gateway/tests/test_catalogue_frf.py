"""dynval.catalogue.frf (report 5.3.1): H1, H2 and coherence equal scipy's spectra, the FRF
of a known filter, and the linearity (two levels) and reciprocity (input and response swapped)
checks on independent simulations of the report's 4-DOF structure: they hold without the
bumper and fail with it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from lanl4dof import declared
from scipy import signal

from dynval import model as mdl
from dynval import synth as gen
from dynval.catalogue import frf as F
from dynval.errors import ConfigError
from dynval.io import read_test
from dynval.io.recording import Recording

BUMPER = gen.Truth(elements=(mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),), label="bumper")
BAND = (20.0, 200.0)
ACC = tuple(f"acc{i}_mps2" for i in range(1, 5))


def _io(r: Recording) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    return r.channel("force_N").data, {c: r.channel(c).data for c in ACC}


def _pair(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(8192)
    b, a = signal.butter(4, [0.1, 0.3], btype="bandpass")
    return u, signal.lfilter(b, a, u) + 0.05 * rng.standard_normal(u.size)


def test_h1_h2_coherence_are_scipys() -> None:
    u, y = _pair()
    fr = F.estimate(u, {"y": y}, 100.0)
    kw = {"fs": 100.0, "window": "hann", "nperseg": 1024, "noverlap": 512}
    f, suu = signal.welch(u, **kw)
    _, suy = signal.csd(u, y, **kw)
    _, syu = signal.csd(y, u, **kw)
    _, syy = signal.welch(y, **kw)
    _, coh = signal.coherence(u, y, **kw)
    np.testing.assert_allclose(fr.f_hz, f)
    np.testing.assert_allclose(fr.h1[:, 0], suy / suu, rtol=1e-12)
    np.testing.assert_allclose(fr.h2[:, 0], syy / syu, rtol=1e-12)
    np.testing.assert_allclose(fr.coh[:, 0], coh, rtol=1e-12)
    assert fr.n_avg == 15  # (8192 - 1024) / 512 + 1


def test_h1_of_a_pure_delay() -> None:
    """y = g u(t - d): a windowed segment of y holds only part of the input that caused it,
    so E[H1] = g rho_w(d) e^(-j w d) and E[coherence] ~ rho_w(d)^2, rho_w the window's
    normalised autocorrelation at lag d (Bendat & Piersol's time-delay bias)."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(16384)
    d, g = 40, 2.0
    y = g * np.concatenate([np.zeros(d), u[:-d]])
    fr = F.estimate(u, {"y": y}, 2.0)
    w = signal.get_window("hann", 1024)
    rho = np.sum(w[:-d] * w[d:]) / np.sum(w * w)
    sel = fr.f_hz > 0.01  # the DC line is the detrend's
    ratio = fr.h1[sel, 0] / (g * np.exp(-1j * np.pi * fr.f_hz[sel] * d))
    assert abs(np.mean(np.abs(ratio)) / rho - 1) < 0.002
    assert abs(np.mean(np.angle(ratio))) < 0.005
    assert abs(np.mean(fr.coh[sel, 0]) - rho ** 2) < 0.003


def test_records_average_their_spectra() -> None:
    (u1, y1), (u2, y2) = _pair(2), _pair(3)
    both = F.estimate_records([(u1, {"y": y1}), (u2, {"y": y2})], 100.0)
    kw = {"fs": 100.0, "nperseg": 1024}
    suy = signal.csd(u1, y1, **kw)[1] + signal.csd(u2, y2, **kw)[1]
    suu = signal.welch(u1, **kw)[1] + signal.welch(u2, **kw)[1]
    np.testing.assert_allclose(both.h1[:, 0], suy / suu, rtol=1e-12)
    assert both.n_avg == 30


def test_bad_input_names_the_problem() -> None:
    u, y = _pair()
    with pytest.raises(ConfigError, match="nperseg = 1024"):
        F.estimate(u[:500], {"y": y[:500]}, 100.0)
    with pytest.raises(ConfigError, match="output 'y' has 8191 samples"):
        F.estimate(u, {"y": y[:-1]}, 100.0)
    fr = F.estimate(u, {"y": y}, 100.0)
    with pytest.raises(ConfigError, match="holds no FRF line"):
        F.compare(fr, fr, 0, 0, (60.0, 70.0))
    silent = F.estimate(np.zeros_like(u), {"y": y}, 100.0)
    with pytest.raises(ConfigError, match="not finite in 5-15 Hz"):
        F.compare(fr, silent, 0, 0, (5.0, 15.0))
    other = F.estimate(u, {"y": y}, 100.0, nperseg=512)
    with pytest.raises(ConfigError, match="different frequency lines"):
        F.compare(fr, other, 0, 0, (5.0, 15.0))


def _linearity(truth: gen.Truth, seed: int, k: int) -> F.Comparison:
    """High (12 N) against low (7.2 N) level, k records each, the top floor (acc4)."""
    recs = gen.generate(declared(), truth, n_tests=2 * k, seed=seed)
    hi = F.estimate_records([_io(r) for r in recs[0::2]], 640.0)
    lo = F.estimate_records([_io(r) for r in recs[1::2]], 640.0)
    return F.compare(hi, lo, 3, 3, BAND)


def test_linearity_holds_without_the_bumper_and_fails_with_it() -> None:
    """Five records a level (the report: ten). Clean: both statistics near 1 (20 seeds of
    bench/catalogue_modal_frf.py: max z2_coh 1.4); bumper: the coherence falls at the high
    level (z2_coh 20-40), while H1's own change stays within its random error."""
    clean = _linearity(gen.Truth(), 7, 5)
    assert clean.passed and 0.6 < clean.z2 < 1.5 and 0.6 < clean.z2_coh < 1.6
    bump = _linearity(BUMPER, 7, 5)
    assert not bump.passed and bump.z2_coh > 10.0
    assert bump.dcoh > 3 * clean.dcoh and bump.coh_min < clean.coh_min - 0.1


def test_reciprocity_holds_without_the_bumper_and_fails_with_it() -> None:
    """H_14 (force at the base, response at the top floor) against H_41 (force at the top
    floor, response at the base), three records a side at 12 N (20 seeds: clean z2_coh <= 1.25,
    bumper median 11.7, every seed fails; one record a side: 18 of 20 fail)."""
    out = {}
    for truth in (gen.Truth(), BUMPER):
        a, b = gen.reciprocal(declared(), truth, 4, n_tests=3, levels_n_rms=(12.0,), seed=11)
        assert b[0].name == f"{truth.label}_at4_high_01"
        out[truth.label] = F.compare(F.estimate_records([_io(r) for r in a], 640.0),
                                     F.estimate_records([_io(r) for r in b], 640.0), 3, 0, BAND)
    assert out["clean"].passed and out["clean"].z2_coh < 1.6 and out["clean"].z2 < 1.6
    assert not out["bumper"].passed and out["bumper"].z2_coh > 2 * F.Z2_LIMIT


def test_reciprocal_refuses_a_ground_input() -> None:
    m = declared()
    shaken = mdl.Model(masses_kg=m.masses_kg, stiffness_n_per_m=m.stiffness_n_per_m,
                       damping=m.damping, input=mdl.Input("ground_acc", 1, "a0"),
                       outputs=dict(m.outputs), fs_hz=640.0)
    with pytest.raises(ConfigError, match="swaps a force"):
        gen.reciprocal(shaken, gen.Truth(), 4, n_tests=1)


def test_checks_on_the_shared_data_of_another_simulator(shared_data: Path) -> None:
    """The shared synthetic data (an RK4 simulator that is not dynval's): five high- and five
    low-level tests. Clean: linearity holds (z2, z2_coh 1.06, 1.04); bumper: it fails (z2_coh
    25), and on one pair of records too (4.3)."""
    def frf(case: str, level: str, n: int) -> F.Frf:
        recs = [read_test(shared_data / "synthetic" / case / f"test_{level}_{i:02d}.csv")
                for i in range(1, n + 1)]
        return F.estimate_records([_io(r) for r in recs], 640.0)

    clean = F.compare(frf("lanl4dof-clean", "high", 5), frf("lanl4dof-clean", "low", 5), 3, 3,
                      BAND)
    assert clean.passed and clean.z2_coh < 1.5 and clean.z2 < 1.5
    bump = F.compare(frf("lanl4dof-bumper", "high", 5), frf("lanl4dof-bumper", "low", 5), 3, 3,
                     BAND)
    assert not bump.passed and bump.z2_coh > 10.0
    one = F.compare(frf("lanl4dof-bumper", "high", 1), frf("lanl4dof-bumper", "low", 1), 3, 3,
                    BAND)
    assert not one.passed
