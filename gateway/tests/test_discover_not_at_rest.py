"""Records that do not start at rest (issue 16, item 3): segments cut from the middle of a
longer run. Assuming rest left 7-10x the noise floor on a right model and 9x after the right
contact (the start-up transient); with the initial state estimated both end within 1.35x,
and records that do start at rest are left alone. A fit that moves the modes estimates each
record's initial state again under every model it tries (TestData.free_start)."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from generated import table_chain
from lanl4dof import KS, declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import initial, loop
from dynval.discover import residual as rs
from dynval.discover.session import Options, make_session, settle_samples
from dynval.io.recording import Recording
from dynval.model.structure import with_appendage

N = 8192


def second_halves(runs: list[Recording], n: int) -> list[Recording]:
    """Each run from sample n on: the structure is moving when each record starts."""
    return [Recording(r.name, r.fs_hz, [dataclasses.replace(
        c, data=np.ascontiguousarray(c.data[n:])) for c in r.channels]) for r in runs]


def cut_from_a_run(truth: gen.Truth, seed: int) -> list[Recording]:
    """The second half of longer runs of the 4-DOF structure."""
    return second_halves(gen.generate(declared(), truth, n_tests=4, n_samples=2 * N,
                                      seed=seed), N)


@pytest.mark.parametrize("with_contact", [False, True])
def test_records_cut_from_a_run_are_not_taken_for_an_effect(with_contact: bool) -> None:
    els = (mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),) if with_contact else ()
    recs = cut_from_a_run(gen.Truth(elements=els, label="cut"), seed=5)
    r = loop.discover(declared(), recs)
    assert sum("does not start at rest" in n for n in r.notes) == len(recs)
    assert [e["type"] for e in r.effects] == (["contact"] if with_contact else [])
    held = r.after.pooled(r.held_names, r.chans)
    assert all(held[c] < 1.5 * r.noise[c] for c in r.chans), (held, r.noise)


def test_records_that_start_at_rest_stay_at_rest() -> None:
    recs = gen.generate(declared(), gen.Truth(label="rest"), n_tests=4, seed=6)
    r = loop.discover(declared(), recs)
    assert not any("does not start at rest" in n for n in r.notes)
    assert all(t.start is None for t in r.tests)


def test_a_fit_that_moves_the_damping_moves_the_records_free_motion_with_it() -> None:
    """A 3-DOF table swept from 6 Hz, records cut from a run, the declared first mode's
    damping twice the truth's. Held at the declared model's initial states, the fit kept
    zeta1 at 1.30 x the truth (measured; 1.91 x when the free motion itself was the declared
    model's, decaying at 6 %, not the fitted model's: residual.start_state); with the states
    estimated under each model (variable projection) zeta1 within 5 % and the held-out error
    within 1 % of the true model's."""
    truth = table_chain((3.0, 7.0, 2.5), (2e5, 2e5, 2.1e5), (0.03, 0.02, 0.02))
    n = 2048
    runs = gen.generate(truth, gen.Truth(), n_tests=4, n_samples=2 * n, seed=1,
                        levels_n_rms=(3.0, 1.8), excitation=gen.Sweep(6.0, 200.0))
    recs = second_halves(runs, n)
    dec = truth.with_params({"zeta1": 0.06})
    s = make_session(dec, recs, Options())
    assert len(initial.apply(dec, s.evals, s.chans, s.scales, s.settle)) == len(recs)
    names = ("k1", "k2", "k3", "zeta1", "zeta2", "zeta3")

    def held(m: mdl.Model) -> float:  # each model with its own initial states
        initial.apply(m, s.evals, s.chans, s.scales, s.settle)
        return s.table(m)[0].total(s.held_names)

    none = fx.NONE.candidates(dec)[0]
    fixed = ft.fit(dec, none, [], s.fit_t, s.chans, s.scales, 40, names).model
    free = ft.fit(dec, none, [], loop._free_starts(s), s.chans, s.scales, 40, names).model
    ideal = held(truth)
    # the premise, and the fixed states' fit moving the transient with zeta1: 1.30 x
    assert 1.2 * 0.03 < fixed.parameters()["zeta1"] < 1.5 * 0.03
    assert free.parameters()["zeta1"] == pytest.approx(0.03, rel=0.05)
    assert held(free) < 1.01 * ideal < held(fixed)


