"""Error rates of the validation verdict by Monte Carlo on generated tests (dynval.synth: the
truth at 16 x fs, a DAQ's anti-alias filter, 1 % sensor noise on every channel): how often an
exactly right model is rejected (false rejection, to compare with 1 - level) and how often a
wrong one is (power), per feature set. bench/validate_error_rates.py writes the table in
gateway/docs/validate-error-rates.md; tests/test_validate_error_rates.py runs a few seeds.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval import synth
from dynval.validate import study

log = logging.getLogger(__name__)

BUMPER = mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6)  # the shared data's bumper (README)
# the generator's truth at 64 x fs: at its default 16 x, its own linear input hold attenuates
# the response by sinc^2(f / 16 fs), 0.01 % in the STDs, half a standard error of a 10-test
# paired residual; at 64 x the right model's bias is below 0.001 %
FINE = 64


LEVELS = (12.0, 7.2)  # force RMS (N) of the shared data's high and low tests, cycled
HIGH = (12.0,)


@dataclass(frozen=True)
class Scenario:
    truth: synth.Truth
    levels: tuple[float, ...] = LEVELS


def scenarios(m: mdl.Model) -> dict[str, Scenario]:
    """The truths the declared model m is checked against: m itself and wrong ones; the
    bumper also with high-level tests only (at the low level it almost never closes)."""
    zeta = m.damping.zeta
    bump = synth.Truth(elements=(BUMPER,), label="bumper")
    return {"right model": Scenario(synth.Truth(label="right")),
            "bumper (story 3)": Scenario(bump),
            "bumper, high-level tests only": Scenario(bump, HIGH),
            "top story 5 % softer": Scenario(synth.Truth(k_scale={4: 0.95}, label="k4")),
            "damping 30 % higher": Scenario(synth.Truth(zeta=tuple(1.3 * z for z in zeta),
                                                        label="zeta"))}


@dataclass
class Tally:
    """Rejections of the verdict (paired test) and of the eq. 41 size check over the seeds."""

    runs: int = 0
    rejected: int = 0
    inconclusive: int = 0
    outside: int = 0  # eq. 41: the model's median D above the 95 % limit

    def add(self, res: Mapping[str, Any]) -> None:
        self.runs += 1
        v = res["verdict"]["verdict"]
        self.rejected += v == "FAIL"
        self.inconclusive += v == "INCONCLUSIVE"
        self.outside += not res["nominal"]["mahalanobis"]["pass"]

    @property
    def rate(self) -> float:
        return self.rejected / self.runs if self.runs else float("nan")

    def interval(self) -> tuple[float, float]:
        """95 % Wilson interval of the rejection rate."""
        n, k = self.runs, self.rejected
        if n == 0:
            return float("nan"), float("nan")
        z = 1.959964
        c = (k + z * z / 2) / (n + z * z)
        h = z * np.sqrt(k * (n - k) / n + z * z / 4) / (n + z * z)
        return float(c - h), float(c + h)


def run(m: mdl.Model, specs: Sequence[str], truths: Mapping[str, Scenario], seeds: int,
        *, n_tests: int = 10, level: float = 0.95, noise: str = "auto", first_seed: int = 0,
        on_seed: Callable[[str, int], None] | None = None) -> dict[tuple[str, str], Tally]:
    """Rejection tallies per (truth, feature spec) over seeds first_seed.. (each seed: new
    forces and noise; the same tests for every feature spec)."""
    out = {(t, s): Tally() for t in truths for s in specs}
    for name, sc in truths.items():
        for seed in range(first_seed, first_seed + seeds):
            recs = synth.generate(m, sc.truth, n_tests=n_tests, seed=seed, fine=FINE,
                                  levels_n_rms=sc.levels)
            for spec in specs:
                res, _ = study.validate(m, recs, spec, noise=noise, level=level)
                out[(name, spec)].add(res)
            if on_seed is not None:
                on_seed(name, seed)
    return out


def markdown(tallies: Mapping[tuple[str, str], Tally], specs: Sequence[str],
             truths: Sequence[str]) -> list[str]:
    """Rows 'truth | spec | rejected % [95 % interval] | eq. 41 outside %'."""
    lines = ["| truth | features | verdict FAIL (95 % interval) | inconclusive | eq. 41 "
             "outside its limit |", "|---|---|---|---|---|"]
    for t in truths:
        for s in specs:
            ty = tallies[(t, s)]
            lo, hi = ty.interval()
            lines.append(f"| {t} | `{s}` | {100 * ty.rate:.1f} % of {ty.runs} "
                         f"({100 * lo:.1f}-{100 * hi:.1f}) | {ty.inconclusive} | "
                         f"{100 * ty.outside / max(ty.runs, 1):.1f} % |")
    return lines


@dataclass
class Coverage:
    """How often the posterior interval at the level holds the true parameter value."""

    runs: int = 0
    covered: int = 0
    widths: list[float] | None = None

    def add(self, lo: float, hi: float, truth: float) -> None:
        self.runs += 1
        self.covered += lo <= truth <= hi
        self.widths = [*(self.widths or []), hi - lo]

    @property
    def rate(self) -> float:
        return self.covered / self.runs if self.runs else float("nan")


def coverage(m: mdl.Model, spec: str, param: str, lo: float, hi: float, seeds: int, *,
             n_tests: int = 10, level: float = 0.95, first_seed: int = 0,
             options: Mapping[str, Any] | None = None,
             on_seed: Callable[[int, dict[str, Any]], None] | None = None
             ) -> dict[str, Coverage]:
    """Coverage of the calibrated interval of one parameter of m (the truth: m itself) on
    generated tests, per method (gp, direct). options: study.calibrate keywords."""
    from dynval.validate import doe

    truth = m.parameters()[param]
    out: dict[str, Coverage] = {}
    rng = [doe.ParamRange(param, lo, hi)]
    with doe.Runner(workers=1) as rn:
        for seed in range(first_seed, first_seed + seeds):
            recs = synth.generate(m, synth.Truth(label="right"), n_tests=n_tests, seed=seed,
                                  fine=FINE)
            res, _, _ = study.calibrate(m, recs, spec, rng, seed=seed, level=level, runner=rn,
                                        **dict(options or {}))
            for meth, post in res["posterior"].items():
                v = post["parameters"][param]
                out.setdefault(meth, Coverage()).add(v["lo"], v["hi"], truth)
            if on_seed is not None:
                on_seed(seed, res)
    return out
