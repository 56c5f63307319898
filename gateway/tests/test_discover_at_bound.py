"""An accepted effect's parameters that ended at an end of their search range are named in its
entry (`at_bound`) and on the report page: the fit wanted to go further, so the effect's form
is stretched there and it may stand in for something else (fit.at_bounds)."""
from __future__ import annotations

import math
from typing import Any

import pytest
from lanl4dof import declared

from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import judge as jd
from dynval.discover import report
from dynval.discover import residual as rs


def _flagged(p: fx.Param, v: float) -> bool:
    return ft.at_bounds([p], [p.name], [v]) == [p.name]


def test_at_bounds_in_the_fits_coordinates() -> None:
    log_p = fx.Param("f_hz", "Hz", 1.0, 1000.0, log=True)  # log: 1..1000, z = log10(v) / 3
    lin_p = fx.Param("x", "m", 0.0, 10.0)
    signed = fx.Param("f0", "N", 1e-3, 10.0, signed=True)  # z = 1/2 at 0
    assert _flagged(log_p, 1000.0) and _flagged(log_p, 1.2)  # z = 1, 0.026
    assert not _flagged(log_p, 1.3) and not _flagged(log_p, 31.6)  # z = 0.038, 0.5
    assert _flagged(lin_p, 9.8) and not _flagged(lin_p, 9.6)
    assert not _flagged(signed, 0.0)  # zero is the middle of a signed range
    assert _flagged(signed, -10.0) and _flagged(signed, 9.9)
    assert ft.at_bounds([log_p], ["other"], [1000.0]) == []  # a name without a range


def _entry(kind: str) -> dict[str, Any]:
    m = declared()
    recs = gen.generate(m, gen.Truth(m_add_kg={2: 1.0}, label="m2"), n_tests=2, seed=3)
    tests = rs.prepare(m, recs)
    chans = rs.common_channels(m, tests)
    scales = rs.channel_scales(tests, chans)
    et = fx.by_type(kind)
    cand = next(c for c in et.candidates(m) if c.location == {"dof": 2})
    res = min((ft.fit(m, cand, s, tests, chans, scales, 40) for s in et.starts(m, cand, 0.5)),
              key=lambda r: r.nsse_fit)
    info = {"reference": "the current model", "evidence": 0.5, "held_gain": 0.5,
            "delta_bic": -100.0}
    return jd.effect_entry(res, info, m, [math.nan] * len(res.values))


def test_an_appendage_standing_in_for_a_mass_is_damped_at_its_bound() -> None:
    # 1 kg added at DOF 2: an appendage there takes the mass (0.98 kg) on a spring far above
    # the band (440 Hz) and damps it as hard as its range allows (zeta 0.5)
    e = _entry("appendage")
    assert e["parameters"]["mass_kg"]["value"] == pytest.approx(1.0, rel=0.05)
    assert e["at_bound"] == ["zeta"]
    page = report._html_effects({"effects": [e]})
    assert "at the end of its search range" in page and ": zeta" in page
    # the right effect is well inside its range, and the page says nothing of bounds
    right = _entry("mass_change")
    assert right["parameters"]["dm_kg"]["value"] == pytest.approx(1.0, rel=0.02)
    assert right["at_bound"] == []
    assert "search range" not in report._html_effects({"effects": [right]})
