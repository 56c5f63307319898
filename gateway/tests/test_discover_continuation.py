"""The joint re-adjustment through the observer's gains (discover/continuation.py): from a
declared model whose upper modes sit several bandwidths off under a swept sine, with their
damping three times too high, the output-error fit stops short, while the continuation
reaches the true stiffnesses and damping ratios (closed form: the generator's own model);
and discover, on a shake table's sweep with a contact and a best-linear declared model,
ends at the ideal's error with the contact alone."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from generated import sought, table_chain

from dynval import model as mdl
from dynval import synth
from dynval.discover import continuation as cont
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.discover import session as ss

K = 399790.0
NAMES = ("k1", "k2", "k3", "k4", "zeta1", "zeta2", "zeta3", "zeta4")


def _table_chain() -> mdl.Model:
    return table_chain((6.5, 6.6, 6.7, 6.8), (K,) * 4, (0.01, 0.05, 0.01, 0.01))


def test_a_model_with_modes_bandwidths_off_is_brought_back_by_the_continuation() -> None:
    truth = _table_chain()
    declared = truth.with_params({"k1": 1.2 * K, "k4": 1.5 * K, "zeta3": 0.03, "zeta4": 0.03})
    f_true, f_dec = mdl.natural_frequencies(truth), mdl.natural_frequencies(declared)
    assert f_dec[2] / f_true[2] > 1.09  # modes 3 and 4 are 10 and 7 % off at 1 % damping
    recs = synth.generate(truth, synth.Truth(), n_tests=4, n_samples=4096, seed=3,
                          levels_n_rms=(3.0,), excitation=synth.Sweep(8.0, 200.0))
    tests = rs.prepare(declared, recs)
    chans = rs.common_channels(declared, tests)
    scales = rs.channel_scales(tests, chans)
    r_true = ft.residual_vector(truth, tests, chans, scales)
    assert r_true is not None
    floor = float(r_true @ r_true)
    plain = ft.fit(declared, fx.NONE.candidates(declared)[0], [], tests, chans, scales, 40,
                   NAMES)
    assert plain.nsse_fit > 5 * floor  # the output-error fit alone stops short (14 x)
    res = cont.fit(declared, NAMES, tests, chans, scales, 40)
    assert res is not None
    assert res.nsse_fit < 1.01 * floor
    got = res.model.parameters()
    want = truth.parameters()
    assert [got[n] for n in NAMES[:4]] == pytest.approx([want[n] for n in NAMES[:4]], rel=5e-3)
    assert [got[n] for n in NAMES[4:]] == pytest.approx([want[n] for n in NAMES[4:]], rel=0.02)
    assert np.allclose(mdl.natural_frequencies(res.model), f_true, rtol=2e-3)


def test_tests_on_an_observer_already_are_left_to_the_plain_fit() -> None:
    m = _table_chain()
    recs = synth.generate(m, synth.Truth(), n_tests=1, n_samples=512, seed=1,
                          levels_n_rms=(3.0,))
    tests = rs.prepare(m, recs)
    chans = rs.common_channels(m, tests)
    scales = rs.channel_scales(tests, chans)
    tests[0].observer = rs.Observer((1.0,) * 4, {c: 1.0 for c in chans})
    assert cont.fit(m, NAMES, tests, chans, scales, 5) is None


def test_a_contact_under_a_sweep_on_a_best_linear_model_ends_at_the_ideal() -> None:
    """The bench's shake-table sweep case, shorter (4 tests x 4096). The best-linear model's
    top mode is 9 % high (79.9 Hz for 73.5); the contact's fit finds the contact but the
    joint re-adjustment from the best-linear values stopped in a local minimum: measured
    before, the contact alone (0.149 mm, 771 kN/m) at 4.5 x the ideal's held-out error; through
    the observer's gains 0.77 x."""
    truth = _table_chain()
    el = mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5)
    recs = synth.generate(truth, synth.Truth(elements=(el,)), n_tests=4, n_samples=4096,
                          seed=7, levels_n_rms=(3.0, 1.8), excitation=synth.Sweep(8.0, 200.0))
    declared = synth.best_linear(truth, recs)
    assert mdl.natural_frequencies(declared)[3] > 1.08 * mdl.natural_frequencies(truth)[3]
    r = loop.discover(declared, recs)
    assert [(e["type"], e["location"]["between"]) for e in sought(r.effects)] == [
        ("contact", [1, 2])]
    got = {k: v["value"] for k, v in sought(r.effects)[0]["parameters"].items()}
    assert got["gap_m"] == pytest.approx(1.5e-4, rel=0.1)
    assert got["kb_n_per_m"] == pytest.approx(8e5, rel=0.1)
    ideal, _ = rs.error_table(dataclasses.replace(truth, elements=(el,)), r.tests, r.chans,
                              r.scales)
    assert r.after.total(r.held_names) / ideal.total(r.held_names) < 1.3


def test_the_continuation_runs_until_one_joint_re_adjustment_is_kept(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """After a kept re-adjustment the modes are where the data put them: a later round's
    re-adjustment is the plain fit from there (the continuation cost blind sweep case 15
    118 s in its second round, not kept)."""
    truth = _table_chain()
    declared = truth.with_params({"k1": 1.2 * K, "k4": 1.5 * K, "zeta3": 0.03, "zeta4": 0.03})
    recs = synth.generate(truth, synth.Truth(), n_tests=4, n_samples=4096, seed=3,
                          levels_n_rms=(3.0,), excitation=synth.Sweep(8.0, 200.0))
    s = ss.make_session(declared, recs, ss.Options(workers=1))
    calls: list[int] = []
    real = cont.fit

    def counted(*a: Any, **k: Any) -> ft.FitResult | None:
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(cont, "fit", counted)
    table, _ = s.table(declared)
    kept = loop._readjust_declared(s, declared, table)
    assert kept is not None and s.readjust_kept and calls == [1]
    got = kept[0].parameters()
    assert got["k4"] == pytest.approx(K, rel=5e-3)  # the continuation's, not the plain fit's
    again = loop._readjust_declared(s, kept[0], kept[1])
    assert calls == [1]  # not run again
    assert again is None  # nothing left to re-adjust


def test_the_continuation_is_not_run_again_after_a_measurement_chain_effect(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A DAQ filter or a sensor's gain moves no mode: after a re-adjustment through the
    observer's gains that was not kept, the same search would find the same basin (4-DOF
    shake-table case of bench/bench_discover.py: 27 s for it after the DAQ filter's round).
    A structural effect since, and it runs again."""
    truth = _table_chain()
    recs = synth.generate(truth, synth.Truth(), n_tests=4, n_samples=2048, seed=4,
                          levels_n_rms=(3.0,), excitation=synth.Sweep(8.0, 200.0))
    s = ss.make_session(truth, recs, ss.Options(workers=1))
    calls: list[bool] = []

    def counted(*a: Any, **k: Any) -> ft.FitResult | None:
        calls.append(True)
        return None  # not kept, as on a model with nothing to re-adjust

    monkeypatch.setattr(cont, "fit", counted)
    table, _ = s.table(truth)
    assert loop._readjust_declared(s, truth, table) is None and len(calls) == 1
    assert loop._readjust_declared(s, truth, table, structural=False) is None
    assert len(calls) == 1  # a measurement-chain effect: not again
    assert loop._readjust_declared(s, truth, table, structural=True) is None
    assert len(calls) == 2  # a structural one: again
