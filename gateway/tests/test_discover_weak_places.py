"""discover's fallback when the evidence view sees little of the residual (judge.weak_to_fit):
each nonlinear type's place is picked by one simulation per start among the view's first few
(judge.screened_places), at strengths matched to the residual (judge.energy_matched), and a
friction that never slides (its regularisation above the motion: a dashpot F / eps) is within
the friction's fitted range (effects.elements.VISCOUS_EPS)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from lanl4dof import declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import judge
from dynval.discover import residual as rs
from dynval.discover import session as ss
from dynval.discover import trace as tr
from dynval.discover.effects import elements as fel

DASHPOT = 150.0  # N s/m: the friction's F / eps in its viscous range


def test_the_energy_matched_amplitude_carries_the_residual_above_the_noise() -> None:
    e = tr.Evidence(fx.Candidate("friction", {"between": [0, 4]}, "f", True), 0.0004, -0.005)
    got = judge.energy_matched(e, 0.64)
    assert got.amp == pytest.approx(-0.005 * 40.0)  # sqrt(0.64 / 0.0004) = 40, sign kept
    assert (got.cand, got.r2) == (e.cand, e.r2)
    assert judge.energy_matched(dataclasses.replace(e, r2=0.0), 0.64).amp == pytest.approx(-5.0)


def _relative_v_rms(m: mdl.Model, u: np.ndarray, a: int, b: int) -> float:
    outs = {f"v{j}": mdl.Output("vel", j) for j in range(1, m.n_dof + 1)}
    y = mdl.simulate(dataclasses.replace(m, outputs=outs), u, float(m.fs_hz or 640.0))
    vb = y[f"v{b}"]
    return float(np.std(vb - (y[f"v{a}"] if a else 0.0)))


def _case() -> tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float], float]:
    """The 4-DOF structure with a friction to the ground at DOF 4 that never slides (eps 20 x
    the DOF's velocity RMS): the tests, their channels and scales, and the declared model's
    velocity RMS at DOF 4 (the friction's motion scale)."""
    m = declared()
    probe = gen.generate(m, gen.Truth(), n_tests=1, n_samples=2048, seed=5)[0]
    u = next(c.data for c in probe.channels if c.role == "input")
    vr = _relative_v_rms(m, u, 0, 4)
    eps = 20 * vr
    truth = gen.Truth(elements=(mdl.Friction(0, 4, DASHPOT * eps, eps),))
    recs = gen.generate(m, truth, n_tests=2, n_samples=2048, seed=5)
    tests = rs.prepare(m, recs)
    chans = rs.common_channels(m, tests)
    return m, tests, chans, rs.channel_scales(tests, chans), vr


def _friction(between: list[int], r2: float, vr: float) -> tr.Evidence:
    """Weak evidence of a friction there: read 100 x too weak (as blind sweep case 8's view
    read 165 x), at the velocity scale vr."""
    cand = fx.Candidate("friction", {"between": between}, f"friction {between}", True)
    return tr.Evidence(cand, r2, DASHPOT * 20 * vr / 100, {"v_rms": vr})


def test_a_weak_view_gets_the_place_a_simulation_puts_best() -> None:
    m, tests, chans, scales, vr = _case()
    s = ss.Session(ss.Options(workers=1), tests, chans, scales, tests, [], (20.0, 200.0), [], 0)
    none = tr.Evidence(fx.NONE.candidates(m)[0], 0.36, 0.0)  # 0.64 of it above the noise
    rd = ss.Round(1, {}, {}, [none], [], None, "")
    rd.weak = [_friction([1, 2], 0.002, vr), _friction([0, 1], 0.0015, vr),
               _friction([0, 4], 0.001, vr)]  # the view's order: the true place last
    r0 = ft.residual_vector(m, tests, chans, scales)
    assert r0 is not None
    now = float(r0 @ r0)
    picked = judge.screened_places(s, rd, m, now)
    assert [e.cand.location["between"] for e in picked] == [[0, 4]]
    # its amplitude matched (x sqrt(0.64 / 0.001) = 25.3) and scaled by its best strength
    k = picked[0].amp / rd.weak[2].amp / math.sqrt(640)
    assert min(abs(k / s - 1) for s in judge.SCREEN_STRENGTHS) < 1e-9
    # where no place screens under SCREEN_GAIN of the model without it, the view's first
    assert judge.screened_places(s, rd, m, 1e-3 * now) == [rd.weak[0]]


def test_a_friction_that_never_slides_is_fitted_as_its_dashpot() -> None:
    m, tests, chans, scales, vr = _case()
    cand = judge.with_shape(tr.Evidence(_friction([0, 4], 0.001, vr).cand, 0.001, 0.5,
                                        {"v_rms": vr}))
    ps = fx.by_type("friction").params(m, cand)
    assert ps[1].upper == pytest.approx(fel.VISCOUS_EPS * vr)
    fits = [ft.fit(m, cand, st, tests, chans, scales, 40)
            for st in fx.by_type("friction").starts(m, cand, 0.5)]
    best = min(fits, key=lambda f: f.nsse_fit)
    force, eps = best.values[:2]
    assert force / eps == pytest.approx(DASHPOT, rel=0.05)
    r0 = ft.residual_vector(m, tests, chans, scales)
    assert r0 is not None and best.nsse_fit < 0.05 * float(r0 @ r0)
