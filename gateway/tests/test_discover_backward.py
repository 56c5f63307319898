"""discover's backward elimination (judge.backward): an early effect that a later one made
redundant is left out, the later effects keep their re-fitted values, and the effects list,
its indices and the notes follow. The fits and error tables are stand-ins (the real ones are
covered by the blind cases); what is tested is the decision and its bookkeeping."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from dynval import model as mdl
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import judge, session
from dynval.discover import residual as rs

HELD = ["h1", "h2"]
FIT = ["f1"]


def _model(tag: float, k1: float = 1e5) -> mdl.Model:
    """A 2-DOF model told apart by its sample rate, not one of its parameters (the stand-in
    error tables key on it)."""
    return mdl.Model(masses_kg=(1.0, 1.0), stiffness_n_per_m=(k1, 1e5),
                     damping=mdl.Damping("modal", (0.02, 0.02)),
                     input=mdl.Input("force", 1, "f"), outputs={"a1": mdl.Output("acc", 1)},
                     fs_hz=100.0 * tag)


class _Session(session.Session):
    held_error: dict[float, float]
    fit_error: dict[float, float]

    def table(self, m: mdl.Model) -> tuple[rs.ErrorTable, dict[str, dict[str, np.ndarray]]]:
        tag = (m.fs_hz or 0.0) / 100.0
        e = self.held_error[tag]
        f = self.fit_error.get(tag, 1.0)
        return rs.ErrorTable({h: {"a1": e} for h in HELD} | {h: {"a1": f} for h in FIT},
                             {h: e for h in HELD} | {h: f for h in FIT}), {}


def _session(monkeypatch: pytest.MonkeyPatch, held: dict[float, float],
             fit: dict[float, float]) -> _Session:
    s = _Session(session.Options(min_gain=0.1, workers=1), [], ["a1"], {"a1": 1.0}, [],
                 [rs.TestData.__new__(rs.TestData) for _ in HELD], (1.0, 100.0), [], 0)
    monkeypatch.setattr(session.Session, "held_names", property(lambda self: HELD))
    monkeypatch.setattr(session.Session, "fit_names", property(lambda self: FIT))
    s.held_error, s.fit_error = held, fit
    return s


def _fit(cand: fx.Candidate, model: mdl.Model, value: float) -> ft.FitResult:
    return ft.FitResult(cand, ["f_hz"], ["Hz"], [value], [0.1], model, 1.0, 1, True)


def _step(before: mdl.Model, cand: fx.Candidate, fit: ft.FitResult, entry: int) -> judge.Step:
    return judge.Step(before, {"candidate": cand, "fit": fit, "readjusted": (),
                               "reference": "the current model", "evidence": 0.5,
                               "held_gain": 0.2, "delta_bic": -10.0}, entry, entry + 1)


def _cand(dof: int) -> fx.Candidate:
    return fx.Candidate("appendage", {"dof": dof}, f"appendage, DOF {dof}", True)


@pytest.mark.parametrize(("without", "dropped"), [(0.101, True), (0.2, False)])
def test_an_effect_a_later_one_made_redundant_is_left_out(
        monkeypatch: pytest.MonkeyPatch, without: float, dropped: bool) -> None:
    base, one, both, alone = (_model(t) for t in (1.0, 2.0, 3.0, 4.0))
    # held-out error: declared 1.0, wrong place 0.5, both 0.1; the right place alone (the
    # re-fit without the first effect) `without`: within 5 % of both -> the first goes
    s = _session(monkeypatch, {1.0: 1.0, 2.0: 0.5, 3.0: 0.1, 4.0: without}, {})
    refits: list[tuple[mdl.Model, Any]] = []

    def refit(m: mdl.Model, cand: fx.Candidate, init: list[float], *a: Any,
              **k: Any) -> ft.FitResult:
        refits.append((m, init))
        return _fit(cand, alone, 34.0)

    monkeypatch.setattr(ft, "fit", refit)
    monkeypatch.setattr(ft, "scatter", lambda *a, **k: [float("nan")])
    effects: list[dict[str, Any]] = [{"type": "sensor_offset"}, {"label": "wrong"},
                                     {"label": "right"}]
    steps = [_step(base, _cand(2), _fit(_cand(2), one, 32.0), 1),
             _step(one, _cand(1), _fit(_cand(1), both, 35.0), 2)]
    cur, table = judge.backward(s, steps, both, s.table(both)[0], effects, "observer")
    assert refits == [(base, [35.0])]  # the later effect re-fitted on the model before
    if not dropped:
        assert cur is both and [e.get("label") for e in effects] == [None, "wrong", "right"]
        return
    assert cur is alone and table.total(HELD) == pytest.approx(2 * without)
    assert [e["type"] for e in effects] == ["sensor_offset", "appendage"]
    assert effects[1]["parameters"]["f_hz"]["value"] == 34.0
    assert [(st.entry, st.before) for st in steps] == [(1, base)]
    assert any("appendage, DOF 2 (round 2) left out" in n for n in s.notes)



@pytest.mark.parametrize(("fit_on_current", "dropped"), [(0.1, True), (0.3, False)])
def test_the_later_effect_is_refitted_on_the_current_declared_values_too(
        monkeypatch: pytest.MonkeyPatch, fit_on_current: float, dropped: bool) -> None:
    """A joint re-adjustment after step 0 moved k1 (cur's 1.2e5, the declared 1e5): the later
    effect is re-fitted on the model before step 0 and on it with cur's k1, and the re-fit
    with the lower fitting error decides (blind sweep 409: a cubic spring then a contact at
    one story, the contact alone found its basin only with a neighbour's stiffness back)."""
    base, one = _model(1.0), _model(2.0, 1.2e5)
    both = _model(3.0, 1.2e5)
    on_base, on_current = _model(4.0), _model(5.0, 1.2e5)
    s = _session(monkeypatch, {1.0: 1.0, 2.0: 0.5, 3.0: 0.1, 4.0: 0.3, 5.0: 0.101},
                 {4.0: 0.2, 5.0: fit_on_current})
    refits: list[float] = []

    def refit(m: mdl.Model, cand: fx.Candidate, *a: Any, **k: Any) -> ft.FitResult:
        refits.append(m.stiffness_n_per_m[0])
        return _fit(cand, on_current if m.stiffness_n_per_m[0] == 1.2e5 else on_base, 34.0)

    monkeypatch.setattr(ft, "fit", refit)
    monkeypatch.setattr(ft, "scatter", lambda *a, **k: [float("nan")])
    effects: list[dict[str, Any]] = [{"label": "stand-in"}, {"label": "right"}]
    steps = [_step(base, _cand(2), _fit(_cand(2), one, 32.0), 0),
             _step(one, _cand(1), _fit(_cand(1), both, 35.0), 1)]
    cur, _ = judge.backward(s, steps, both, s.table(both)[0], effects, "observer")
    assert refits == [1e5, 1.2e5]
    assert (cur is on_current) if dropped else (cur is both and len(effects) == 2)


def test_a_current_declared_mix_the_core_refuses_is_not_refitted() -> None:
    """The model before a step with cur's values: None where a value makes the core refuse
    it (a damping matrix's ratio fitted with the effect in), and where nothing moved."""
    before = mdl.Model(masses_kg=(1.0, 1.0), stiffness_n_per_m=(1e5, 1e5),
                       damping=mdl.Damping("matrix", c_n_s_per_m=((10.0, -5.0), (-5.0, 10.0))),
                       input=mdl.Input("force", 1, "f"), outputs={"a1": mdl.Output("acc", 1)},
                       fs_hz=512.0)
    step = _step(before, _cand(2), _fit(_cand(2), before, 32.0), 0)
    assert judge._current_declared(step, before) is None
    assert judge._current_declared(step, before.with_params({"k1": 1.2e5})) is not None
    bad = dataclasses.replace(before, damping=mdl.Damping("modal", (-0.5, 0.02)))
    assert judge._current_declared(step, bad) is None
