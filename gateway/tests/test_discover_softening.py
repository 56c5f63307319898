"""A softening spring is a cubic spring with k3 < 0 (issue 16, item 7: the library's effects
between any two DOFs). Loosening joints and bolted connections soften; the cubic spring was
hardening only, so a softening story was named something else. Measured before the change
(k3 refused below 0 in the fit): the 3-DOF case below was named stick-slip friction at story
2, 10.3 x the ideal's held-out error; the 4-DOF best-linear case stick-slip and two frictions
(max_effects reached), 15.0 x. After: the cubic spring with k3 < 0 at the right place, k3
within 1 %, 1.00 x the ideal in both."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from lanl4dof import declared
from test_discover_two_effects import three_dof

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.errors import ConfigError


def softening(m: mdl.Model, a: int, b: int, share: float, seed: int) -> mdl.CubicSpring:
    """A softening cubic spring between DOF a and b that takes `share` of the story's linear
    stiffness at the drift's RMS (12 N RMS input), its peak force far beyond the peak drift."""
    f = gen.band_limited_force(np.random.default_rng(seed), 8192, m.fs_hz, 12.0)
    y = mdl.simulate(dataclasses.replace(m, outputs={"a": mdl.Output("disp", a),
                                                     "b": mdl.Output("disp", b)}), f, m.fs_hz)
    x_rms = float(np.sqrt(np.mean((y["b"] - y["a"]) ** 2)))
    return mdl.CubicSpring(a, b, -share * m.stiffness_n_per_m[b - 1] / x_rms ** 2)


@pytest.mark.parametrize(("case", "a", "b", "seed"), [("3dof", 1, 2, 1), ("lanl-bl", 2, 3, 3)])
def test_a_softening_story_is_a_cubic_spring_with_k3_below_zero(case: str, a: int, b: int,
                                                                seed: int) -> None:
    m = three_dof() if case == "3dof" else declared()
    el = softening(m, a, b, 0.01, seed)
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=6, n_samples=4096, seed=seed)
    r = loop.discover(gen.best_linear(m, recs) if case.endswith("-bl") else m, recs)
    assert [(e["type"], e["location"]["between"]) for e in r.effects] == [
        ("cubic_stiffness", [a, b])]
    k3 = r.effects[0]["parameters"]["k3_n_per_m3"]["value"]
    assert k3 == pytest.approx(el.k3_n_per_m3, rel=0.1)
    ideal, _ = rs.error_table(dataclasses.replace(m, elements=(el,)), r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) < 1.1 * ideal.total(r.held_names)


def test_a_softening_spring_driven_past_its_peak_force_is_a_one_line_error() -> None:
    m = three_dof()
    el = mdl.CubicSpring(1, 2, -1e14)  # peaks at X = sqrt(k / (3 |k3|)) = 24 um
    u = gen.band_limited_force(np.random.default_rng(0), 4096, m.fs_hz, 50.0)
    with pytest.raises(ConfigError,
                       match=r"diverged .*elements\[0\] \(cubic_spring.*softening spring"):
        mdl.simulate(dataclasses.replace(m, elements=(el,)), u, m.fs_hz)
    y = mdl.simulate(dataclasses.replace(m, elements=(el,)), 1e-3 * u, m.fs_hz)
    assert all(np.isfinite(v).all() for v in y.values())  # below it: an ordinary record
    # the observer (discover's drifting models) names the element the same way
    y = mdl.simulate(m, u, m.fs_hz)
    with pytest.raises(ConfigError, match=r"observer's model ran away .*elements\[0\] "
                                          r"\(cubic_spring.*softening spring"):
        mdl.predict_observed(dataclasses.replace(m, elements=(el,)), u, y, m.fs_hz,
                             [1.0] * m.n_dof, {c: 1e-4 for c in m.outputs})


def test_the_signed_log_scale_is_continuous_through_zero_and_inverts() -> None:
    p = fx.Param("k3_n_per_m3", "N/m^3", 1e9, 1e14, signed=True)
    assert ft._to_value(p, 0.5) == 0.0
    for v in (-9e13, -3e11, -1e9, -1.0, 0.0, 2e8, 5e12, 9e13):
        assert ft._to_value(p, ft._to_z(p, v)) == pytest.approx(v, rel=1e-9, abs=1e-6)
        z, h = ft._to_z(p, v), 1e-7
        slope = (ft._to_value(p, z + h) - ft._to_value(p, z - h)) / (2 * h)
        assert ft._dv_dz(p, v) == pytest.approx(slope, rel=1e-4)
    assert ft._to_value(p, 0.0) == pytest.approx(-(1e14 - 1e9))  # the bounds
    assert ft._to_value(p, 1.0) == pytest.approx(1e14 - 1e9)


def test_the_joint_re_adjustment_keeps_a_softening_spring_and_refits_its_k3() -> None:
    """After an effect is accepted, its element parameters are re-adjusted with the declared
    ones (loop._readjust_declared). A negative k3 was given the bounds of a zero parameter,
    0..1 N/m^3, so the re-adjustment removed the spring. Blind seed 57, a softening spring
    on a best-linear 5-DOF model, had ended at 1.90 x the ideal with a spurious contact."""
    m = three_dof()
    el = softening(m, 1, 2, 0.01, 4)
    truth = dataclasses.replace(m, elements=(el,))
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=3, seed=4)
    tests = rs.prepare(truth, recs)
    chans = rs.common_channels(truth, tests)
    (p,) = ft.uncertain_params(truth, ["e1.k3_n_per_m3"])
    assert (p.lower, p.upper) == pytest.approx((3 * el.k3_n_per_m3, el.k3_n_per_m3 / 3))
    start = truth.with_params({"e1.k3_n_per_m3": 1.5 * el.k3_n_per_m3})
    cal = ft.fit(start, fx.NONE.candidates(m)[0], [], tests, chans,
                 rs.channel_scales(tests, chans), 40, ["e1.k3_n_per_m3"])
    assert cal.values[0] == pytest.approx(el.k3_n_per_m3, rel=0.01)
