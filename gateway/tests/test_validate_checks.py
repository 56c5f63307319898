"""`dynval validate --check` (validate.checks): the report's linearity (two excitation levels)
and reciprocity (input and response swapped) checks on the tests and on the model, in the
verdict, on independent simulations of the report's 4-DOF structure (dynval.synth): both hold
for the linear model on linear data and fail on the bumper's data, where the linear model
(on which they hold) is then rejected."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from lanl4dof import declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.catalogue import frf as F
from dynval.errors import ConfigError
from dynval.validate import checks as chk
from dynval.validate import report, study

BUMPER = gen.Truth(elements=(mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),), label="bumper")


def _z2_bound(o: chk.Outcome) -> float:
    """z2 is the band's mean of |dH|^2 / var (each about Exp(1) for two estimates of one
    linear FRF): 1 within 6 standard errors, 1 / sqrt(lines) each, times 1.5 for the
    correlation of neighbouring lines under the Hann window's 50 % overlap."""
    lines = int(np.sum(o.frfs["measured"][0].band(o.measured.band_hz)))
    return 6 * 1.5 / np.sqrt(lines)


@pytest.mark.parametrize("seed", [3, 4])
def test_linearity_holds_on_linear_data_and_the_linear_model(seed: int) -> None:
    m = declared()
    recs = gen.generate(m, gen.Truth(), n_tests=10, seed=seed)
    (o,) = chk.run(m, recs, chk.parse(["linearity@acc4"], m, list(m.outputs)), "force_N")
    assert o.labels == ("5 higher-level tests", "5 lower-level tests")
    b = _z2_bound(o)
    for c in (o.measured, o.model):
        assert abs(c.z2 - 1.0) < b and abs(c.z2_coh - 1.0) < b
        assert c.passed
    assert o.consistent


def test_linearity_fails_with_the_bumper_and_rejects_the_linear_model(tmp_path: Path) -> None:
    m = declared()
    recs = gen.generate(m, BUMPER, n_tests=10, seed=5)
    res, art = study.validate(m, recs, "rms@acc4", checks=["linearity@acc4"])
    c = res["checks"][0]
    # the bumper closes at 12 N, hardly at 7.2 N: the high-level coherence drops
    assert c["measured"]["z2_coh"] > 3 * F.Z2_LIMIT and not c["measured"]["holds"]
    assert c["model"]["holds"] and abs(c["model"]["z2_coh"] - 1.0) < _z2_bound(art.checks[0])
    assert not c["consistent"]
    assert res["verdict"]["verdict"] == "FAIL" and res["verdict"]["exit_code"] == 1
    assert "linearity check fails on the tests and holds on the model" in \
        res["verdict"]["meaning"]
    report.write_html(res, art, tmp_path / "r.html")
    page = (tmp_path / "r.html").read_text()
    assert "Linearity check (5.3.1)" in page and "model reproduces it" in page


@pytest.mark.parametrize("truth,holds", [(gen.Truth(), True), (BUMPER, False)])
def test_reciprocity_on_swapped_tests(truth: gen.Truth, holds: bool) -> None:
    m = declared()
    a, b = gen.reciprocal(m, truth, 4, n_tests=3, levels_n_rms=(12.0,), seed=11)
    checks = chk.parse(["reciprocity@acc4"], m, list(m.outputs))
    assert checks[0].other == "acc1_mps2"  # the response at the input DOF 1
    (o,) = chk.run(m, a, checks, "force_N", swapped=b)
    assert o.model.passed and abs(o.model.z2 - 1.0) < _z2_bound(o)
    assert o.measured.passed is holds
    if not holds:
        assert o.measured.z2_coh > 2 * F.Z2_LIMIT
    assert o.consistent is holds


def test_check_errors_are_one_line() -> None:
    m = declared()
    recs = gen.generate(m, gen.Truth(), n_tests=4, levels_n_rms=(12.0,), seed=1)
    with pytest.raises(ConfigError, match="two excitation levels"):
        chk.run(m, recs, chk.parse(["linearity@acc4"], m, list(m.outputs)), "force_N")
    with pytest.raises(ConfigError, match="needs --swapped"):
        chk.run(m, recs, chk.parse(["reciprocity@acc4"], m, list(m.outputs)), "force_N")
    with pytest.raises(ConfigError, match="expected linearity@CHANNEL"):
        chk.parse(["symmetry@acc4"], m, list(m.outputs))
    with pytest.raises(ConfigError, match="not found"):
        chk.parse(["linearity@acc9"], m, list(m.outputs))
