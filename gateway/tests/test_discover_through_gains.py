"""A nested element's fit that stopped in another basin is fitted again through the
observer's gains (judge.stuck_nested, continuation.fit_candidate). An element that makes the
response jump (a hardening spring under a swept sine) gives the output-error fit many basins:
on a best-linear declared model a cubic spring fitted from a start a few times its
coefficient stops near zero, while the observer's one-step predictions, whose gain follows the
data less at each step, keep the simulation in phase and lead it to the basin a start under
the coefficient reaches. 6-DOF blind sweep case 1: a contact won the hardening spring's story
(twice, two rounds) because the cubic's own fit ended above its reference."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import continuation, judge, session
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import residual as rs
from dynval.discover import trace as tr


def _chain() -> mdl.Model:
    return mdl.Model(masses_kg=(4.0, 3.0, 2.0), stiffness_n_per_m=(2e5, 1.5e5, 1e5),
                     damping=mdl.Damping("modal", (0.02,) * 3),
                     input=mdl.Input("ground_acc", 0, "table_mps2"),
                     outputs={f"acc{j}": mdl.Output("acc", j) for j in (1, 2, 3)},
                     fs_hz=640.0)


def test_a_cubic_fit_from_far_above_reaches_the_basin_through_the_gains() -> None:
    m = _chain()
    sweep = gen.Sweep(8.0, 200.0)
    # the hardening at the story's RMS drift: 0.4 x its linear stiffness
    lin = dataclasses.replace(m, outputs={"x1": mdl.Output("disp", 1)})
    drift = float(np.std(rs.prepare(lin, gen.generate(
        lin, gen.Truth(), n_tests=1, n_samples=4096, seed=1, levels_n_rms=(3.0,),
        excitation=sweep))[0].y["x1"]))
    k3 = 0.4 * m.stiffness_n_per_m[0] / drift ** 2
    recs = gen.generate(m, gen.Truth(elements=(mdl.CubicSpring(0, 1, k3),)), n_tests=2,
                        n_samples=4096, seed=1, levels_n_rms=(3.0, 1.8), excitation=sweep)
    declared = gen.best_linear(m, recs)
    tests = rs.prepare(declared, recs)
    chans = rs.common_channels(declared, tests)
    scales = rs.channel_scales(tests, chans)
    cand = next(dataclasses.replace(c, shape={"amp": k3})
                for c in fx.by_type("cubic_stiffness").candidates(declared)
                if c.location["between"] == [0, 1])
    names = ("k1", "k2", "m1")

    def plain(f: float) -> ft.FitResult:
        return ft.fit(declared, cand, [f * k3], tests, chans, scales, 40, names)

    below, above = plain(0.5), plain(5.0)
    through = continuation.fit_candidate(declared, cand, [5.0 * k3], names, tests, chans,
                                         scales, 40)
    assert through is not None
    assert above.nsse_fit > 2.0 * below.nsse_fit  # the plain fit from above: another basin
    assert abs(above.values[0]) < 0.1 * k3
    assert through.nsse_fit == pytest.approx(below.nsse_fit, rel=0.01)
    assert through.values[0] == pytest.approx(below.values[0], rel=0.02)


def _fit(kind: str, story: int, before: float, after: float, **shape: float
         ) -> dict[str, Any]:
    loc = {"between": [story - 1, story], "story": story}
    if kind == "contact":
        loc["side"] = "pos"
    return {"candidate": fx.Candidate(kind, loc, f"{kind} {story}", True, "", dict(shape)),
            "nsse_fit_before": before, "nsse_fit_after": after, "accepted": False}


def test_only_the_winners_nested_types_that_ended_above_their_reference_are_fitted_again(
        ) -> None:
    winner = _fit("contact", 5, 3.9, 2.2)
    fits = [winner,
            _fit("cubic_stiffness", 5, 3.9, 4.9),  # nested, above its reference: again
            _fit("cubic_stiffness", 4, 3.9, 4.9),  # another story
            _fit("vv_damping", 5, 3.9, 5.7),  # not a contact's simpler type
            _fit("cubic_stiffness", 6, 3.9, 3.5)]
    ev = [tr.Evidence(f["candidate"], 0.1, 1e13, {"sign": 1.0}) for f in fits]
    rd = session.Round(1, {}, {}, ev, fits, None, "")
    got = judge.stuck_nested(rd, winner)
    assert [(e.cand.type, e.cand.location["story"]) for e in got] == [("cubic_stiffness", 5)]
    assert got[0].shape == {"sign": 1.0, judge.THROUGH_GAINS: 1.0}
    # below its reference: not again; a fit already through the gains: not again
    rd.fits[1] = _fit("cubic_stiffness", 5, 3.9, 3.0)
    assert judge.stuck_nested(rd, winner) == []
    rd.fits[1] = _fit("cubic_stiffness", 5, 3.9, 4.9, **{judge.THROUGH_GAINS: 1.0})
    assert judge.stuck_nested(rd, winner) == []
    assert judge.stuck_nested(rd, None) == []


def _held(kind: str, story: int, gain: float, worst: float) -> dict[str, Any]:
    return {**_fit(kind, story, 1.0, 1.0), "held_gain": gain, "held_worst_test_change": worst}


def test_with_nothing_accepted_only_fits_that_crossed_branches_are_fitted_again() -> None:
    """judge.stuck_unexplained: a round that accepts nothing with its residual at twice the
    floor fits again the nonlinear elements that gained overall and made a held-out test
    worse than max_worse (a fit between the response's branches); one that gained a little
    and harmed no test found the element not needed."""
    fits = [_held("contact", 2, 0.07, 1.81),  # gained, one test 181 % worse: again
            _held("cubic_stiffness", 2, 0.21, 0.61),  # gained more: first
            _held("contact", 3, 0.09, 0.016),  # gained, harmed no test: not again
            _held("vv_damping", 2, -0.04, 1.2),  # gained nothing: not again
            _held("stiffness_change", 2, 0.5, 0.9)]  # linear: not again
    ev = [tr.Evidence(f["candidate"], 0.1, 1e6, {}) for f in fits]
    rd = session.Round(3, {"acc1": 2.08, "acc2": 1.3}, {}, ev, fits, None, "")
    got = judge.stuck_unexplained(rd, None, max_worse=0.05)
    assert sorted((e.cand.type, e.cand.location["story"]) for e in got) == [
        ("contact", 2), ("cubic_stiffness", 2)]
    assert all(e.shape[judge.THROUGH_GAINS] == 1.0 for e in got)
    # the worse test within max_worse: none again; under twice the floor or with a winner: none
    assert judge.stuck_unexplained(rd, None, max_worse=2.0) == []
    rd.ratio = {"acc1": 1.99, "acc2": 1.3}
    assert judge.stuck_unexplained(rd, None, max_worse=0.05) == []
    rd.ratio = {"acc1": 2.08}
    assert judge.stuck_unexplained(rd, fits[0], max_worse=0.05) == []
