"""Issue 19, report 5.3.2-5.3.4: harmonic peaks of a PSD, response spectra, cepstrum and
liftering. Closed forms (a sine with known harmonics, an SDOF's steady state, an echo) and the
physics the report shows: harmonic distortion and cepstral differences appear with the bumper
on the generator's 54 Hz harmonic tests, not without it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.signal as sg

from dynval import model as mdl
from dynval import synth
from dynval.catalogue import spectral as sp
from dynval.validate import montecarlo as mc
from dynval.validate.featvec import parse

FS = 2560.0


def test_psd_is_scipys_whole_record_hann_welch() -> None:
    x = np.random.default_rng(0).standard_normal(4096)
    f, p = sp.psd(x, 640.0)
    f2, p2 = sg.welch(x, 640.0, window="hann", nperseg=4096)
    assert np.allclose(f, f2) and np.allclose(p, p2) and f.size == 2049


def test_harmonic_peaks_count_frequencies_and_distortion_of_a_known_signal() -> None:
    """A 54.3 Hz sine with 2nd and 5th harmonics at -30 and -40 dB in 1 % noise: two
    harmonics found at 108.6 and 271.5 Hz; THD = 10 log10(1e-3 + 1e-4) = -29.6 dB."""
    t = np.arange(16384) / FS
    w = 2 * np.pi * 54.3
    x = (np.sin(w * t) + 10 ** -1.5 * np.sin(2 * w * t + 1) + 1e-2 * np.sin(5 * w * t)
         + 0.01 * np.random.default_rng(1).standard_normal(t.size))
    h = sp.harmonic_peaks(x, FS)
    assert h.f0_hz == pytest.approx(54.3, abs=0.01)
    assert h.count == 2
    assert np.allclose(h.freqs_hz, [108.6, 271.5], atol=0.2)
    assert 10 * np.log10(h.powers / h.p0) == pytest.approx([-30, -40], abs=0.3)
    assert h.thd_db == pytest.approx(10 * np.log10(1.1e-3), abs=0.3)
    assert sp.harmonic_peaks(np.sin(w * t), FS).count == 0


def test_response_spectrum_is_the_sdof_steady_state() -> None:
    """A base acceleration A sin(w t): oscillator fn's absolute acceleration has amplitude
    A |1 + 2 j zeta r| / |1 - r^2 + 2 j zeta r|, r = f / fn; RMS that / sqrt 2 (60 s record,
    ramped on so the free transient is small). The first-order hold (Smallwood's ramp
    invariance) sees the sine's samples joined by lines, whose fundamental is sinc^2(f / fs)
    x A (1.3 % low at 16 samples a cycle)."""
    fs, f = 640.0, 40.0
    t = np.arange(int(60 * fs)) / fs
    x = 3.0 * np.sin(2 * np.pi * f * t) * np.minimum(t / 5.0, 1.0)
    fn = np.array([15.0, 38.0, 40.0, 80.0, 200.0])
    _, peak, rms = sp.response_spectrum(x, fs, fn)
    r, z = f / fn, sp.SRS_ZETA
    amp = 3.0 * np.sinc(f / fs) ** 2 * np.abs(1 + 2j * z * r) / np.abs(1 - r ** 2 + 2j * z * r)
    assert peak == pytest.approx(amp, rel=0.01)
    ramp_ms = (55 + 5 / 3) / 60  # mean square of the ramp-on envelope over the record
    assert rms == pytest.approx(amp / np.sqrt(2) * np.sqrt(ramp_ms), rel=0.01)
    assert sp.srs_frequencies(640.0)[[0, -1]] == pytest.approx([10.0, 10 * 2 ** (28 / 6)])
    assert sp.db_distance(1.1 * peak, peak) == pytest.approx(20 * np.log10(1.1))


def test_cepstrum_of_an_echo_and_the_liftered_envelope() -> None:
    """x(t) + a x(t - q0) with x a unit impulse: the real cepstrum is a/2 at q0, -a^2/4 at
    2 q0 (log(1 + a e^-jwq)); the liftered log spectrum of a scaled record moves by the
    scale in dB."""
    n, q0, a = 4096, 300, 0.5
    x = np.zeros(n)
    x[0], x[q0] = 1.0, a
    c = sp.cepstrum(x, window=None)
    assert c[q0] == pytest.approx(a / 2) and c[2 * q0] == pytest.approx(-a * a / 4)
    assert c[q0 // 2] == pytest.approx(0.0, abs=1e-12)
    y = np.random.default_rng(2).standard_normal(n)
    assert sp.cepstral_distance(2 * y, y, FS) == pytest.approx(20 * np.log10(2))
    f, env = sp.liftered_envelope(y, FS)
    assert f.size == n // 2 + 1 and abs(np.median(env) - np.median(
        20 * np.log10(np.abs(np.fft.rfft(y * sg.get_window("hann", n)))))) < 3.0


def _sine_tests(m: mdl.Model, truth: synth.Truth, f_hz: float, seed: int
                ) -> list[np.ndarray]:
    recs = synth.generate(m, truth, n_tests=2, levels_n_rms=(7.0,), fs_hz=FS, n_samples=8192,
                          excitation=synth.Sine(f_hz), seed=seed)
    return [r.channel("acc4_mps2").data for r in recs]


def test_bumper_makes_harmonics_and_a_cepstral_difference(shared_data: Path) -> None:
    """54 Hz at 7 N RMS (the bumper closes every cycle): harmonic peaks appear with the
    bumper (measured 7 and 7 on acc4, THD -29 dB) and not without it (0, THD -55 dB); the
    71 Hz linear test has none either.
    At the clean reference's envelope peaks, a bumper record's liftered envelope lies lower
    (the bumper detunes mode 3 away from 54 Hz; measured -1.74 dB) by more than two clean
    records' differ (-0.19 dB)."""
    m = mdl.load(shared_data / "synthetic" / "lanl4dof-clean" / "declared_model.json")
    bump = synth.Truth(elements=(mc.BUMPER,))
    xb = _sine_tests(m, bump, 54.0, 1)
    xc = _sine_tests(m, synth.Truth(), 54.0, 1)
    hb = [sp.harmonic_peaks(x, FS) for x in xb]
    hc = [sp.harmonic_peaks(x, FS) for x in xc]
    assert all(h.count >= 5 for h in hb) and all(h.count == 0 for h in hc)
    assert min(h.thd_db for h in hb) > max(h.thd_db for h in hc) + 10
    assert all(sp.harmonic_peaks(x, FS).count == 0
               for x in _sine_tests(m, synth.Truth(), 71.0, 2))
    d_bc = sp.cepstral_distance(xb[1], xc[0], FS)
    d_cc = sp.cepstral_distance(xc[1], xc[0], FS)
    assert d_bc < -1.0 and abs(d_cc) < 0.4 and d_bc < d_cc - 1.0
    fset = parse("harm_n,thd,cep_env@acc4").resolve(list(m.outputs))
    fset = fset.fit_reference({"acc4_mps2": xc[0]})
    v = fset.extract({"acc4_mps2": xb[1]}, FS)
    assert v[0] == hb[1].count and v[1] == pytest.approx(hb[1].thd_db)
    assert v[2] == pytest.approx(d_bc)
