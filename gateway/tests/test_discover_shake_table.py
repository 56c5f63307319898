"""A shake-table input gets the same evidence view as a force input (issue 16, item 7): the
states relative to the table from the measured absolute accelerations minus the table's, the
missing force from -M 1 a_g. Before, the view was refused, every candidate was fitted and a
friction joint was put in the wrong place."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from generated import sought, table_chain
from test_discover_noise import pink

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import changes_apart as ca
from dynval.discover import effects as fx
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.discover import trace as tr
from dynval.model import simulation as sim
from dynval.model.structure import with_appendage

ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}


def on_a_table() -> mdl.Model:
    return table_chain((6.54, 6.66, 6.86, 6.80), (399790.0,) * 4, (0.01, 0.02, 0.01, 0.01))


@pytest.mark.parametrize(("el", "want"), [
    (mdl.Friction(1, 2, 2.0, 1e-4), ("friction", [1, 2])),
    (mdl.Contact(2, 3, 0.5e-4, 1e-4, 1.925e6), ("contact", [2, 3])),
    (mdl.CubicSpring(3, 4, 3e12), ("cubic_stiffness", [3, 4])),
])
def test_shake_table_evidence_ranks_the_element_first(el: mdl.Element,
                                                      want: tuple[str, list[int]]) -> None:
    m = on_a_table()
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=3, seed=3, levels_n_rms=(3.0, 1.8))
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None
    top = tr.score(view, fx.catalogue(m))[0]
    assert (top.cand.type, top.cand.location["between"]) == want


def test_shake_table_friction_joint_is_found_and_fitted() -> None:
    m = on_a_table()
    recs = gen.generate(m, gen.Truth(elements=(mdl.Friction(1, 2, 2.0, 1e-4),)), n_tests=6,
                        seed=3, levels_n_rms=(3.0, 1.8))
    r = loop.discover(m, recs)
    assert [(e["type"], e["location"]["between"]) for e in sought(r.effects)] == [
        ("friction", [1, 2])]
    assert sought(r.effects)[0]["parameters"]["force_n"]["value"] == pytest.approx(2.0, rel=0.1)
    assert r.after.total(r.held_names) < 0.05 * r.before.total(r.held_names)



def five_on_a_table() -> mdl.Model:
    """Uneven masses and stories, a light top: the kind of the blind case that failed."""
    return table_chain((2.8, 4.3, 5.7, 7.0, 2.75), (3.46e5, 2.46e5, 4.39e5, 3.75e5, 2.25e5),
                       (0.011, 0.025, 0.02, 0.039, 0.033))


@pytest.mark.parametrize("seed", [4])  # seed 5 (found either way): dropped for CI time
def test_rarely_closing_contact_on_a_table_is_found(seed: int) -> None:
    """A contact that closes a few times per record on a shake table (gap 2.5 x the story's
    RMS drift): the view's evidence is swamped by the integrated sensor noise (under 2 % of
    the residual). When the best evidence is under a tenth of the residual above the noise,
    the best-placed candidate of each nonlinear element type is fitted too and the held-out
    tests judge. Measured without that: seed 4 "no effect" at 2.74 x the ideal's held-out
    error (the blind case of bench/RESULTS.blind.md: 2.77 x); with it 1.10 x; seed 5 found
    either way (1.11 x)."""
    m = five_on_a_table()
    u = gen.band_limited_force(np.random.default_rng(0), 8192, 640.0, 3.0)
    probe = dataclasses.replace(m, outputs={f"x{j}": mdl.Output("disp", j) for j in (3, 4)})
    y = mdl.simulate(probe, u, 640.0)
    el = mdl.Contact(3, 4, 2.5 * float(np.std(y["x4"] - y["x3"])), 5e-5,
                     4 * m.stiffness_n_per_m[3])
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=6, seed=seed,
                        levels_n_rms=(3.0, 1.8))
    r = loop.discover(m, recs)
    assert r.rounds[0].evidence[0].cand.type == "none"  # the view sees little
    assert [(e["type"], e["location"]["between"]) for e in r.effects][:1] == [("contact", [3, 4])]
    ideal, _ = rs.error_table(dataclasses.replace(m, elements=(el,)), r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)


@pytest.mark.parametrize(("truth", "want"), [
    (gen.Truth(m_add_kg={2: 0.7}), ("mass_change", {"dof": 2})),
    (gen.Truth(appendages=(gen.Appendage(3, 0.5, 60.0, 0.02),)), ("appendage", {"dof": 3})),
])
def test_a_mass_on_a_table_resists_the_absolute_acceleration(
        truth: gen.Truth, want: tuple[str, dict[str, int]]) -> None:
    """The states of a shake-table model are relative to the table; an added mass or an
    appendage resists the absolute acceleration (a + a_g). Their bases on the relative one
    saw half the evidence (measured: 0.088 and 0.24 against 0.183 and 0.478), and a blind
    case (a mass change at DOF 4, best-linear, cheap DAQ) ranked its mass change 64th and
    ended "no effect" at 1.42 x the ideal."""
    m = on_a_table()
    recs = gen.generate(m, truth, n_tests=3, seed=3, levels_n_rms=(3.0, 1.8))
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None and view.states.ag is not None

    def right(ev: list[tr.Evidence]) -> tuple[int, float]:
        i = next(i for i, e in enumerate(ev)
                 if (e.cand.type, e.cand.location) == want)
        return i, ev[i].r2

    rank, r2 = right(tr.score(view, fx.catalogue(m)))
    view.states.ag = None  # as before: the relative acceleration only
    _, r2_relative = right(tr.score(view, fx.catalogue(m)))
    assert rank <= 1 and r2 > 1.8 * r2_relative


def test_a_joint_on_a_table_with_its_dof_unmeasured_is_found() -> None:
    """A shake table with no accelerometer at DOF 2 and friction between DOF 1 and DOF 2: the
    output view (the model's simulated states, G from a force at each DOF) now serves a
    table as it does a force input. Before, there was no view (every candidate fitted), and
    the residual's 61 Hz mode, read as mains hum, put the floor at 1.0-1.5 m/s^2: "no
    effect" at 823 x the ideal's held-out error. Measured after: 1.00 x."""
    m = on_a_table()
    part = dataclasses.replace(m, outputs={k: v for k, v in ACC.items() if k != "acc2_mps2"})
    el = mdl.Friction(1, 2, 2.0, 1e-4)
    recs = gen.generate(part, gen.Truth(elements=(el,)), n_tests=6, n_samples=4096, seed=3,
                        levels_n_rms=(3.0, 1.8))
    r = loop.discover(part, recs)
    assert [(e["type"], e["location"]["between"]) for e in sought(r.effects)] == [
        ("friction", [1, 2])]
    assert sought(r.effects)[0]["parameters"]["force_n"]["value"] == pytest.approx(2.0, rel=0.1)
    ideal, _ = rs.error_table(dataclasses.replace(part, elements=(el,)), r.tests, r.chans,
                              r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_clearance_under_a_cheap_daqs_pink_noise_ranks_first(seed: int) -> None:
    """A clearance (a contact closing both ways, gap 1.6 x the story's RMS drift) on a table
    whose every channel, the table's too, carries a cheap DAQ's 1/f noise (2 % of its RMS)
    and white noise (1 %). The states were high-passed at 0.4 x the lowest mode, where the
    1/f noise integrated twice swamps the drift: the blind cases (RESULTS.blind-kinds.md,
    seeds 1 and 20) had the contact's evidence at 0.02 and ended with "no effect" (3.42 x
    the ideal) or a cubic spring at the wrong place (1.93 x). The corner is now at least half
    the input band's lower edge: the contact ranks first."""
    m = five_on_a_table()
    u = gen.band_limited_force(np.random.default_rng(0), 8192, 640.0, 3.0)
    probe = dataclasses.replace(m, outputs={f"x{j}": mdl.Output("disp", j) for j in (1, 2)})
    y = mdl.simulate(probe, u, 640.0)
    el = mdl.Contact(1, 2, 1.6 * float(np.std(y["x2"] - y["x1"])), 5e-5,
                     4 * m.stiffness_n_per_m[1], "both")
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=3, seed=seed,
                        levels_n_rms=(3.0, 1.8), noise=0.0)
    rng = np.random.default_rng(seed)
    for rec in recs:
        for ch in rec.channels:
            s = float(np.std(ch.data))
            ch.data = ch.data + s * (0.02 * pink(rng, ch.data.size)
                                     + 0.01 * rng.standard_normal(ch.data.size))
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None
    top = tr.score(view, fx.catalogue(m))[0]
    assert (top.cand.type, top.cand.location["between"]) == ("contact", [1, 2])
    assert top.r2 > 0.2


def test_a_mass_the_stiffnesses_stood_in_for_is_asked_again_at_the_floor() -> None:
    """Blind 2-DOF case 27: 0.30 kg added at DOF 1 of a 2-DOF chain on a shake table. Round 1's
    mass change (45 % held-out gain over re-adjusting both stiffnesses) gave the round to the
    story-1 stiffness change it carried, to be asked again on top of it; that change and the
    joint re-adjustment left the residual at 0.96 x its floor, the round was never asked and
    the model stayed 1.8 x the true model's held-out error (simulated alike). Asked: within
    1.2 x of it."""
    m = table_chain((5.372873860462428, 5.390972366656358),
                    (154030.56080230296, 467037.47173231374),
                    (0.03975657752689802, 0.02077875353801136))
    truth = gen.Truth(m_add_kg={1: 0.3021691433399584})
    recs = gen.generate(m, truth, n_tests=6, seed=27, levels_n_rms=(3.0, 1.8))
    r = loop.discover(m, recs)
    # the true model simulated as discover simulated its updated model (the cubic hold)
    tm = dataclasses.replace(gen.truth_model(m, truth), outputs=m.outputs,
                             interpolation=r.model.interpolation, oversample=r.model.oversample)
    ideal = rs.error_table(tm, r.tests, r.chans, r.scales)[0]
    assert r.after.total(r.held_names) < 1.2 * ideal.total(r.held_names)
    # named at the declared scale: the mass at DOF 1, not m2, k1 and k2 all 5 % lower (was)
    assert [(e["type"], e["location"]) for e in r.effects] == [("mass_change", {"dof": 1})]
    assert r.effects[0]["parameters"]["dm_kg"]["value"] == pytest.approx(0.302, rel=0.1)
    p0, p = m.parameters(), r.model.parameters()
    assert all(p[n] == pytest.approx(p0[n], rel=0.005) for n in ("m2", "k1", "k2"))


def test_a_model_scaled_on_a_table_predicts_the_same() -> None:
    """M, C, K and the element forces times one factor: the same equation of motion under a
    ground motion (a contact, an appendage's link and a damping matrix scaled with them; the
    contact's gap and the modal ratios do not move)."""
    m = table_chain((2.0, 3.0), (2e5, 3e5), (0.02, 0.03))
    m = dataclasses.replace(with_appendage(m, 2, 0.4, 40.0, 0.02),
                            elements=(mdl.Contact(1, 2, 2e-4, 1e-4, 6e5),))
    m = dataclasses.replace(m, damping=mdl.Damping("matrix", c_n_s_per_m=(
        (60.0, -20.0, 0.0), (-20.0, 50.0, -8.0), (0.0, -8.0, 8.0))))
    ag = np.random.default_rng(1).normal(0.0, 20.0, 4096)
    a = ca.scaled(m, 1.7)
    y, ya = (sim.simulate(x, ag, 640.0) for x in (m, a))
    assert a.parameters()["e1.gap_m"] == m.parameters()["e1.gap_m"]
    assert a.parameters()["e1.kb_n_per_m"] == pytest.approx(1.7 * 6e5)
    assert np.allclose(a.damping.c_n_s_per_m, 1.7 * np.asarray(m.damping.c_n_s_per_m))
    for c in y:
        assert np.max(np.abs(ya[c] - y[c])) < 1e-9 * np.max(np.abs(y[c]))


def test_the_changes_are_named_at_the_scale_that_changes_the_fewest() -> None:
    """A mass at DOF 1 fitted as m2, k1 and k2 scaled down together: at the declared scale one
    change (m1 +6 %) and every other mass and stiffness as declared; none with a force input
    (the scale is seen), nor on one DOF (k/m: a stiffness or a mass, one change either way)."""
    start = table_chain((5.0, 5.0), (1.5e5, 4.5e5), (0.04, 0.02))
    cur = ca.scaled(start.with_params({"m1": 5.3}), 0.95)
    sc = ca.at_declared_scale(start, cur, [])
    assert sc is not None and sc.changed == ["m1"]
    p = sc.model.parameters()
    assert p["m1"] == pytest.approx(5.3, rel=1e-12)
    assert all(p[n] == pytest.approx(v, rel=1e-12) for n, v in start.parameters().items()
               if n != "m1")
    forced = dataclasses.replace(start, input=mdl.Input("force", 1, "f_n"))
    assert ca.at_declared_scale(forced, dataclasses.replace(cur, input=forced.input), []) is None
    one = table_chain((5.0,), (1.5e5,), (0.04,))
    assert ca.at_declared_scale(one, one.with_params({"k1": 1.4e5}), []) is None