def stuck_chain() -> tuple[mdl.Model, gen.Truth, list[Recording]]:
    """A 4-DOF chain whose top DOF has friction to the ground (0.3 N: stuck for much of the
    sweep's high end), its records cut from swept runs."""
    chain = mdl.Model(masses_kg=(3.3, 7.9, 7.9, 7.1),
                      stiffness_n_per_m=(2.9e5, 1.6e5, 2.4e5, 2.8e5),
                      damping=mdl.Damping("modal", (0.016, 0.016, 0.023, 0.035)),
                      input=mdl.Input("force", 1, "force_N"),
                      outputs={f"acc{j}_mps2": mdl.Output("acc", j) for j in range(1, 5)},
                      fs_hz=640.0)
    truth = gen.Truth(elements=(mdl.Friction(0, 4, 0.3, 1e-4),), label="cut")
    runs = gen.generate(chain, truth, n_tests=4, n_samples=2 * N, seed=5, fs_hz=640.0,
                        excitation=gen.Sweep(100.0, 250.0, "linear"))
    return chain, truth, second_halves(runs, N)


def test_an_appendage_is_judged_at_its_hosts_states_estimated_under_it() -> None:
    """Records of the 4-DOF structure with an appendage at DOF 2 (0.3 kg, 20 Hz) cut from a
    run, the declared model without it. The true model judged at the declared model's
    initial states read 1.27 x its held-out error at its own (measured); its hosts' states
    estimated under it (the appendage's DOF starting where its host does: no state of its
    own, so no free parameters on the held-out tests) within 1 % of that."""
    recs = cut_from_a_run(gen.Truth(appendages=(gen.Appendage(2, 0.3, 20.0, 0.02),)), seed=3)
    dec = declared()
    truth = with_appendage(dec, 2, 0.3, 20.0, 0.02)
    s = make_session(dec, recs, Options())
    assert len(initial.apply(dec, s.evals, s.chans, s.scales, s.settle)) == len(recs)
    with initial.kept(s.evals):
        kept = s.table(truth)[0].total(s.held_names)  # the declared model's states
    with initial.starts_under(truth, s.evals, s.chans, s.scales):
        assert all(t.start_x0 is not None and t.start_x0.size == 2 * dec.n_dof
                   for t in s.evals)
        hosts = s.table(truth)[0].total(s.held_names)
    initial.apply(truth, s.evals, s.chans, s.scales, s.settle)
    own = s.table(truth)[0].total(s.held_names)  # every DOF's state its own
    assert hosts < 1.01 * own < 0.85 * kept


def test_a_friction_element_stuck_where_the_cut_left_it_starts_there() -> None:
    """Records cut from a swept run of a 4-DOF chain whose top DOF has friction to the
    ground (0.3 N: stuck for much of the sweep's high end). The linear part's estimate of the
    initial state misses the offsets the friction holds its DOF at; refined through the
    elements (initial.refined, the core's dv_obs_set_state) the true model's held-out error
    on DOF 2-4 falls by 1.9-3 x (measured: 0.0059, 0.0028, 0.00074 -> 0.0032, 0.0011,
    0.00024 m/s^2), to where a model driven from rest on the run's first half is."""
    chain, truth, recs = stuck_chain()
    tm = dataclasses.replace(gen.truth_model(chain, truth), outputs=chain.outputs,
                             interpolation=chain.interpolation, oversample=chain.oversample)
    s = make_session(tm, recs, Options())
    assert len(initial.apply(tm, s.evals, s.chans, s.scales, s.settle)) == len(recs)
    refined = s.table(tm)[0].pooled(s.held_names, s.chans)
    for t in s.evals:  # the linear part's free motion added instead
        t.start_x0 = None
    linear = s.table(tm)[0].pooled(s.held_names, s.chans)
    for c in ("acc2_mps2", "acc3_mps2", "acc4_mps2"):
        assert refined[c] < 0.6 * linear[c], (c, refined[c], linear[c])


