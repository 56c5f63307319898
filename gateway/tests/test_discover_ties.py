"""Effects the tests do not tell apart (judge.alternatives): the round's other accepted fits
whose held-out error is within half of min_gain of the winner's, of another type or place and
not nested with it, are named beside the effect (an appendage under the input band reads as a
spring to the ground; a constant force on a free chain acts at any DOF). The fit records are
stand-ins; the fits behind them are covered by the discover cases."""
from __future__ import annotations

import math
from typing import Any

import pytest

from dynval.discover import effects as fx
from dynval.discover import judge, report


def _fit(kind: str, where: dict[str, Any], err: float, accepted: bool = True
         ) -> dict[str, Any]:
    label = f"{kind} " + ",".join(f"{k} {v}" for k, v in where.items())
    return {"candidate": fx.Candidate(kind, where, label, True), "nsse_held_after": err,
            "accepted": accepted}


def test_ties_are_accepted_fits_within_half_the_minimum_gain() -> None:
    win = _fit("stiffness_change", {"story": 1, "between": [0, 1]}, 2.0)
    fits = [win,
            _fit("appendage", {"dof": 1}, 2.09),  # +4.5 %: tied (limit +5 %)
            _fit("stiffness_change", {"story": 2, "between": [1, 2]}, 2.02),  # another place
            _fit("friction", {"between": [0, 1]}, 2.11),  # +5.5 %: told apart
            _fit("contact", {"between": [0, 1], "side": "pos"}, 2.01, accepted=False),
            _fit("stiffness_change", {"story": 1, "between": [0, 1]}, 2.0)]  # the winner again
    alt = judge.alternatives(win, fits, min_gain=0.10)
    assert [a["label"] for a in alt] == ["stiffness_change story 2,between [1, 2]",
                                         "appendage dof 1"]
    assert alt[0]["held_out_rmse_ratio"] == pytest.approx(math.sqrt(1.01))
    assert alt[1]["held_out_rmse_ratio"] == pytest.approx(math.sqrt(1.045))
    assert alt[1]["location"] == {"dof": 1} and alt[1]["type"] == "appendage"


def test_a_special_case_of_the_winner_is_not_a_tie() -> None:
    # a mass change is an appendage far above the band (EffectType.simpler): simplest_nested
    # already chose between them, and the same effect with an offset is the same effect
    win = _fit("appendage", {"dof": 2}, 1.0)
    fits = [_fit("mass_change", {"dof": 2}, 1.01), _fit("mass_change", {"dof": 3}, 1.02),
            _fit("friction", {"between": [0, 2], "offset": True}, 1.0)]
    assert [a["label"] for a in judge.alternatives(win, fits, 0.10)] == [
        "friction between [0, 2],offset True", "mass_change dof 3"]  # best first
    win = _fit("friction", {"between": [0, 2], "offset": True}, 1.0)
    assert judge.alternatives(win, [_fit("friction", {"between": [0, 2]}, 1.0)], 0.10) == []


def test_the_verdict_names_the_ties() -> None:
    alt = [{"label": f"appendage, DOF {d}"} for d in range(1, 6)]
    eff = {"label": "stiffness change, story 1"}
    assert report._verdict([{**eff, "alternatives": []}], {}, None) == (
        "the model lacks: stiffness change, story 1")
    assert report._verdict([{**eff, "alternatives": alt[:2]}], {}, None) == (
        "the model lacks: stiffness change, story 1 (or, as well supported by these tests: "
        "appendage, DOF 1 or appendage, DOF 2)")
    assert report._verdict([{**eff, "alternatives": alt}], {}, None).endswith(
        "appendage, DOF 1 or appendage, DOF 2 or appendage, DOF 3 and 2 more)")
