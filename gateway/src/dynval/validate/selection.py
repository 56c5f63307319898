"""Feature selection for a pair of hypotheses (report Section 6.3, done there by hand): which
candidate features can tell model A (e.g. linear) from model B (e.g. with the bumper) with the
tests at hand, and which cannot.

Both models are driven by each test's measured input and get the same simulated sensor noise
(measurement.py), so d_k = f_B,k - f_A,k is the effect of the difference alone on test k. A
feature's scatter is what the paired test of one feature sees when the other hypothesis is
true: the noise of its paired residual (the SD over the tests of the measured features'
residual against the hypothesis that fits them better) and the effect's own test-to-test
spread (SD of d_k: a bumper that closes only in the high-level tests), in quadrature. The
separation is |mean_k d_k| / scatter, and z = separation x sqrt(n) is the paired test's signal
for n tests: with z >= Z_TELL (1.96 + 0.84) the one-feature paired test at 5 % rejects the wrong
hypothesis with probability >= 80 %; below 1 it is a coin toss.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.io.recording import Recording
from dynval.validate import measurement as meas
from dynval.validate.study import Setup, experiment_features, setup

Z_TELL = 1.96 + 0.84  # two-sided 5 % test, 80 % power


@dataclass(frozen=True)
class Ranked:
    feature: str
    effect: float  # mean of f_B - f_A over the tests (feature units)
    scatter: float  # noise and the effect's spread over the tests, in quadrature
    separation: float  # |effect| / scatter
    z: float  # separation x sqrt(n)
    scatter_from: str

    @property
    def tells_apart(self) -> bool:
        return self.z >= Z_TELL

    def summary(self) -> dict[str, Any]:
        return {"feature": self.feature, "effect": self.effect, "scatter": self.scatter,
                "separation": self.separation, "z": self.z, "scatter_from": self.scatter_from,
                "tells_apart": self.tells_apart}


def _features_of(s: Setup, m: mdl.Model) -> np.ndarray:
    out = []
    for k, (r, nz) in enumerate(zip(s.recs, s.noise, strict=True)):
        u = r.channel(s.input_channel).data
        y = meas.simulate(m, u, s.fs_hz)
        out.append(s.features.extract(meas.add_noise(y, nz, u, k), s.fs_hz, u))
    return np.array(out)


def rank(m_a: mdl.Model, m_b: mdl.Model, recs: Sequence[Recording], candidates: str,
         noise: str = "auto") -> list[Ranked]:
    """Candidate features (a feature spec) ranked by how well they tell m_a from m_b."""
    s = setup(m_a, recs, candidates, noise=noise)
    x = experiment_features(s, s.recs)
    fa, fb = _features_of(s, m_a), _features_of(s, m_b)
    n = x.shape[0]
    sd_a, sd_b = (np.std(x - f, axis=0, ddof=1) for f in (fa, fb))
    d = fb - fa
    effect = np.mean(d, axis=0)
    spread = np.var(d, axis=0, ddof=1)
    out = []
    for j, lab in enumerate(s.features.labels()):
        frm = "A" if sd_a[j] <= sd_b[j] else "B"
        sc = math.sqrt(float(min(sd_a[j], sd_b[j])) ** 2 + float(spread[j]))
        sep = abs(effect[j]) / sc if sc > 0 else math.inf
        out.append(Ranked(lab, float(effect[j]), float(sc), float(sep),
                          float(sep * math.sqrt(n)), frm))
    return sorted(out, key=lambda r: -r.separation)


def table(ranked: Sequence[Ranked], n_tests: int) -> list[str]:
    """The ranking as text lines."""
    lines = [f"{'feature':<24} {'effect B-A':>12} {'scatter':>10} {'sep.':>7} "
             f"{'z (n=' + str(n_tests) + ')':>9}  can tell A from B?"]
    for r in ranked:
        lines.append(f"{r.feature:<24} {r.effect:>12.4g} {r.scatter:>10.3g} "
                     f"{r.separation:>7.3g} {r.z:>9.3g}  "
                     f"{'yes' if r.tells_apart else 'no'}")
    return lines