def test_the_joint_readjustment_is_judged_on_the_starts_it_is_kept_with() -> None:
    """Records cut from a run of a structure with a two-sided contact; the model has the
    contact and its stiffnesses 0.2-0.3 % off (a best-linear fit's spread): the joint
    re-adjustment is fitted with free starts (the linear part's free motion) and judged on the
    table, each record started through the contact. Its fitting error must come from that
    table too: the fit's own is not comparable and refused a re-adjustment that lowers the
    held-out error (measured: held-out 0.0385 -> 0.0107; fitting error 0.042 -> 0.0098 by
    the table, 0.077 by the fit's own)."""
    contact = mdl.Contact(1, 2, 0.6e-4, 1e-4, 1.925e6, "both")
    recs = cut_from_a_run(gen.Truth(elements=(contact,), label="cut"), seed=7)
    off = declared().with_params({"k2": 1.003 * KS[1], "k3": 0.997 * KS[2], "k4": 1.002 * KS[3]})
    off = dataclasses.replace(off, elements=(contact,))
    s = make_session(off, recs, Options())
    initial.apply(off, s.evals, s.chans, s.scales, s.settle)
    before = s.table(off)[0]
    kept = loop._readjust_declared(s, off, before)
    assert kept is not None
    after = kept[1].total(s.held_names)
    assert after < 0.5 * before.total(s.held_names), (after, before.total(s.held_names))
    # the stories away from the contact back to the truth (k2 trades with the contact's
    # own stiffness)
    k = kept[0].stiffness_n_per_m[2:]
    assert np.allclose(k, KS[2:], rtol=0.001), k


def test_a_prediction_that_overflowed_is_left_to_its_caller() -> None:
    """A free start on a non-finite prediction (a diverging element) gives the prediction
    back as it is, for residual_vector to refuse (no least squares on it: NaN states)."""
    from dynval.discover import residual as rs
    m = declared()
    recs = gen.generate(m, gen.Truth(label="rest"), n_tests=1, n_samples=256, seed=2)
    t = rs.prepare(m, recs)[0]
    p = {c: np.full(t.u.size, np.inf) for c in m.outputs}
    out = rs._with_free_start(m, t, p, {c: 1.0 for c in m.outputs})
    assert all(np.all(np.isinf(out[c])) for c in m.outputs)


def table_sweep_with_a_contact(seed: int) -> tuple[mdl.Model, list[Recording]]:
    """A 5-DOF chain on a shake table swept from 13 Hz (its 0.25 s ramp: the records start
    at rest), a contact across story 4 that the low start of the sweep closes most (blind
    swept sine 4), and the true model."""
    m = table_chain((2.83, 4.28, 5.72, 7.02, 2.75), (3.46e5, 2.46e5, 4.39e5, 3.75e5, 2.25e5),
                    (0.011, 0.025, 0.020, 0.039, 0.033))
    truth = gen.Truth(elements=(mdl.Contact(3, 4, 1.04e-4, 5e-5, 1.5e6, side="pos"),),
                      label="sweep")
    recs = gen.generate(m, truth, n_tests=6, n_samples=N, seed=seed, fs_hz=640.0,
                        levels_n_rms=(3.0, 1.8), excitation=gen.Sweep(13.0, 221.0, "linear"))
    return dataclasses.replace(gen.truth_model(m, truth), outputs=m.outputs), recs


