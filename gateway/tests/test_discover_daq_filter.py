"""The DAQ's anti-alias filter as an effect discover finds (effects.DaqAntiAlias): a nonlinear
element's harmonics pass the rig's filter, not a simulation driven by the filtered input, so a
right nonlinear model whose filter is not declared leaves a residual the filter explains. On
the generator's tests (its DAQ: an 8th-order Butterworth at 0.4 fs) of a contact under a
shake-table sweep, discover must name the filter with a cutoff near the generator's and end
within 1.3 x the held-out error of the true model with that filter declared."""
from __future__ import annotations

import dataclasses
from typing import Any

import pytest
from generated import table_chain

from dynval import model as mdl
from dynval import synth
from dynval.discover import effects as fx
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.discover import session as ss

FS = 640.0
AA = mdl.DaqFilter("butterworth", 8, 0.4 * FS)  # synth.daq_filter("butter8")'s analog twin


def _table_chain() -> mdl.Model:
    return table_chain((6.5, 6.6, 6.7, 6.8), (4e5,) * 4, (0.01, 0.02, 0.01, 0.015))


def test_the_filter_is_offered_only_where_the_tests_can_see_it() -> None:
    """A linear model commutes with the filter, a declared filter is there already, and a
    cutoff needs the sample rate: no candidate then; else one per order."""
    m = _table_chain()
    with_contact = dataclasses.replace(m, elements=(mdl.Contact(1, 2, 1e-4, 1e-4, 1e6),))

    def offered(mm: mdl.Model) -> list[str]:
        return [c.label for c in fx.catalogue(mm) if c.type == "daq_filter"]

    assert offered(m) == []
    assert offered(dataclasses.replace(with_contact, daq_filter=AA)) == []
    assert offered(dataclasses.replace(with_contact, fs_hz=None)) == []
    assert offered(with_contact) == [f"DAQ anti-alias filter, Butterworth order {k}"
                                     for k in fx.DaqAntiAlias.ORDERS]
    cand = fx.catalogue(with_contact)[-1]
    (p,) = fx.by_type("daq_filter").params(with_contact, cand)
    assert (p.lower, p.upper) == (0.05 * FS, FS)
    assert fx.by_type("daq_filter").apply(with_contact, cand, [200.0]).daq_filter == \
        mdl.DaqFilter("butterworth", 8, 200.0)


def test_discover_names_the_filter_a_right_nonlinear_model_lacks() -> None:
    """The true model (a contact across story 2) declared without its DAQ filter: the filter is
    the effect found, its cutoff within 15 % of the generator's -3 dB point (measured: order
    8 at 268 Hz for the generator's 8 at 256; the 6-DOF bench case took order 4 at 268 Hz:
    the order is known only as far as the harmonics reach), and the held-out error within
    1.3 x that of the true model with the generator's filter declared (measured 1.09 x:
    0.00191 against 0.00176, from 0.00774 before); the model written keeps it. Every order
    is fitted once one wins (before, only the 4th and 8th were: a probe at one cutoff ranked
    them, and blind sweep case 4 took the 4th for the generator's 8th)."""
    m = _table_chain()
    truth = synth.Truth(elements=(mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5),))
    recs = synth.generate(m, truth, n_tests=4, n_samples=4096, seed=11,
                          levels_n_rms=(3.0, 1.8), excitation=synth.Sweep(8.0, 200.0))
    declared = dataclasses.replace(synth.truth_model(m, truth), outputs=m.outputs,
                                   interpolation="bandlimited", oversample=4)
    r = loop.discover(declared, recs, loop.Options(workers=1, max_effects=1))
    (found,) = r.effects
    assert found["type"] == "daq_filter", [e["label"] for e in r.effects]
    orders = {f["candidate"].location["order"] for f in r.rounds[0].fits
              if f["candidate"].type == "daq_filter"}
    assert orders == set(fx.DaqAntiAlias.ORDERS)  # each fitted: one probe cannot rank them
    cutoff = found["parameters"]["cutoff_hz"]["value"]
    assert cutoff == pytest.approx(AA.cutoff_hz, rel=0.15)
    assert r.model.daq_filter is not None
    assert r.model.daq_filter.cutoff_hz == pytest.approx(cutoff)
    ideal = dataclasses.replace(r.model, daq_filter=AA, elements=declared.elements)
    tab, _ = rs.error_table(ideal, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) <= 1.3 * tab.total(r.held_names)
    assert r.after.total(r.held_names) < 0.8 * r.before.total(r.held_names)


def test_the_verdict_names_the_structure_first_then_the_measurement_chain() -> None:
    """A DAQ's filter, gains and offsets are the measurement chain's: the verdict names them
    after the structure's effects, whatever the order they were found in (sensor offsets are
    taken before the rounds)."""
    from dynval.discover import report

    def entry(kind: str, label: str) -> dict[str, object]:
        return {"type": kind, "label": label, "alternatives": []}

    found = [entry("sensor_offset", "sensor offsets, channels a1"),
             entry("contact", "contact, story 2"),
             entry("daq_filter", "DAQ anti-alias filter, Butterworth order 8")]
    assert [e["type"] for e in fx.structural(found)] == ["contact"]
    assert report._verdict(found, {}, None) == (
        "the model lacks: contact, story 2; in its measurements: sensor offsets, channels a1; "
        "DAQ anti-alias filter, Butterworth order 8")
    assert report._verdict(found[:1], {}, None) == (
        "the model lacks: in its measurements: sensor offsets, channels a1")


