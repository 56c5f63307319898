"""discover on a best-linear declared model (issue 16, item 1): users fit their linear model to
the same kind of data, so part of the nonlinearity hides in its stiffness and damping. The
default re-adjusts the declared parameters at each candidate's location (and the modal
damping) while fitting it, against a reference with the same re-adjustment and no effect.
Without it (measured here before the change) a hardening spring was named a contact and left
0.44 of the held-out error; with it, the cubic spring is named and the held-out error is the
true model's (0.99-1.02 x)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from generated import sought, table_chain
from lanl4dof import KS, declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop
from dynval.discover import residual as rs


def test_the_best_linear_model_of_a_linear_truth_is_that_truth() -> None:
    """synth.best_linear fits k2..kn and the modal ratios, keeping the masses and k1: on a
    linear structure whose story 3 is 20 % softer and whose flexible modes are damped 3 % it
    finds them (to 1 %), and leaves k1 and the masses as declared. (Mode 1, the 0.2 Hz mode
    of k1 = 10 N/m, is far under the 20-200 Hz input: its ratio is not identified.)"""
    m0 = declared()
    zeta = (0.01, 0.03, 0.03, 0.03)
    truth = m0.with_params({"k3": 0.8 * KS[2], **{f"zeta{i}": 0.03 for i in (2, 3, 4)}})
    recs = gen.generate(m0, gen.Truth(k_scale={3: 0.8}, zeta=zeta, label="k3"), n_tests=2,
                        seed=4)
    fitted = gen.best_linear(m0, recs).parameters()
    assert fitted["zeta2"] != m0.parameters()["zeta2"]  # 0.05 declared
    for name, v in truth.parameters().items():
        if name != "zeta1":
            assert fitted[name] == pytest.approx(v, rel=0.01), name


# ("cubic", 1) passed too: dropped for CI time (more: bench_discover_blind)
@pytest.mark.parametrize(("kind", "seed"), [("cubic", 2), ("contact", 3)])
def test_best_linear_declared_model_gets_the_right_effect(kind: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    el: mdl.Element = (mdl.CubicSpring(story - 1, story, float(10 ** rng.uniform(12.3, 12.8)))
                       if kind == "cubic" else
                       mdl.Contact(story - 1, story, 0.9e-4, 1e-4, 1.925e6))
    m0 = declared()
    recs = gen.generate(m0, gen.Truth(elements=(el,), label=kind), n_tests=6, n_samples=4096,
                        seed=seed)
    mbl = gen.best_linear(m0, recs)
    assert mbl.parameters() != m0.parameters()  # the linear model did absorb something
    r = loop.discover(mbl, recs)
    assert len(sought(r.effects)) == 1, [e["label"] for e in r.effects]
    e = sought(r.effects)[0]
    want = "cubic_stiffness" if kind == "cubic" else "contact"
    assert e["type"] == want and e["location"]["between"] == [story - 1, story]
    assert e["readjusted"], "the re-adjusted declared parameters are reported"
    for v in e["readjusted"].values():
        assert abs(v["change_rel"]) < 2.0
    # within 1.3 x of the ideal: the true model driven by the measured input
    truth = dataclasses.replace(m0, elements=(el,))
    ideal, _ = rs.error_table(truth, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)


@pytest.mark.parametrize(("story", "loss", "seed"), [(3, 0.15, 1), (4, 0.08, 2)])
def test_stiffness_loss_with_the_physical_damping_fixed(story: int, loss: float,
                                                       seed: int) -> None:
    """Item 6: a real structure's damping matrix does not follow its modes when a story
    softens. The truth keeps the declared C; with the damping re-adjusted jointly the one
    stiffness change is found within 1.3 x the true model's held-out error (fixed damping
    added a spurious v|v| damper or friction, 1.10-1.62 x)."""
    m0 = declared()
    c0 = mdl.linear(m0).c
    truth = dataclasses.replace(m0.with_params({f"k{story}": KS[story - 1] * (1 - loss)}),
                                damping=mdl.Damping("matrix",
                                                    c_n_s_per_m=tuple(tuple(r) for r in c0)))
    recs = gen.generate(truth, gen.Truth(label="kloss"), n_tests=6, n_samples=4096,
                        seed=seed)
    r = loop.discover(m0, recs)
    assert [(e["type"], e["location"]["story"]) for e in r.effects] == [
        ("stiffness_change", story)]
    assert r.effects[0]["parameters"]["dk_n_per_m"]["value"] == pytest.approx(
        -loss * KS[story - 1], rel=0.05)
    ideal, _ = rs.error_table(truth, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)


def test_best_linear_spread_over_far_parameters_is_re_adjusted_jointly_at_the_end() -> None:
    """Friction to the ground at DOF 1 under a best-linear declared model: the linear fit
    spread it over every story's stiffness and every mode's damping, which the candidate's
    local re-adjustment leaves. With the effects in, all declared stiffness and damping are
    re-adjusted jointly, kept on a held-out gain (blind cases of bench/RESULTS.blind.md:
    after/ideal 1.57 -> 1.00 and 1.65 -> 1.00)."""
    m0 = declared()
    el = mdl.Friction(0, 1, 1.5, 1e-4)
    recs = gen.generate(m0, gen.Truth(elements=(el,), label="friction"), n_tests=6,
                        n_samples=4096, seed=7)
    mbl = gen.best_linear(m0, recs)
    r = loop.discover(mbl, recs)
    assert r.effects and r.effects[0]["type"] in ("friction", "stick_slip")
    assert r.effects[0]["location"]["between"] == [0, 1]
    truth = dataclasses.replace(m0, elements=(el,))
    ideal, _ = rs.error_table(truth, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.1 * ideal.total(r.held_names)
    assert any("re-adjusted jointly" in n for n in r.notes)
    # each re-adjusted declared parameter reported is the model the user gets
    final = r.model.parameters()
    readj = [(n, d) for e in r.effects for n, d in e["readjusted"].items()]
    assert readj and all(d["value"] == final[n] for n, d in readj)
    assert any("value_in_its_round" in d for _, d in readj)


@pytest.mark.parametrize(("kind", "dof", "seed"), [("mass", 2, 11), ("appendage", 3, 12)])
def test_best_linear_declared_model_gets_a_mass_or_a_mode(kind: str, dof: int,
                                                          seed: int) -> None:
    """An added mass or an unmodelled appendage under a best-linear declared model: the
    linear fit moved the story stiffnesses to absorb it, so a mass at a DOF is fitted with the
    story stiffnesses on either side re-adjusted (an appendage also with the DOF's mass).
    Measured before: blind cases of this kind were named a stiffness change, a sensor gain or
    'no effect' and left 1.5-18 x the ideal's held-out error."""
    m0 = declared()
    truth_t = (gen.Truth(m_add_kg={dof: 0.15 * m0.masses_kg[dof - 1]}, label=kind)
               if kind == "mass" else
               gen.Truth(appendages=(gen.Appendage(dof, 0.1 * m0.masses_kg[dof - 1], 45.0,
                                                   0.02),), label=kind))
    recs = gen.generate(m0, truth_t, n_tests=6, n_samples=4096, seed=seed)
    mbl = gen.best_linear(m0, recs)
    r = loop.discover(mbl, recs)
    phys = [e for e in r.effects if e["type"] != "sensor_offset"]
    assert phys, "an effect is found"
    e = phys[0]
    assert (e["type"], e["location"]["dof"]) == (f"{kind}_change" if kind == "mass" else kind,
                                                 dof)
    assert any(n.startswith("k") for n in e["readjusted"])
    tm = dataclasses.replace(gen.truth_model(m0, truth_t), outputs=m0.outputs,
                             interpolation=m0.interpolation, oversample=m0.oversample)
    ideal, _ = rs.error_table(tm, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)


def test_a_story_loss_the_best_linear_model_moved_next_door_is_found() -> None:
    """Blind 2-DOF seed 8: story 1 of a shake-table chain lost 9 %, and synth.best_linear,
    which keeps k1, moved k2 and zeta2 to make up for it (-34 %, x 3), so a stiffness change
    at story 1 alone gained 3.7 % and discover said "no effect" at 142 x the true model's
    held-out error. A round that accepts nothing fits the story changes again with the next
    stories re-adjusted: k1 and k2 back to the truth's, the truth's held-out error. On two
    DOFs story 1 with k2 re-adjusted and story 2 with k1 re-adjusted are the same model:
    either is named and the other given as a tie."""
    ks, loss = (4.94e5, 4.94e5), 0.91
    m = table_chain((6.9, 3.3), ks, (0.035, 0.022))
    recs = gen.generate(m, gen.Truth(k_scale={1: loss}), n_tests=6, seed=8,
                        levels_n_rms=(3.0, 1.8))
    bl = gen.best_linear(m, recs)
    assert bl.stiffness_n_per_m[1] < 0.9 * ks[1]  # what the declared model made of the loss
    r = loop.discover(bl, recs)
    (e,) = r.effects
    named = {(a["type"], a["location"]["story"]) for a in [e, *e["alternatives"]]}
    assert named == {("stiffness_change", 1), ("stiffness_change", 2)}
    assert r.model.stiffness_n_per_m == pytest.approx((loss * ks[0], ks[1]), rel=0.01)
    truth = m.with_params({"k1": loss * ks[0]})
    ideal, _ = rs.error_table(truth, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.1 * ideal.total(r.held_names)