@pytest.mark.parametrize("seed", [4, 5])
def test_a_sweep_that_starts_at_rest_stays_at_rest(seed: int) -> None:
    """Under the true model a free motion fitted 32-52 % of the residual over the first
    0.3 s of every record (the contact's residual is largest where the sweep starts low), and
    every record was taken for one cut from a run (blind swept sine 4: a spurious appendage
    followed). Every output is quiet over its first quarter period: at rest."""
    tm, recs = table_sweep_with_a_contact(seed)
    s = make_session(tm, recs, Options())
    assert all(initial.quiet_start(tm, t, s.chans) for t in s.evals)
    assert all(initial.estimate(tm, t, s.chans, s.scales, s.settle) is None for t in s.evals)
    cut = make_session(tm, second_halves(recs, N // 2), Options())
    assert not any(initial.quiet_start(tm, t, cut.chans) for t in cut.evals)


def three_dof() -> mdl.Model:
    """A 3-DOF chain forced at its middle."""
    return mdl.Model(masses_kg=(3.0, 2.0, 1.5), stiffness_n_per_m=(2.5e5, 2.0e5, 1.5e5),
                     damping=mdl.Damping("modal", (0.02, 0.015, 0.02)),
                     input=mdl.Input("force", 2, "force_N"),
                     outputs={f"acc{j}": mdl.Output("acc", j) for j in (1, 2, 3)},
                     fs_hz=640.0)


def stepped_sine(m: mdl.Model, truth: gen.Truth, levels: tuple[float, float]
                 ) -> list[Recording]:
    """A stepped-sine test: a record in periodic steady state (2 s after switch-on) at each of
    five frequencies beside the flexible modes, at two levels."""
    fr = [f for f in mdl.natural_frequencies(m) if f > 1.0]
    freqs = [0.92 * fr[0], 1.04 * fr[0], 0.96 * fr[1], 1.05 * fr[1], 0.97 * fr[-1]]
    recs = []
    for i, f in enumerate(freqs):
        for j, level in enumerate(levels):
            r = gen.generate(m, truth, n_tests=1, n_samples=4096, seed=10 * i + j,
                             levels_n_rms=(level,), excitation=gen.Sine(float(f)))[0]
            recs.append(Recording(f"sine_{f:.0f}Hz_{('high', 'low')[j]}", r.fs_hz, r.channels))
    return recs


@pytest.mark.parametrize(("model", "element", "levels", "seen", "found"), [
    (declared, mdl.CubicSpring(2, 3, 5e12), (30.0, 15.0), (), ("cubic_stiffness", [2, 3])),
    (three_dof, mdl.Contact(1, 2, 4e-5, 2e-5, 1.5e6), (20.0, 8.0), (), ("contact", [1, 2])),
    (three_dof, mdl.Contact(1, 2, 4e-5, 2e-5, 1.5e6), (20.0, 8.0), (1, 3),
     ("contact", [1, 2])),
    (three_dof, mdl.StickSlip(1, 2, 2.0, 6e-5), (20.0, 8.0), (), ("stick_slip", [1, 2])),
    (three_dof, mdl.VVDamper(1, 2, 900.0), (20.0, 8.0), (), ("vv_damping", [1, 2])),
])
def test_a_stepped_sine_in_steady_state(model: Any, element: mdl.Element,
                                        levels: tuple[float, float], seen: tuple[int, ...],
                                        found: tuple[str, list[int]]) -> None:
    """Every record starts in steady state (issue 16, item 3: periodic steady state): the
    right element, and a held-out error within 1.3 x the true model's at its own initial
    states. The contact's open-loop fit stopped in another basin (7 % gained, one test 181 %
    worse: "no effect" at 9 x the true model's error); fitted again through the observer's
    gains (judge.stuck_unexplained) 0.85 x. Seen at DOF 1 and 3 only (``seen``), its
    evidence read it 12 x too soft at a gap 12 x too wide, and only a grid start in that
    round (Contact.stuck_starts) reaches it ("no effect" at 12 x before); a 0.02 N force
    offset that gained on one held-out test alone is refused (judge.replicated_gain). Dealt
    by level alone, both records beside the third mode were held out: the stick-slip joint's
    fit (within 3 % of its force) was refused at 130 x the true model's held-out error and
    "no effect" said; tests at several frequencies are now paired (session.twins). In that
    split a stiffness change at the contact's story wins round 1 for the contact seen at DOF
    1 and 3, and only its rivals at every side of that story, from the grid too, find it.
    The true model is simulated as declared: at the samples held linearly (truth_model's
    own) its error was 17 x higher and hid the stick-slip joint's 1.83 x, its fit having
    re-adjusted the declared parameters to the fitting tests (now 1.03 x, as declared:
    Judge.as_declared)."""
    m = model()
    if seen:
        m = dataclasses.replace(m, outputs={f"acc{j}": mdl.Output("acc", j) for j in seen})
    truth = gen.Truth(elements=(element,), label="sine")
    r = loop.discover(m, stepped_sine(m, truth, levels))
    assert [(e["type"], e["location"]["between"]) for e in r.effects] == [found]
    strength = {"contact": "kb_n_per_m", "cubic_stiffness": "k3_n_per_m3",
                "stick_slip": "force_n", "vv_damping": "c2_n_s2_per_m2"}[found[0]]
    got = r.effects[0]["parameters"][strength]["value"]
    assert got == pytest.approx(getattr(element, strength), rel=0.25)
    tm = dataclasses.replace(gen.truth_model(m, truth), outputs=m.outputs,  # as declared,
                             interpolation=m.interpolation, oversample=m.oversample)  # not foh
    initial.apply(tm, r.tests, r.chans, r.scales,
                  settle_samples(r.modes_hz, r.band_hz, r.tests[0].fs_hz))
    ideal = rs.error_table(tm, r.tests, r.chans, r.scales)[0].total(r.held_names)
    assert r.after.total(r.held_names) < 1.3 * ideal, (r.after.total(r.held_names), ideal)



def test_with_uncertain_parameters_the_winner_moves_only_those() -> None:
    """The stick-slip joint of the stepped-sine test with ``--uncertain k2``: the round's
    winner fitted again with the declared parameters as they are keeps k2 re-adjusted (the
    user asked for it) and nothing else, judged against the model with k2 calibrated
    (Judge.as_declared); its held-out error within 1.1 x the true model's as declared
    (measured 0.99 x)."""
    m = three_dof()
    truth = gen.Truth(elements=(mdl.StickSlip(1, 2, 2.0, 6e-5),), label="sine")
    r = loop.discover(m, stepped_sine(m, truth, (20.0, 8.0)),
                      loop.Options(uncertain=("k2",), workers=1))
    assert [(e["type"], list(e["readjusted"])) for e in r.effects] == [("stick_slip", ["k2"])]
    tm = dataclasses.replace(gen.truth_model(m, truth), outputs=m.outputs,
                             interpolation=m.interpolation, oversample=m.oversample)
    initial.apply(tm, r.tests, r.chans, r.scales,
                  settle_samples(r.modes_hz, r.band_hz, r.tests[0].fs_hz))
    ideal = rs.error_table(tm, r.tests, r.chans, r.scales)[0].total(r.held_names)
    assert r.after.total(r.held_names) < 1.1 * ideal, (r.after.total(r.held_names), ideal)

@pytest.mark.parametrize("off", [(1.0, 0.5, 0.7), (1.05, 2.0, 1.4)])
def test_an_elements_parameters_fitted_again_at_each_models_own_starts(
        off: tuple[float, float, float]) -> None:
    """Records cut from a run of the 4-DOF structure with a contact at story 4; the model has
    the contact with its gap, delta and kb off by the factors ``off`` and the records'
    initial states estimated under it (where an accepted candidate's fit leaves them: blind
    case 309, 1.38 x the ideal). Fitted again with each model's own states
    (ft.at_own_starts) the fitting and held-out errors reach the true model's (measured:
    0.00142 and 0.0014 from 0.00156-0.00207 and 0.00152-0.00165), the gap within 1 % (delta
    and kb trade along a valley: 0.25-1.3 x)."""
    contact = mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6)
    recs = cut_from_a_run(gen.Truth(elements=(contact,), label="cut"), seed=5)
    true_m = dataclasses.replace(declared(), elements=(contact,))
    names = ("e1.gap_m", "e1.delta_m", "e1.kb_n_per_m")
    pt = true_m.parameters()
    wrong = true_m.with_params({n: pt[n] * f for n, f in zip(names, off, strict=True)})
    s = make_session(wrong, recs, Options())

    def errors(m: mdl.Model) -> tuple[float, float]:  # each model at its own states
        initial.apply(m, s.evals, s.chans, s.scales, s.settle, quiet=True)
        tab = s.table(m)[0]
        return tab.total(s.fit_names), tab.total(s.held_names)

    fit_true, held_true = errors(true_m)
    fit_wrong, held_wrong = errors(wrong)
    assert fit_wrong > 1.08 * fit_true and held_wrong > 1.08 * held_true
    got = ft.at_own_starts(wrong, names, s.fit_t, s.chans, s.scales, s.settle)
    assert got is not None
    fit_new, held_new = errors(got[0])
    assert got[1] == pytest.approx(fit_new, rel=1e-4)
    assert got[2] == pytest.approx(fit_wrong, rel=1e-4)
    assert fit_new < 1.01 * fit_true and held_new < 1.01 * held_true, (fit_new, held_new)
    assert got[0].parameters()["e1.gap_m"] == pytest.approx(pt["e1.gap_m"], rel=0.01)


@pytest.mark.parametrize("off", [(1.0, 1.01, 1.3), (0.995, 1.0, 1.0)])
def test_the_declared_parameters_an_element_readjusted_fitted_again_with_it(
        off: tuple[float, float, float]) -> None:
    """As above (the contact's gap, delta and kb off by 1.05, 2 and 1.4), and k4, m4 and
    zeta2, which the contact's fit re-adjusted, off by ``off`` (traded with the element at
    the old states: blind sweep case 8, 3.1 x the ideal). The element's parameters alone
    cannot make up for them (measured: fitting error 29 x and 5 x the true model's); with
    the re-adjusted ones fitted again too (``readjusted``) the errors reach the true model's
    and the declared parameters come back within 0.5 % (measured: 1.000-1.004 x)."""
    contact = mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6)
    recs = cut_from_a_run(gen.Truth(elements=(contact,), label="cut"), seed=5)
    true_m = dataclasses.replace(declared(), elements=(contact,))
    names, decl = ("e1.gap_m", "e1.delta_m", "e1.kb_n_per_m"), ("k4", "m4", "zeta2")
    pt = true_m.parameters()
    wrong = true_m.with_params({n: pt[n] * f for n, f in zip(
        names + decl, (1.05, 2.0, 1.4, *off), strict=True)})
    s = make_session(wrong, recs, Options())

    def fitting_error(m: mdl.Model) -> float:  # m at its own states
        initial.apply(m, s.evals, s.chans, s.scales, s.settle, quiet=True)
        return s.table(m)[0].total(s.fit_names)

    fit_true = fitting_error(true_m)
    fitting_error(wrong)
    alone = ft.at_own_starts(wrong, names, s.fit_t, s.chans, s.scales, s.settle)
    assert alone is None or alone[1] > 3 * fit_true, (alone and alone[1], fit_true)
    got = ft.at_own_starts(wrong, names, s.fit_t, s.chans, s.scales, s.settle,
                           ft.uncertain_params(wrong, decl))
    assert got is not None
    assert got[1] < 1.01 * fit_true, (got[1], fit_true)
    p = got[0].parameters()
    assert p["e1.gap_m"] == pytest.approx(pt["e1.gap_m"], rel=0.01)
    assert all(p[n] == pytest.approx(pt[n], rel=0.005) for n in decl), {n: p[n] / pt[n]
                                                                        for n in decl}


