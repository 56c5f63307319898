"""discover's last look at each accepted effect with a simpler type at its place
(judge.simpler_in_place): an appendage that a mass added at its DOF explains as well (a
stiff, overdamped link far above the band) is replaced by that mass change, fitted; a real
appendage in the band stays. Generated: the truth is known exactly."""
from __future__ import annotations

from typing import Any

import pytest

from dynval import model as mdl
from dynval import synth
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import initial, judge
from dynval.discover import session as ss


def _chain() -> mdl.Model:
    return mdl.Model(masses_kg=(4.0, 3.0, 2.5), stiffness_n_per_m=(3e5, 2.4e5, 1.8e5),
                     damping=mdl.Damping("modal", (0.02, 0.02, 0.02)),
                     input=mdl.Input("force", 1, "force_N"),
                     outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in (1, 2, 3)},
                     fs_hz=640.0)


def _accepted(declared: mdl.Model, f_hz: float, mass: float, zeta: float
              ) -> tuple[mdl.Model, judge.Step, dict[str, Any]]:
    """The model with an appendage at DOF 2 accepted in round 1, its step and its entry."""
    typ = fx.by_type("appendage")
    cand = next(c for c in typ.candidates(declared) if c.location == {"dof": 2})
    cur = typ.apply(declared, cand, [f_hz, mass, zeta])
    res = ft.FitResult(cand, ["f_hz", "mass_kg", "zeta"], ["Hz", "kg", "1"], [f_hz, mass, zeta],
                       [0.1, 0.01, 0.01], cur, 1.0, 1, True)
    info = {"candidate": cand, "fit": res, "readjusted": (), "reference": "the current model",
            "evidence": 0.5, "held_gain": 0.5, "delta_bic": -100.0}
    entry = judge.effect_entry(res, info, declared, [0.0, 0.0, 0.0])
    return cur, judge.Step(declared, info, 0, 1), entry


@pytest.mark.parametrize(("truth", "replaced"), [
    (synth.Truth(m_add_kg={2: 0.45}), True),
    (synth.Truth(appendages=(synth.Appendage(2, 0.45, 60.0, 0.03),)), False)])
def test_an_appendage_a_mass_change_explains_as_well_is_replaced(
        truth: synth.Truth, replaced: bool) -> None:
    """0.45 kg added at DOF 2 (modes of the chain 25-73 Hz), found as an appendage there at
    400 Hz, zeta 2 (a mass on a stiff link): replaced by a mass change of 0.45 kg within 2 %.
    An appendage at 60 Hz in the truth, found as itself: kept."""
    declared = _chain()
    recs = synth.generate(declared, truth, n_tests=6, n_samples=4096, seed=21)
    s = ss.make_session(declared, recs, ss.Options(workers=1))
    found = (400.0, 0.45, 2.0) if replaced else (60.0, 0.45, 0.03)
    cur, step, entry = _accepted(declared, *found)
    effects = [entry]
    initial.apply(cur, s.evals, s.chans, s.scales, s.settle)
    table, _ = s.table(cur)
    notes = list(s.notes)
    m, new_table, done = judge.simpler_in_place(s, [step], cur, table, effects, "open loop")
    assert done is replaced
    if not replaced:
        assert m is cur and effects == [entry] and s.notes == notes
        return
    assert effects[0]["label"] == "mass change, DOF 2"
    assert effects[0]["parameters"]["dm_kg"]["value"] == pytest.approx(0.45, rel=0.02)
    assert m.n_dof == 3 and m.masses_kg[1] == pytest.approx(3.45, rel=0.003)
    assert new_table.total(s.held_names) <= 1.05 * table.total(s.held_names)
    assert s.notes[-1].startswith("appendage, DOF 2 (round 1) replaced by mass change, DOF 2: ")