def _entry(f: mdl.DaqFilter) -> dict[str, Any]:
    return {"type": "daq_filter", "label": f"DAQ anti-alias filter, Butterworth order {f.order}",
            "location": {"filter": "butterworth", "order": f.order},
            "parameters": {"cutoff_hz": {"value": f.cutoff_hz, "uncertainty": 1.0,
                                         "uncertainty_fit": 1.0, "uncertainty_scatter": 0.0,
                                         "unit": "Hz"}}}


@pytest.mark.parametrize("order", [4, 8])
def test_the_filter_order_is_chosen_again_on_the_final_model(order: int) -> None:
    """A round ranks the orders before the later re-adjustments move the structure: the 6-DOF
    shake-table sweep of bench/bench_discover.py ended with the generator's 8th order read as
    a 4th at 223 Hz (1.48 x the true model's held-out error). On the final model each other
    order's cutoff is fitted again: from a 4th order at 223 Hz the 8th is taken, its cutoff
    within 6 % of the generator's (measured 268.8 Hz on these four tests, 255.3 Hz on the
    bench case's ten: the harmonics reach only so far) and the held-out error lower, its
    entry keeping the round's; from the 8th at 256 Hz nothing changes."""
    m = _table_chain()
    truth = synth.Truth(elements=(mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5),))
    recs = synth.generate(m, truth, n_tests=4, n_samples=4096, seed=11,
                          levels_n_rms=(3.0, 1.8), excitation=synth.Sweep(8.0, 200.0))
    f = mdl.DaqFilter("butterworth", order, 223.0 if order == 4 else AA.cutoff_hz)
    cur = dataclasses.replace(synth.truth_model(m, truth), outputs=m.outputs,
                              interpolation="bandlimited", oversample=4, daq_filter=f)
    s = ss.make_session(cur, recs, ss.Options(workers=1))
    table = s.table(cur)[0]
    effects = [_entry(f)]
    got, tab = loop._daq_order_again(s, cur, table, effects, "open loop")
    if order == 8:
        assert got is cur and "in_its_round" not in effects[0]
        return
    assert got.daq_filter is not None and got.daq_filter.order == 8
    assert got.daq_filter.cutoff_hz == pytest.approx(AA.cutoff_hz, rel=0.06)
    assert tab.total(s.held_names) < table.total(s.held_names)
    e = effects[0]
    assert (e["location"]["order"], e["in_its_round"]) == (8, {"order": 4, "cutoff_hz": 223.0})
    assert e["parameters"]["cutoff_hz"]["value"] == got.daq_filter.cutoff_hz
    assert any("order chosen again" in n for n in s.notes)


def test_with_a_filter_found_the_updated_model_is_simulated_as_declared() -> None:
    """A linear declared model passes the cubic hold's check (it commutes with any filter);
    once a contact and the DAQ filter are in, the filter divided out of the measured input
    lifts what the hold misses near the cutoff: the true model's held-out error measured
    1.62 x under the hold. So the hold is checked again on the updated model, and over
    HOLD_GAP the model, re-adjusted there, and the report's errors are in the declared
    simulation (measured:
    the contact, then the filter, 4th at 229 Hz chosen again as the 8th at 254.9 Hz; 1.13 x
    the true model's held-out error)."""
    m = dataclasses.replace(_table_chain(), interpolation="bandlimited", oversample=4)
    truth = synth.Truth(elements=(mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5),))
    recs = synth.generate(m, truth, n_tests=6, n_samples=4096, seed=11,
                          levels_n_rms=(3.0, 1.8), excitation=synth.Sweep(8.0, 200.0))
    r = loop.discover(m, recs)
    assert [(e["type"], e["location"].get("story"), e["location"].get("order"))
            for e in r.effects] == [("contact", 2, None), ("daq_filter", None, 8)]
    assert (r.model.interpolation, r.model.oversample) == ("bandlimited", 4)
    assert (r.model0.interpolation, r.model0.oversample) == ("bandlimited", 4)
    assert any("its parameters re-adjusted again, and the errors before and after, in the "
               "declared simulation" in n for n in r.notes)
    tm = dataclasses.replace(synth.truth_model(m, truth), outputs=m.outputs, daq_filter=AA)
    ideal, held = (rs.error_table(dataclasses.replace(tm, interpolation=i, oversample=k),
                                  r.tests, r.chans, r.scales)[0].total(r.held_names)
                   for i, k in (("bandlimited", 4), ("cubic", 1)))
    assert held > 1.3 * ideal  # the hold is not good enough here (1.62 x)
    assert r.after.total(r.held_names) < 1.2 * ideal