def test_no_refit_at_own_starts_for_records_at_rest() -> None:
    contact = mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6)
    recs = gen.generate(declared(), gen.Truth(elements=(contact,)), n_tests=4, seed=6)
    m = dataclasses.replace(declared(), elements=(contact,))
    s = make_session(m, recs, Options())
    initial.apply(m, s.evals, s.chans, s.scales, s.settle)
    assert ft.at_own_starts(m, ("e1.gap_m",), s.fit_t, s.chans, s.scales, s.settle) is None


@pytest.mark.parametrize("seed", [1, 2])
def test_records_found_at_rest_under_a_wrong_model_are_asked_again_under_each(
        seed: int) -> None:
    """A 3-DOF chain, records cut from a run, story 1 11.5 % softer and DOF 2 0.45 kg heavier
    than declared: under the declared model the start-up transient is lost in the model's
    error and every record is found at rest; the true model judged at rest leaves 5-7 x its
    held-out error with its own states (measured 0.0282 and 0.0412 against 0.0055). A
    candidate is judged at the states it puts the records in: the true model's error with
    them is its own (blind two-effect case 415, these two changes: 57.8 x the ideal when the
    records stayed at rest, the right changes at 1.00 x when asked again)."""
    dec = mdl.Model(masses_kg=(3.6, 5.0, 6.1), stiffness_n_per_m=(2.7e5, 2.1e5, 1.7e5),
                    damping=mdl.Damping("modal", (0.013, 0.03, 0.013)),
                    input=mdl.Input("force", 1, "force_N"),
                    outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in (1, 3)},
                    fs_hz=640.0)
    truth = gen.Truth(k_scale={1: 0.885}, m_add_kg={2: 0.45})
    recs = second_halves(gen.generate(dec, truth, n_tests=6, n_samples=2 * N, seed=seed), N)
    s = make_session(dec, recs, Options())
    assert initial.apply(dec, s.evals, s.chans, s.scales, s.settle) == []  # the premise
    tm = dataclasses.replace(gen.truth_model(dec, truth), outputs=dec.outputs)
    at_rest = s.table(tm)[0].total(s.held_names)
    with initial.starts_under(tm, s.evals, s.chans, s.scales):
        asked = s.table(tm)[0].total(s.held_names)
    assert all(t.start is None for t in s.evals)  # back as they were
    assert len(initial.apply(tm, s.evals, s.chans, s.scales, s.settle, quiet=True)) == len(recs)
    own = s.table(tm)[0].total(s.held_names)
    assert at_rest > 4 * own
    assert asked == pytest.approx(own, rel=1e-9)


