"""A declared DAQ anti-alias filter (model.daq, ``simulation.daq_filter``): the model is driven by
the measured input with the filter divided out and measured through it. Checked against the
filter's closed-form response, a linear model (which commutes with the filter: the same
prediction), and the generator's tests of a nonlinear rig (its 8th-order Butterworth at 0.4 fs):
the true model's residual falls where the element's harmonics pass the filter."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from dynval import model as mdl
from dynval import synth
from dynval.discover import residual as rs
from dynval.errors import ConfigError
from dynval.model import daq

FS = 640.0
AA = mdl.DaqFilter("butterworth", 8, 0.4 * FS)  # synth.daq_filter("butter8")'s analog twin


def chain(kind: str = "force") -> mdl.Model:
    return mdl.Model(masses_kg=(6.5, 6.6, 6.7, 6.8), stiffness_n_per_m=(4e5,) * 4,
                     damping=mdl.Damping("modal", (0.01, 0.02, 0.01, 0.015)),
                     input=mdl.Input(kind, 1 if kind == "force" else 0,
                                     "force_N" if kind == "force" else "table_mps2"),
                     outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)},
                     fs_hz=FS)


def test_the_declared_filter_is_read_written_and_refused_when_wrong() -> None:
    d = mdl.formats.to_dict(chain())
    d["simulation"]["daq_filter"] = {"type": "bessel", "order": 4, "cutoff_hz": 200.0}
    m = mdl.from_dict(d, "rig.json")
    assert m.daq_filter == mdl.DaqFilter("bessel", 4, 200.0)
    assert mdl.from_dict(mdl.formats.to_dict(m)) == m
    assert "daq_filter" not in mdl.formats.to_dict(chain())["simulation"]
    for bad, where in (({"type": "chebyshev", "order": 4, "cutoff_hz": 200.0}, "type"),
                       ({"type": "bessel", "order": 0, "cutoff_hz": 200.0}, "order"),
                       ({"type": "bessel", "order": 4, "cutoff_hz": -1.0}, "cutoff_hz"),
                       ({"type": "bessel", "order": 4, "cutoff_hz": "high"}, "cutoff_hz"),
                       ({"type": "bessel", "order": 4}, "cutoff_hz"),
                       ({"type": "bessel", "order": 4, "cutoff_hz": 1.0, "q": 2}, "q"),
                       ("butter8", "daq_filter"),
                       # finite but out of reach: an overflowed polynomial, a 9e9-sample ring
                       ({"type": "butterworth", "order": 12, "cutoff_hz": 1e300}, "cutoff_hz"),
                       ({"type": "butterworth", "order": 12, "cutoff_hz": 1e-6}, "cutoff_hz")):
        d["simulation"]["daq_filter"] = bad
        with pytest.raises(ConfigError, match=rf"rig\.json.*{where}"):
            mdl.from_dict(d, "rig.json")


def test_the_cutoff_is_a_model_parameter_where_a_filter_is_declared() -> None:
    # discover's joint re-adjustment moves a found filter's cutoff with the elements' values
    m = dataclasses.replace(chain(), daq_filter=AA)
    assert m.parameters()[mdl.DAQ_CUTOFF] == AA.cutoff_hz
    assert mdl.DAQ_CUTOFF not in chain().parameters()
    moved = m.with_params({mdl.DAQ_CUTOFF: 200.0})
    assert moved.daq_filter == mdl.DaqFilter("butterworth", 8, 200.0)
    assert moved.masses_kg == m.masses_kg and mdl.param_unit(mdl.DAQ_CUTOFF, m) == "Hz"
    with pytest.raises(ConfigError, match="daq.cutoff_hz' needs a DAQ filter"):
        chain().with_params({mdl.DAQ_CUTOFF: 200.0})
    with pytest.raises(ConfigError, match="cutoff_hz"):  # validated as a declared one
        m.with_params({mdl.DAQ_CUTOFF: 1e-6})


def test_the_filters_gain_is_the_closed_form_one() -> None:
    """Butterworth: |H|^2 = 1 / (1 + (f/fc)^2n); Bessel (norm 'mag'): -3 dB at cutoff."""
    f = np.array([0.0, 100.0, 256.0, 300.0])
    h = daq.response(AA, f)
    assert np.abs(h) == pytest.approx(1.0 / np.sqrt(1.0 + (f / 256.0) ** 16), rel=1e-9)
    bes = daq.response(mdl.DaqFilter("bessel", 4, 200.0), np.array([0.0, 200.0]))
    assert np.abs(bes) == pytest.approx([1.0, math.sqrt(0.5)], rel=1e-6)


def test_through_the_filter_is_the_filter_and_unmeasured_undoes_it_in_band() -> None:
    """daq.measured against scipy's lsim of the analog filter on a response from rest;
    daq.unmeasured(measured(u)) gives u back where the filter passes (a band-limited input)."""
    rng = np.random.default_rng(1)
    n = 4096
    u = signal.sosfilt(signal.butter(4, [10.0, 150.0], btype="bandpass", fs=FS,
                                     output="sos"), rng.standard_normal(n))
    # the reference: the generator's way, the band-limited input at 16 fs through the
    # Butterworth made digital there, then every 16th sample
    fine = signal.resample_poly(u, 16, 1)
    ref = signal.sosfilt(synth.daq_filter("butter8", FS, 16 * FS), fine)[::16]
    got = daq.measured(AA, u, FS)
    assert float(np.std(u - ref)) > 0.3 * float(np.std(u))  # the filter's delay shows
    # (measured 3.3e-3: the digital filter at 16 fs is the analog one warped by 0.2 %)
    assert float(np.std(got - ref)) < 5e-3 * float(np.std(u))
    back = daq.unmeasured(AA, got, FS)
    # (measured 1.5e-3: what the filter rang out after the record is not in it)
    assert float(np.std(back[64:-64] - u[64:-64])) < 3e-3 * float(np.std(u))
    assert float(np.std(got[64:-64] - u[64:-64])) > 0.3 * float(np.std(u))
    two = daq.measured(AA, np.stack([u, 2 * u], axis=1), FS)
    assert two[:, 1] == pytest.approx(2 * got, abs=1e-12)
    # at 4 fs: through the samples, with nothing above fs/2 (an exact band-limited
    # interpolation: no image for the outputs to carry through the filter at 4 fs)
    fine_back = daq.unmeasured(AA, got, FS, 4)
    assert fine_back.size == 4 * n
    assert fine_back[::4] == pytest.approx(back, abs=1e-9 * float(np.std(u)))
    spec = np.abs(np.fft.rfft(fine_back * np.hanning(4 * n)))  # the window: no edge leakage
    above = np.fft.rfftfreq(4 * n, 1 / (4 * FS)) > 0.52 * FS
    assert float(spec[above].max()) < 1e-6 * float(spec.max())


def test_a_linear_model_commutes_with_the_filter_and_is_simulated_without_it() -> None:
    """daq.applied: a model without a nonlinear element is simulated as if none were declared;
    the filter divided out and put back gives the same within 2e-3 of the signal (measured
    2.3e-4 to 7.6e-4: the input's content near fs/2, divided by the filter's gain there, down
    to 0.17, is interpolated by 4 less exactly than in band)."""
    m = chain()
    recs = synth.generate(m, synth.Truth(), n_tests=1, n_samples=4096, seed=2)
    u = recs[0].channel("force_N").data
    plain = mdl.simulate(m, u, FS)
    with_aa = dataclasses.replace(m, daq_filter=AA)
    assert daq.applied(with_aa) is None
    same = mdl.simulate(with_aa, u, FS)
    ui = daq.unmeasured(AA, u, FS)
    round_trip = mdl.simulate(m, ui, FS)
    for c in m.outputs:
        assert np.array_equal(same[c], plain[c])
        back = daq.measured(AA, round_trip[c], FS)
        assert float(np.std(back - plain[c])) < 2e-3 * float(np.std(plain[c]))


@pytest.mark.parametrize("kind", ["force", "ground_acc"])
def test_a_nonlinear_rigs_true_model_is_measured_as_the_daq_measured_it(kind: str) -> None:
    """A contact on the generator's tests without noise (its filter: 8th order at 0.4 fs):
    the true model driven by the measured input leaves, on the contact's two channels, more
    than five times what it leaves with the filter declared, through simulate,
    simulate_batch and discover's test views alike. Measured (m/s^2): force 0.070 / 0.067 ->
    0.011 / 0.008, table sweep 0.60 / 0.59 -> 0.011 / 0.011; read through the filter after
    the samples were taken from the simulation at 4 x fs (before: the element's harmonics
    above fs/2 aliased at full strength) 0.018 / 0.016 and 0.16 / 0.16 (3.7-4.2 x)."""
    m = chain(kind)
    contact = (mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6) if kind == "force"
               else mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5))
    truth = synth.Truth(elements=(contact,))
    near = [f"acc{j}_mps2" for j in (contact.dof_a, contact.dof_b) if j]
    extra = {} if kind == "force" else {"levels_n_rms": (3.0,),
                                        "excitation": synth.Sweep(8.0, 200.0)}
    rec = synth.generate(m, truth, n_tests=1, n_samples=4096, seed=4, noise=0.0, **extra)[0]
    tm = dataclasses.replace(synth.truth_model(m, truth), outputs=m.outputs,
                             interpolation="bandlimited", oversample=4)
    u = rec.channel(m.input.channel).data
    t = rs.prepare(m, [rec])[0]
    left = {}
    for f in (None, AA):
        mm = dataclasses.replace(tm, daq_filter=f)
        sim = mdl.simulate(mm, u, FS)
        batch = mdl.simulate_batch(mm, u, FS, [{}])[0]
        res = rs.residuals(mm, t, list(m.outputs))
        assert res is not None
        for j, c in enumerate(m.outputs):
            assert batch[:, j] == pytest.approx(sim[c], abs=1e-12)
        left[f] = [float(np.std(res[c])) for c in near]
    assert all(a > 5 * b for a, b in zip(left[None], left[AA], strict=True)), left


def test_an_input_prepared_for_one_filter_is_refused_by_another() -> None:
    m = dataclasses.replace(chain(), elements=(mdl.Contact(3, 4, 1e-4, 1e-4, 1e6),))
    u = np.sin(np.arange(512) * 0.3)
    with_aa = dataclasses.replace(m, daq_filter=AA)
    prepared = mdl.prepare_input(with_aa, u, fs_hz=FS)
    assert prepared.daq == AA
    with pytest.raises(ConfigError, match="prepared for the DAQ filter"):
        mdl.simulate(m, prepared, FS)
    with pytest.raises(ConfigError, match="needs the sample rate"):
        mdl.prepare_input(dataclasses.replace(with_aa, fs_hz=None), u)
    # the model's rate unknown, the test's: the same range checked where it simulates
    far = dataclasses.replace(with_aa, fs_hz=None, daq_filter=mdl.DaqFilter("butterworth", 8,
                                                                           1e300))
    with pytest.raises(ConfigError, match=r"cutoff_hz: 1e\+300 Hz is outside 0.01..100 x"):
        mdl.simulate(far, u, FS)
    held = u.copy()
    held[7] = np.nan  # a held sample of a first-order hold: the FFT would spread it
    with pytest.raises(ConfigError, match="non-finite samples .1, the first at sample 7"):
        mdl.simulate(dataclasses.replace(with_aa, interpolation="foh", oversample=1), held, FS)
    with pytest.raises(ConfigError):
        mdl.simulate(with_aa, u[:0], FS)
    # the observer reads the measured channels: it takes the input as measured
    y = mdl.simulate(m, u, FS)
    assert mdl.predict_observed(with_aa, mdl.prepare_input(m, u), y, FS, [1.0] * 4,
                                dict.fromkeys(m.outputs, 1e-6))["acc1_mps2"].size == 512


def test_discover_says_it_and_writes_the_filter_with_the_model() -> None:
    """The run's note names the filter, the updated model keeps it, and its after-error is
    what simulating that model gives."""
    from dynval.discover import loop

    m = dataclasses.replace(chain(), daq_filter=AA)
    recs = synth.generate(chain(), synth.Truth(), n_tests=4, n_samples=2048, seed=5)
    r = loop.discover(m, recs, loop.Options(workers=1, max_effects=0))
    (note,) = [n for n in r.notes if "DAQ filter" in n]
    assert "butterworth, order 8, 256 Hz" in note
    assert r.model.daq_filter == AA
    tab, _ = rs.error_table(r.model, r.tests, r.chans, r.scales)
    assert tab.total(r.held_names) == pytest.approx(r.after.total(r.held_names), rel=1e-9)


def test_a_fit_of_the_cutoff_takes_the_measured_input_through_its_noise_filters_once(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """TestData.input_for at a new cutoff prepares a new input, but the measured input as the
    simulations take it (noise.simulated_input) does not depend on the model: it is computed
    once per test and input kind, and the predictions are those of a fresh test's."""
    from dynval.discover import noise

    m = chain()
    recs = synth.generate(m, synth.Truth(), n_tests=1, n_samples=2048, seed=3,
                          levels_n_rms=(10.0,))
    calls: list[int] = []
    real = noise.simulated_input

    def counting(kind: str, u: np.ndarray, fs_hz: float) -> np.ndarray:
        calls.append(1)
        return real(kind, u, fs_hz)

    monkeypatch.setattr(noise, "simulated_input", counting)
    t = rs.prepare(m, recs)[0]
    for cut in (200.0, 230.0, 256.0, 230.0, 210.0):
        filtered = dataclasses.replace(m, daq_filter=mdl.DaqFilter("butterworth", 8, cut))
        p = rs.predict(filtered, t)
        fresh = rs.predict(filtered, rs.prepare(m, recs)[0])
        assert p is not None and fresh is not None
        assert all(np.array_equal(p[c], fresh[c]) for c in p)
    assert len(calls) == 1 + 5  # this test's once, and each fresh test's once
