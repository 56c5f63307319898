"""Starts far worse than no effect (fit.temper): the evidence's amplitude is a first-order
reading of a noisy missing force, and a start whose simulation leaves the tests at hundreds of
times the current model's error lies in no basin of the effect. Its strength is moved toward
no effect (Param.null) until the start is back under fit.TEMPER_RATIO x that error; the shape
(a gap, a frequency) is kept. Checked against direct simulations of the same starts."""
from __future__ import annotations

import logging
import math

import pytest

from dynval import model as mdl
from dynval import synth
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import residual as rs
from dynval.discover import trace as tr
from dynval.discover.judge import Judge
from dynval.discover.session import Options

K = 4.0e5


def _chain() -> mdl.Model:
    return mdl.Model(masses_kg=(6.5, 6.6, 6.7, 6.8), stiffness_n_per_m=(K,) * 4,
                     damping=mdl.Damping("modal", (0.02, 0.02, 0.02, 0.02)),
                     input=mdl.Input("force", 4, "force_N"),
                     outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)},
                     fs_hz=640.0)


@pytest.fixture(scope="module")
def case() -> tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]]:
    m = _chain()  # a linear truth: every effect is spurious here
    recs = synth.generate(m, synth.Truth(), n_tests=2, n_samples=2048, seed=5,
                          levels_n_rms=(10.0,))
    tests = rs.prepare(m, recs)
    chans = rs.common_channels(m, tests)
    return m, tests, chans, rs.channel_scales(tests, chans)


def _nsse(m: mdl.Model, tests: list[rs.TestData], chans: list[str],
          scales: dict[str, float]) -> float:
    r = ft.residual_vector(m, tests, chans, scales)
    assert r is not None
    return float(r @ r)


def _contact(m: mdl.Model) -> fx.Candidate:
    et = fx.by_type("contact")
    return next(c for c in et.candidates(m)
                if c.location["between"] == [1, 2] and c.location["side"] == "neg")


def test_a_start_far_worse_than_no_effect_is_weakened_to_the_first_factor_under_the_ratio(
        case: tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]]) -> None:
    m, tests, chans, scales = case
    cand = _contact(m)
    et = fx.by_type("contact")
    without = _nsse(m, tests, chans, scales)
    start = [0.0, 1e-5, 2.0 * K]  # closed from the first micrometre, half a story's stiffness
    at_start = _nsse(et.apply(m, cand, start), tests, chans, scales)
    assert at_start > 10 * ft.TEMPER_RATIO * without
    got = ft.temper(m, cand, start, tests, chans, scales)
    assert got[:2] == start[:2]  # the gap and its transition kept
    f = got[2] / start[2]
    assert f in [pytest.approx(x, rel=1e-12) for x in ft.TEMPER_FACTORS]
    assert _nsse(et.apply(m, cand, got), tests, chans, scales) <= ft.TEMPER_RATIO * without
    stronger = [x for x in ft.TEMPER_FACTORS if x > f * (1 + 1e-9)]
    for x in stronger:  # every stronger factor tried first was still over the ratio
        s = _nsse(et.apply(m, cand, [0.0, 1e-5, x * start[2]]), tests, chans, scales)
        assert s > ft.TEMPER_RATIO * without


def test_a_start_under_the_ratio_is_kept_as_it_is(
        case: tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]]) -> None:
    m, tests, chans, scales = case
    cand = _contact(m)
    without = _nsse(m, tests, chans, scales)
    start = [0.0, 1e-5, 1e3]  # closing half the time, at 0.25 % of a story's stiffness
    at_start = _nsse(fx.by_type("contact").apply(m, cand, start), tests, chans, scales)
    assert without < at_start <= ft.TEMPER_RATIO * without
    assert ft.temper(m, cand, start, tests, chans, scales) == start


def test_a_declared_change_is_weakened_toward_the_current_value(
        case: tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]]) -> None:
    m, tests, chans, scales = case
    et = fx.by_type("stiffness_change")
    cand = next(c for c in et.candidates(m) if c.location["story"] == 2)
    without = _nsse(m, tests, chans, scales)
    got = ft.temper(m, cand, [0.9 * K], tests, chans, scales)
    f = got[0] / (0.9 * K)
    assert 0 < f < 1
    assert _nsse(et.apply(m, cand, got), tests, chans, scales) <= ft.TEMPER_RATIO * without


def test_a_round_fits_a_spurious_candidate_from_its_weakened_start(
        case: tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]],
        caplog: pytest.LogCaptureFixture) -> None:
    """Judge.candidate: evidence with a stiffness of twice a story's for a contact the truth
    lacks; the start is weakened, and the fit (with the re-adjusted declared parameters)
    ends at the model without the effect, refused."""
    m, tests, chans, scales = case
    fit_t, held_t = tests[:1], tests[1:]
    table, _ = rs.error_table(m, tests, chans, scales)
    judge = Judge(m, table, fit_t, held_t, chans, scales, Options(), (20.0, 200.0))
    cand = _contact(m)
    ev = tr.Evidence(cand, 0.3, 2.0 * K, {"gap_m": 0.0, "drift_rms_m": 1e-4})
    with caplog.at_level(logging.INFO, logger="dynval.discover.fit"):
        info = judge.candidate(ev)
    assert info is not None
    assert any("start's strength x" in r.getMessage() for r in caplog.records)
    without = table.total([t.name for t in fit_t])
    assert info["fit"].nsse_fit <= 1.01 * without
    assert not info["accepted"]


@pytest.mark.parametrize("kb", [math.nan, 1e300])
def test_a_start_the_core_refuses_at_every_strength_is_given_back_as_it_is(
        case: tuple[mdl.Model, list[rs.TestData], list[str], dict[str, float]],
        kb: float) -> None:
    """A NaN or a huge finite stiffness: every weakened start is refused too (validation, or
    a run that is not finite); temper gives the start back for the fit to penalise, no
    exception."""
    m, tests, chans, scales = case
    start = [0.0, 1e-5, kb]
    got = ft.temper(m, _contact(m), start, tests, chans, scales)
    assert len(got) == 3 and got[:2] == start[:2]
    assert got[2] == kb or (math.isnan(got[2]) and math.isnan(kb))