def test_the_head_bound_skips_only_records_estimate_finds_at_rest(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """initial._head_bound, the first settling window's own least-squares free motion, is an
    upper bound of the share estimate's whole-record state explains there: a record it puts
    under MIN_REDUCTION is one estimate finds at rest anyway (records cut from a run and
    records at rest, the declared 4-DOF model)."""
    cut = cut_from_a_run(gen.Truth(label="cut"), seed=5)
    rest = gen.generate(declared(), gen.Truth(label="rest"), n_tests=4, seed=6)
    m = declared()
    s = make_session(m, [*cut, *rest], Options())
    bounds = {t.name: initial._head_bound(m, t, s.chans, s.scales, s.settle) for t in s.evals}
    monkeypatch.setattr(initial, "_head_bound", lambda *a: 1.0)
    full = {t.name: initial.estimate(m, t, s.chans, s.scales, s.settle) for t in s.evals}
    found = {n: st.reduction for n, st in full.items() if st is not None}
    assert found and len(found) < len(full)  # both kinds are there
    assert all(bounds[n] >= r - 1e-9 for n, r in found.items()), (bounds, found)
    assert any(b < initial.MIN_REDUCTION for b in bounds.values())
    assert all(full[n] is None for n, b in bounds.items() if b < initial.MIN_REDUCTION)


def test_a_lightly_damped_transient_that_rings_on_is_a_start_not_an_effect() -> None:
    """A shake table's sweep cut from a run where it has passed the first modes, read by a
    quiet DAQ (noise 0.01 % of each channel's RMS): the first mode (1.1 % damping) rings
    through the record. From rest the model's start-up transient is thousands of times what
    is left of it later, yet a free motion still explains half of that small rest. Taken as
    shares (reduction against twice the later window's share) half of these records were
    found at rest (blind sweep case 20: the true model read 400-700 x the noise floor); as
    energies every record starts where the run left it."""
    m = table_chain((2.45, 6.24, 2.53, 4.60, 4.94), (3.40e5, 3.62e5, 2.90e5, 4.56e5, 4.12e5),
                    (0.011, 0.037, 0.028, 0.032, 0.032))
    runs = gen.generate(m, gen.Truth(label="cut"), n_tests=6, n_samples=2 * N, seed=20,
                        fs_hz=640.0, levels_n_rms=(3.0, 1.8), noise=1e-4,
                        excitation=gen.Sweep(9.3, 213.7, "linear"))
    s = make_session(m, second_halves(runs, N), Options())
    starts = [initial.estimate(m, t, s.chans, s.scales, s.settle) for t in s.evals]
    assert all(st is not None and st.reduction > 0.97 for st in starts), starts
    assert len(initial.apply(m, s.evals, s.chans, s.scales, s.settle, quiet=True)) == 6
