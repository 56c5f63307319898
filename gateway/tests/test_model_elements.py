"""The element registry (dynval.model.elements): its parameter bounds are what the core's
dv_elem_check enforces, and elements.force (the core's dv_elem_force_block) is each law's
closed form (include/dynval/dv_elem.h)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from dynval import model as mdl
from dynval.errors import ConfigError
from dynval.model import elements as el

X = np.linspace(-4e-4, 4e-4, 801)


def _with(t: el.ElementType, name: str, v: float) -> el.Element:
    vals = {p.name: (v if p.name == name else 2.0 * max(p.lower, 1e-3)) for p in t.params}
    return el.make(t.name, 0, 1, vals)


@pytest.mark.parametrize("t", list(el.REGISTRY.values()), ids=list(el.REGISTRY))
def test_registry_bounds_are_the_core_check(t: el.ElementType) -> None:
    for p in t.params:
        if math.isinf(p.lower):  # any finite value (the constant force, of either sign)
            cases = [(-1e300, True), (0.0, True), (1e300, True)]
        else:
            cases = [(math.nextafter(p.lower, -math.inf), False), (p.lower, not p.strict),
                     (math.nextafter(p.lower, math.inf), True)]
        for v, ok in (*cases, (math.nan, False), (math.inf, False), (-math.inf, False)):
            e = _with(t, p.name, v)
            assert p.admits(v) is ok, (p.name, v)
            assert el.core_accepts(e) is ok, (p.name, v)  # dv_elem_check agrees
            assert (el.refusal(e) is None) is ok
            if not ok:
                assert el.refusal(e) == (p.name, f"must be {p.bound_text()}, got {v!r}")


def test_registry_laws_and_arguments_are_the_core_s() -> None:
    assert [el.REGISTRY[n].law_id for n in el.TYPES] == [0, 1, 2, 3, 4, 5]
    assert {n for n in el.TYPES if el.REGISTRY[n].on_velocity} == {"friction", "vv_damper"}
    assert el.spec("friction").param("v_eps_m_per_s").unit == "m/s"
    assert el.spec("cubic_spring").param("k3_n_per_m3").field == "kb_n_per_m"


def test_model_refuses_an_element_outside_its_bound_naming_the_field() -> None:
    d = {"format": mdl.FORMAT, "masses_kg": [1.0], "stiffness_n_per_m": [100.0],
         "damping": {"type": "modal", "zeta": [0.02]}, "input": {"kind": "force", "dof": 1},
         "outputs": {"a": {"kind": "acc", "dof": 1}},
         "elements": [{"type": "stick_slip", "between": [0, 1], "force_n": 1.0, "slip_m": 0.0}]}
    with pytest.raises(ConfigError, match=r"elements\[0\]\.slip_m.*must be > 0 m, got 0\.0"):
        mdl.from_dict(d)
    d["elements"][0]["type"] = "coulomb"  # type: ignore[index]
    with pytest.raises(ConfigError, match="'coulomb' is not one of contact, friction"):
        mdl.from_dict(d)


def _bump(s: np.ndarray, d: float, kb: float) -> np.ndarray:
    return np.where(s <= 0, 0.0, np.where(s < d, kb * s * s / (2 * d), kb * (s - d / 2)))


@pytest.mark.parametrize("side", ["pos", "neg", "both"])
def test_contact_force_is_the_bumper_closed_form(side: str) -> None:
    gap, d, kb = 1e-4, 5e-5, 2e6
    g = el.force(mdl.Contact(0, 1, gap, d, kb, side), X)
    want = np.zeros_like(X)
    if side in ("pos", "both"):
        want += _bump(X - gap, d, kb)
    if side in ("neg", "both"):
        want -= _bump(-X - gap, d, kb)
    np.testing.assert_allclose(g, want, rtol=1e-14, atol=1e-12)
    # delta = 0: the bilinear spring kB max(X - gap, 0)
    g0 = el.force(mdl.Contact(0, 1, gap, 0.0, kb), X)
    np.testing.assert_allclose(g0, kb * np.maximum(X - gap, 0.0), rtol=1e-14, atol=1e-12)


def test_velocity_laws_and_cubic_are_their_closed_forms() -> None:
    v = X * 100.0
    np.testing.assert_allclose(el.force(mdl.Friction(0, 1, 2.5, 1e-3), v=v),
                               2.5 * v / np.sqrt(v * v + 1e-6), rtol=1e-14)
    np.testing.assert_allclose(el.force(mdl.VVDamper(0, 1, 300.0), v=v), 300.0 * v * np.abs(v),
                               rtol=1e-14)
    np.testing.assert_allclose(el.force(mdl.CubicSpring(0, 1, 5e12), X), 5e12 * X ** 3,
                               rtol=1e-14)
    # the constant force pushes DOF b by +F: its restoring force g is -F whatever X
    np.testing.assert_array_equal(el.force(mdl.ConstantForce(0, 1, -4.5), X), 4.5)


def test_stick_slip_is_the_elasto_plastic_loop() -> None:
    f, z = 2.0, 1e-5
    up = np.linspace(0.0, 3 * z, 31)
    down = np.linspace(3 * z, -3 * z, 61)[1:]
    g = el.force(mdl.StickSlip(0, 1, f, z), np.concatenate([up, down]))
    np.testing.assert_allclose(g[:31], np.minimum(f / z * up, f), rtol=1e-12, atol=1e-12)
    # from the slip at +F, the stick spring unloads over 2 z, then it slips at -F
    np.testing.assert_allclose(g[31:], np.maximum(f - f / z * (3 * z - down), -f), rtol=1e-12,
                               atol=1e-12)


def test_restoring_pushes_dof_a_and_b_apart() -> None:
    x = np.vstack([np.zeros(3), np.array([1.0, 2.0, 3.0]) * 1e-3])
    v = np.zeros_like(x)
    f = el.restoring((mdl.CubicSpring(1, 2, 1e6),), x, v)
    np.testing.assert_allclose(f[1], 1e6 * x[1] ** 3)
    np.testing.assert_allclose(f[0], -f[1])


def test_file_round_trip_reads_and_writes_registry_keys() -> None:
    es = (mdl.Contact(0, 1, 1e-4, 0.0, 1e6, "both", name="b"), mdl.Friction(1, 2, 1.0, 1e-3),
          mdl.VVDamper(0, 2, 5.0), mdl.StickSlip(0, 1, 1.0, 1e-5))  # the core's 4 elements
    m = mdl.Model((1.0, 1.0), (100.0, 100.0), mdl.Damping("modal", (0.01, 0.01)),
                  mdl.Input("force", 1), {"a": mdl.Output("acc", 1)}, elements=es)
    d = mdl.to_dict(m)
    assert d["elements"][0] == {"type": "contact", "name": "b", "between": ["ground", 1],
                                "side": "both", "gap_m": 1e-4, "delta_m": 0.0,
                                "kb_n_per_m": 1e6}
    assert d["elements"][1] == {"type": "friction", "between": [1, 2], "force_n": 1.0,
                                "v_eps_m_per_s": 1e-3}
    assert mdl.from_dict(d).elements == es
    assert mdl.param_unit("e2.v_eps_m_per_s", m) == "m/s"
    assert m.with_params({"e4.slip_m": 2e-5}).elements[3] == mdl.StickSlip(0, 1, 1.0, 2e-5)
    with pytest.raises(ConfigError, match="element 3: element type vv_damper has no parameter"):
        m.with_params({"e3.k3_n_per_m3": 1.0})
