"""Uncertainties that cover the truth (issue 16, item 9). The Gauss-Newton sigma assumes the
model's form is right; generated tests carry what real ones do (an anti-alias filter's phase,
a finer integrator) and the fitted values missed the truth by 2-26 of those sigmas (covered
0 of 12 cases at 2 sigma). With the test-to-test scatter of per-test fits added (fit.scatter),
10 of 12 were covered at 2 sigma (measured over seeds 0-11: cubic spring, friction, stiffness
loss, contact); this test runs four of them, at 4096 samples a test (CI time)."""
from __future__ import annotations

import numpy as np
from lanl4dof import declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop


def case(seed: int) -> tuple[gen.Truth, str, float]:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    kind = seed % 4
    if kind == 0:
        k3 = float(10 ** rng.uniform(12.0, 12.8))
        return gen.Truth(elements=(mdl.CubicSpring(story - 1, story, k3),)), "k3_n_per_m3", k3
    if kind == 1:
        f = float(rng.uniform(0.3, 1.0))
        return gen.Truth(elements=(mdl.Friction(0, story, f, 1e-4),)), "force_n", f
    if kind == 2:
        loss = float(rng.uniform(0.03, 0.15))
        return gen.Truth(k_scale={story: 1 - loss}), "dk_n_per_m", -loss * 399790.0
    gap = float(rng.uniform(0.8e-4, 1.2e-4))
    return gen.Truth(elements=(mdl.Contact(story - 1, story, gap, 1e-4, 1.925e6),)), "gap_m", gap


def test_uncertainty_with_the_test_to_test_scatter_covers_the_truth() -> None:
    covered_total = covered_fit = 0
    for seed in range(4):
        truth, name, want = case(seed)
        r = loop.discover(declared(), gen.generate(declared(), truth, n_tests=6, n_samples=4096,
                                                     seed=seed))
        p = r.effects[0]["parameters"][name]
        err = abs(p["value"] - want)
        covered_total += err <= 2 * p["uncertainty"]
        covered_fit += err <= 2 * p["uncertainty_fit"]
        assert p["uncertainty"] >= p["uncertainty_fit"]
    assert covered_total >= 3, covered_total
    assert covered_fit < covered_total  # the Gauss-Newton sigma alone is too small
