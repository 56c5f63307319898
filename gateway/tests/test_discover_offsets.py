"""Sensor offsets (issue 16, item 5): a constant added to one channel is named on that channel
and fitted within 3 %, the other channels are left alone; offsets on every channel of a cheap
DAQ are one calibration, found together, and leave room for the physical effect."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from lanl4dof import ACC, declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import acc_offsets, loop
from dynval.discover import residual as rs
from dynval.io.recording import Recording


@pytest.mark.parametrize("seed", [101, 102])
def test_a_sensor_offset_is_named_on_its_channel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ch = f"acc{int(rng.integers(1, 5))}_mps2"
    recs = gen.generate(declared(), gen.Truth(label="offset"), n_tests=4, seed=seed)
    rms = float(np.sqrt(np.mean(np.concatenate([r.channel(ch).data for r in recs]) ** 2)))
    b = float(rng.choice([-1, 1]) * rng.uniform(0.05, 0.15) * rms)
    for r in recs:
        r.channel(ch).data = r.channel(ch).data + b
    res = loop.discover(declared(), recs)
    # the model has a nearly rigid mode, but a constant is an offset, not a drift: the
    # observer (which tracked the offset and biased it: 4.6x the true model's held-out error
    # after) is not taken
    assert res.prediction == "open loop"
    assert [e["type"] for e in res.effects] == ["sensor_offset"]
    e = res.effects[0]
    assert e["location"]["channels"] == [ch]
    assert e["parameters"][f"offset {ch}"]["value"] == pytest.approx(b, rel=0.03)
    assert res.model.outputs[ch].offset == pytest.approx(b, rel=0.03)
    assert all(res.model.outputs[c].offset == 0.0 for c in ACC if c != ch)
    # the model file keeps it
    assert mdl.from_dict(mdl.to_dict(res.model)).outputs[ch].offset == res.model.outputs[ch].offset


@pytest.mark.parametrize("with_contact", [False, True])
def test_a_cheap_daq_offsets_hum_and_coloured_noise(with_contact: bool) -> None:
    """Every channel offset (2-8 % of its STD), 50 Hz hum, 1/f + white noise behind a
    2nd-order anti-alias filter: before, the offsets were fitted one per round and used up
    max_effects (the bumper was never reached) and the hum read as an unexplained residual;
    now an offset per test and channel (acc_offsets.py: they grow with the test's level), the
    hum counted in the noise floor, and the bumper found."""
    from test_discover_noise import cheap_daq

    m = declared()
    els = (mdl.Contact(3, 4, 1.0e-4, 1e-4, 1.925e6),) if with_contact else ()
    recs = gen.generate(m, gen.Truth(elements=els), n_tests=6, seed=11, noise=0.0)
    cheap_daq(recs, np.random.default_rng(11), offset=0.02, hum=3.0)
    r = loop.discover(m, recs)
    # the offsets grow with each test's level: one per test and channel, not an effect
    assert [e["type"] for e in r.effects] == (["contact"] if with_contact else [])
    note = [n for n in r.notes if n.startswith("the mean residual of ")]
    assert len(note) == 1 and all(f"{c} (" in note[0] for c in ACC)
    assert all("mains hum at 50 Hz" in r.noise_floors[c].detail for c in r.chans)
    assert not r.unexplained


def cheap_tests(seed: int, offset: float, common: float
                ) -> tuple[mdl.Model, list[Any], dict[str, list[float]]]:
    """A clean 4-DOF case plus a displacement sensor at DOF 2 through a cheap DAQ whose
    offsets grow with each test's level (``offset``, test_discover_noise.cheap_daq), and
    ``common`` added to every output of every test; with each output's offset per test."""
    from test_discover_noise import cheap_daq

    m = declared()
    m = dataclasses.replace(m, outputs={**m.outputs, "x2_m": mdl.Output("disp", 2)})
    recs = gen.generate(m, gen.Truth(), n_tests=6, seed=seed, noise=0.0)
    clean = [{c.name: c.data.copy() for c in r.channels} for r in recs]
    cheap_daq(recs, np.random.default_rng(seed), offset, 2.0)
    for r in recs:
        for c in r.channels:
            c.data = c.data + (common if c.role == "output" else 0.0)
    added = {c: [float(np.mean(r.channel(c).data - y[c])) for r, y in zip(recs, clean,
                                                                         strict=True)]
             for c in m.outputs}
    return m, recs, added


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_accelerometer_offsets_that_change_per_test_are_found_and_measured(seed: int) -> None:
    """Offsets of 3-12 % of each channel's STD that follow the test's level: every
    accelerometer is found (p < 1e-6; measured at most 3e-10) and each test's offset is
    measured within 0.5 % of their spread (measured at most 0.07 %); the displacement channel
    is never given per-test offsets (its mean is the structure's, not only the sensor's)."""
    m, recs, added = cheap_tests(seed, 0.03, 0.0)
    tests = rs.prepare(m, recs)
    spread = acc_offsets.analyse(m, tests, rs.common_channels(m, tests))
    assert set(spread) == set(ACC)
    assert all(s.p < 1e-6 for s in spread.values())
    for c, sp in spread.items():
        assert np.max(np.abs(np.array(sp.per_test) - added[c])) < 0.005 * np.ptp(added[c])
    assert len(acc_offsets.apply(m, tests, [], rs.common_channels(m, tests))) == 1  # a note
    assert all(sorted(t.demean) == sorted(ACC) for t in tests)
    assert all(t.demean[c] == spread[c].per_test[i] for i, t in enumerate(tests) for c in ACC)
    # every prediction of those channels now leaves each test's residual without its mean
    r = rs.residuals(m, tests[0], list(ACC))
    assert r is not None and all(abs(float(np.mean(r[c]))) < 1e-12 for c in ACC)


@pytest.mark.parametrize("seed", [0, 1, 5])
def test_clean_records_and_one_offset_for_all_tests_get_no_per_test_offsets(seed: int) -> None:
    """White noise only (the generator's), or a cheap DAQ's noise with one offset on every
    test: no channel's mean changes from test to test beyond its scatter within a test
    (measured p >= 0.002 on these seeds). Under 1/f noise the block means are not
    independent and the analysis reads low p more often than 1e-3 (4 of 24 channels on
    seeds 0-5): it then leaves out a per-test mean that is the noise's, which no structure
    makes (an acceleration's mean over a test is about zero)."""
    m = declared()
    recs = gen.generate(m, gen.Truth(), n_tests=6, seed=seed)
    tests = rs.prepare(m, recs)
    assert all(s.p > 1e-3 for s in acc_offsets.analyse(m, tests, list(ACC)).values())
    m, recs, _ = cheap_tests(seed, 0.0, 0.05)
    tests = rs.prepare(m, recs)
    assert all(s.p > 1e-3 for s in acc_offsets.analyse(m, tests, list(ACC)).values())


def test_the_observer_reads_the_accelerometers_without_their_offsets() -> None:
    """A free chain in observer mode (an encoder at DOF 1): accelerometer offsets of 0.05-0.6
    m/s^2 that grow from test to test. The observer that read them held its state off, and
    the encoder's one-step errors carried a mean of -0.29 to -1.13 um (RMS up to 1.5 x the
    offset-free records'), which a constant force at a DOF then explained (blind free chain
    seeds 0 and 9 under a cheap DAQ). With each test's offsets taken out of what the
    observer reads, its errors are those of the offset-free records."""
    from test_discover_drift import PARTIAL, free_chain

    from dynval.discover import drift

    m = free_chain(PARTIAL)
    chans, acc = list(PARTIAL), [c for c in PARTIAL if c.startswith("a")]

    def encoder_errors(with_offsets: bool, demean: bool) -> np.ndarray:
        recs = gen.generate(m, gen.Truth(), n_tests=4, seed=3)
        for k, r in enumerate(recs):
            for j, c in enumerate(acc):
                r.channel(c).data = r.channel(c).data + with_offsets * 0.05 * (k + 1) * (j + 1)
        tests = rs.prepare(m, recs)
        if demean:
            assert len(acc_offsets.apply(m, tests, [], chans)) == 1
        obs = drift.observer_for(m, tests, chans, rs.channel_scales(tests, chans))
        out = []
        for t in tests:
            t.observer = obs
            r = rs.residuals(m, t, ["x1_m"])
            assert r is not None
            out.append(r["x1_m"])
        return np.array(out)

    clean = encoder_errors(with_offsets=False, demean=False)
    read = encoder_errors(with_offsets=True, demean=False)
    taken_out = encoder_errors(with_offsets=True, demean=True)
    assert np.all(read.mean(axis=1) < -2e-7)  # the offsets bias the encoder's errors
    assert np.max(np.abs(clean.mean(axis=1))) < 2e-8
    rms = [np.sqrt(np.mean(e ** 2, axis=1)) for e in (clean, read, taken_out)]
    assert np.max(rms[1] / rms[0]) > 1.4
    np.testing.assert_allclose(rms[2], rms[0], rtol=1e-3)


@pytest.mark.parametrize("seed", [4, 7])
def test_an_encoder_zero_on_a_weak_position_loop_is_its_offset_not_a_force(seed: int) -> None:
    """An encoder whose zero is not the loop's (2-4 um) on a chain in a weak position loop
    (1 % of the story stiffness), records cut from a run (no start-up transient): a constant
    force at any DOF shifts the encoder's mean alike and nothing else the tests see. One
    offset or one force: the tie goes to the sensor's zero, named with the force beside it
    (before, a 7 mN force offset at DOF 5 was named beside the right contact on blind free
    chain seed 9, 0.77 x the ideal held-out error)."""
    n = 4096
    m = mdl.Model(masses_kg=(3.0, 2.0, 2.5), stiffness_n_per_m=(2.5e3, 2.5e5, 2.0e5),
                  damping=mdl.Damping("modal", (0.4, 0.02, 0.02)),
                  input=mdl.Input("force", 2, "force_N"),
                  outputs={"x1_m": mdl.Output("disp", 1),
                           **{f"a{j}_mps2": mdl.Output("acc", j) for j in (1, 2, 3)}},
                  fs_hz=640.0)
    zero = float(np.random.default_rng(seed).uniform(2e-6, 4e-6))
    runs = gen.generate(m, gen.Truth(), n_tests=4, n_samples=2 * n, seed=seed)
    recs = [Recording(r.name, r.fs_hz, [dataclasses.replace(
        c, data=np.ascontiguousarray(c.data[n:]) + (zero if c.name == "x1_m" else 0.0))
        for c in r.channels]) for r in runs]
    r = loop.discover(m, recs)
    assert [e["type"] for e in r.effects] == ["sensor_offset"]
    assert r.effects[0]["location"]["channels"] == ["x1_m"]
    assert r.effects[0]["parameters"]["offset x1_m"]["value"] == pytest.approx(zero, rel=0.05)
    assert any("cannot tell a constant force from the sensor's zero" in n for n in r.notes)
