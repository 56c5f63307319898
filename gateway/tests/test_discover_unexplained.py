"""A residual nothing in the library explains is characterised, not just labelled (issue 16,
item 7): an unmodelled appendage (a 0.8 kg mass on a spring at DOF 4, 45.9 Hz, a mode the
model lacks) leaves a residual whose traits say where it is (its peak at the missing mode,
between the model's modes), that it scales with the input and is linearly related to it."""
from __future__ import annotations

import numpy as np
import pytest

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop, report
from dynval.discover import residual as rs
from dynval.discover import unexplained as ux

ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}


def chain(masses: tuple[float, ...], ks: tuple[float, ...]) -> mdl.Model:
    return mdl.Model(masses_kg=masses, stiffness_n_per_m=ks,
                     damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01, 0.01)[:len(masses)]),
                     input=mdl.Input("force", 1, "force_N"), outputs=dict(ACC), fs_hz=640.0)


def test_an_unmodelled_appendage_is_characterised() -> None:
    ka = 0.8 * (2 * np.pi * 45.0) ** 2
    truth = chain((6.54, 6.66, 6.86, 6.80, 0.8), (10.0, 399790.0, 399790.0, 399790.0, ka))
    f_app = float(mdl.natural_frequencies(truth)[2])
    recs = gen.generate(truth, gen.Truth(label="appendage"), n_tests=6, seed=4)
    m = chain((6.54, 6.66, 6.86, 6.80), (10.0, 399790.0, 399790.0, 399790.0))
    r = loop.discover(m, recs)
    u = r.unexplained
    assert u, "a residual is left and characterised"
    assert u["peak_hz"] == pytest.approx(f_app, rel=0.03)
    assert all(abs(u["peak_hz"] - f) > 0.1 * f for f in r.modes_hz if f > 1)  # not a model mode
    assert 0.7 <= u["level_slope"] <= 1.3
    assert u["input_coherence"] > 0.6
    assert u["summary"] in report.to_json(r)["verdict"]


def test_level_slope_reads_how_the_residual_grows() -> None:
    rng = np.random.default_rng(1)
    tests, res = [], {}
    for i, level in enumerate((1.0, 2.0, 4.0)):
        u = level * rng.standard_normal(4096)
        tests.append(rs.TestData(f"t{i}", 640.0, u, {"a": u}))
        res[f"t{i}"] = {"a": level ** 1.5 * rng.standard_normal(4096)}
    assert ux.level_slope(tests, res, ["a"]) == pytest.approx(1.5, abs=0.05)
    assert ux.level_slope(tests[:1], res, ["a"]) is None  # one level: no slope
