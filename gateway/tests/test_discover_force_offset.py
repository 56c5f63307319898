"""Force offsets (issue 16, item 5): a constant force at a DOF is an effect of the library (the
core's constant_force element). On a positioning stage (a carriage on a guide: a rigid-body
mode) with Coulomb friction and a drive's force offset, the offset leaves no mean in the
residual (the friction balances it) and friction alone fits badly (held-out gain 0.35, a
spurious damping change won the round before): the two are fitted together. On a free
carriage a force offset alone shifts every accelerometer's mean alike; it must be named as
one force, not as offsets of each sensor. On a grounded structure with displacement sensors
a force transducer's bias at the input is a static deflection on every channel."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_discover_drift import carriage

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop, report
from dynval.discover import residual as rs


def _ideal_ratio(r: loop.DiscoverResult, truth: mdl.Model) -> float:
    """Held-out error after / the true model's (driven by the measured input)."""
    ideal, _ = rs.error_table(truth, r.tests, r.chans, r.scales)
    return r.after.total(r.held_names) / ideal.total(r.held_names)


# (3, 0.4) passed too: dropped for CI time
@pytest.mark.parametrize(("seed", "offset"), [(2, -0.6)])
def test_friction_and_a_force_offset_on_a_positioning_stage(seed: int, offset: float) -> None:
    force = float(np.random.default_rng(seed).uniform(1.0, 2.0))
    els = (mdl.Friction(0, 1, force, 1e-3), mdl.ConstantForce(0, 1, offset))
    truth = dataclasses.replace(carriage(), elements=els)
    r = loop.discover(carriage(), gen.generate(carriage(), gen.Truth(elements=els), n_tests=4,
                                               n_samples=4096, seed=seed))
    assert r.prediction == "observer"
    assert [(e["type"], e["location"]["between"], e["location"].get("offset"))
            for e in r.effects] == [("friction", [0, 1], True)]
    p = r.effects[0]["parameters"]
    assert p["force_n"]["value"] == pytest.approx(force, rel=0.03)  # see test_discover_drift
    assert p["offset_force_n"]["value"] == pytest.approx(offset, rel=0.03)
    assert _ideal_ratio(r, truth) < 1.3


def test_friction_without_offset_keeps_the_simpler_law() -> None:
    force = 1.5
    r = loop.discover(carriage(), gen.generate(
        carriage(), gen.Truth(elements=(mdl.Friction(0, 1, force, 1e-3),)), n_tests=4,
        n_samples=4096, seed=5))
    assert [(e["type"], e["location"].get("offset")) for e in r.effects] == [("friction", None)]
    # +2.9 % (see test_discover_drift: the trade with the law's velocity scale)
    assert r.effects[0]["parameters"]["force_n"]["value"] == pytest.approx(force, rel=0.04)


def test_a_force_offset_on_a_free_carriage_is_one_force_not_sensor_offsets() -> None:
    els = (mdl.ConstantForce(0, 1, -0.6),)
    r = loop.discover(carriage(), gen.generate(carriage(), gen.Truth(elements=els), n_tests=4,
                                               seed=2))
    assert [(e["type"], e["location"]["dof"]) for e in r.effects] == [("force_offset", 1)]
    assert r.effects[0]["parameters"]["force_n"]["value"] == pytest.approx(-0.6, rel=0.02)
    # on a free chain a constant force moves both masses alike; only the spring's static
    # deflection (0.6 N / 2e4 N/m = 30 um) tells DOF 1 from DOF 2: the effect names the tie
    # (held-out RMSE 1.017 x here), within half the minimum gain (5 % of the SSE)
    alt = r.effects[0]["alternatives"]
    assert [a["label"] for a in alt] == ["force offset, DOF 2"]
    assert 1.0 < alt[0]["held_out_rmse_ratio"] < math.sqrt(1.05)
    assert "(or, as well supported by these tests: force offset, DOF 2)" in \
        report.to_json(r)["verdict"]
    assert any("one force offset, DOF 1 explains the channels' mean residuals" in n
               for n in r.notes)
    truth = dataclasses.replace(carriage(), elements=els)
    assert _ideal_ratio(r, truth) < 1.3


def grounded() -> mdl.Model:
    """Three masses on springs, force at DOF 1, displacement sensors on every DOF."""
    return mdl.Model(masses_kg=(2.0, 1.5, 1.0), stiffness_n_per_m=(4e4, 3e4, 2e4),
                     damping=mdl.Damping("modal", (0.02, 0.02, 0.02)),
                     input=mdl.Input("force", 1, "force_N"),
                     outputs={f"x{j}_m": mdl.Output("disp", j) for j in (1, 2, 3)},
                     fs_hz=640.0)


def test_a_force_transducer_bias_on_a_grounded_structure() -> None:
    bias = 0.8  # N: the force acting is the measured one + 0.8 N
    els = (mdl.ConstantForce(0, 1, bias),)
    r = loop.discover(grounded(), gen.generate(grounded(), gen.Truth(elements=els), n_tests=4,
                                               n_samples=4096, seed=11))
    assert r.prediction == "open loop"
    assert [(e["type"], e["location"]["dof"]) for e in r.effects] == [("force_offset", 1)]
    assert r.effects[0]["parameters"]["force_n"]["value"] == pytest.approx(bias, rel=0.03)
    truth = dataclasses.replace(grounded(), elements=els)
    assert _ideal_ratio(r, truth) < 1.3
