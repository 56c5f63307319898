"""Records that real rigs give and discover must take or refuse in one line: a dead (constant)
sensor channel, one test far shorter than the others, a constant input, samples a lenient
reader kept as missing. Found by a fuzz of the bundled bumper folder through `dynval discover`
(13 record mutations): the dead channel drew a mass change, an appendage and a sensor gain at
its bound (the bumper's contact with it left out); the short test and the constant input were
internal errors (a spectrum's bins, an empty band); the missing samples a LinAlgError."""
from __future__ import annotations

import dataclasses
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from dynval import io
from dynval import model as mdl
from dynval.cli import main
from dynval.discover import loop, noise, session
from dynval.discover import residual as rs
from dynval.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
BUMPER = REPO / "data" / "lanl4dof-sim" / "bumper"


def bumper() -> tuple[mdl.Model, list[io.Recording]]:
    m = mdl.load(BUMPER / "declared_model.json")
    return m, [io.read_csv(p) for p in sorted(BUMPER.glob("test_*.csv"))]


def with_channel(rec: io.Recording, name: str, data: np.ndarray) -> io.Recording:
    chans = [dataclasses.replace(c, data=data) if c.name == name else c for c in rec.channels]
    return dataclasses.replace(rec, channels=chans)


def test_a_dead_channel_is_left_out_of_every_test_and_said(
        caplog: pytest.LogCaptureFixture) -> None:
    m, recs = bumper()
    recs[0] = with_channel(recs[0], "acc3_mps2", np.zeros(recs[0].n_samples))
    s = session.make_session(m, recs, loop.Options())
    assert s.chans == ["acc1_mps2", "acc2_mps2", "acc4_mps2"]
    assert all("acc3_mps2" not in t.y for t in s.tests)
    assert ("unusable in some test: acc3_mps2 (test_high_01: constant throughout (a dead or "
            "unplugged sensor))") in s.notes[1]
    assert any("acc3_mps2" in r.getMessage() for r in caplog.records
               if r.levelno == logging.WARNING)
    # every channel dead: one line naming them, not "no output is a column"
    for c in m.outputs:
        recs = [with_channel(r, c, np.full(r.n_samples, 0.25)) for r in recs]
    with pytest.raises(ConfigError, match=r"can be fitted \(unusable: acc1_mps2 \(test_high"):
        session.make_session(m, recs, loop.Options())


def test_a_channel_some_tests_lack_is_said_to_be_left_out(
        caplog: pytest.LogCaptureFixture) -> None:
    """discover fits the channels every test has: acc4 missing from one test left it out of
    the whole run without a word (found by the fuzz)."""
    m, recs = bumper()
    recs[1] = dataclasses.replace(recs[1], channels=[c for c in recs[1].channels
                                                     if c.name != "acc4_mps2"])
    s = session.make_session(m, recs, loop.Options())
    assert s.chans == ["acc1_mps2", "acc2_mps2", "acc3_mps2"]
    assert "left out, a column of some tests only: acc4_mps2 (not in test_low_01)" in s.notes
    assert "acc4_mps2 (not in test_low_01)" in caplog.text


def test_a_clipped_channel_is_left_out_and_a_live_or_coarsely_quantised_one_is_not() -> None:
    """The bumper's high test with acc4 clipped at +-2 m/s^2 (its RMS 2.5: an overloaded
    range): discover named a sensor gain on it; now it is left out (and the contact found, by
    the fuzz). A live channel's extreme is one sample; rounded to 0.5 m/s^2 (a quarter of its
    RMS) a few."""
    m, recs = bumper()
    y = recs[0].channel("acc4_mps2").data
    assert session.unusable(y) == ""
    assert session.unusable(np.round(y / 0.5) * 0.5) == ""
    assert session.unusable(np.clip(y, -2.0, 2.0)).startswith("clipped (")
    assert session.unusable(np.clip(y, -2.0, 2.0), "disp") == ""  # a position's plateau
    recs[0] = with_channel(recs[0], "acc4_mps2", np.clip(y, -2.0, 2.0))
    s = session.make_session(m, recs, loop.Options())
    assert s.chans == ["acc1_mps2", "acc2_mps2", "acc3_mps2"]


def test_a_short_test_among_long_ones_leaves_the_summed_spectrum_to_the_long_ones() -> None:
    rng = np.random.default_rng(0)
    long_ones = [rng.standard_normal(8192) for _ in range(2)]
    f, p = rs.summed_spectrum([*long_ones, rng.standard_normal(300)], 640.0)
    f2, p2 = rs.summed_spectrum(long_ones, 640.0)
    assert p is not None and p2 is not None
    assert f.size == 513 and np.array_equal(p, p2)
    f3, p3 = rs.summed_spectrum([rng.standard_normal(300)], 640.0)  # alone: its own segment
    assert f3.size == 151 and p3 is not None


def test_a_constant_input_has_no_sub_band() -> None:
    assert noise.sub_band_corner(np.full(8192, 0.5), 640.0) is None


def test_missing_samples_are_refused_in_one_line(tmp_path: Path,
                                                caplog: pytest.LogCaptureFixture) -> None:
    for p in BUMPER.iterdir():
        shutil.copy(p, tmp_path)
    csv = tmp_path / "test_high_01.csv"
    lines = csv.read_text().splitlines()
    for i in range(1001, 1012):  # 11 empty acc2 cells (a spreadsheet's missing samples)
        cells = lines[i].split(",")
        cells[3] = ""
        lines[i] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")
    assert main(["discover", "--lenient", str(tmp_path / "declared_model.json"),
                 str(tmp_path)]) == 2
    errors = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert errors == [f"{csv}: channel acc2_mps2: 11 missing sample(s), the first at sample "
                      "1000: discover needs complete records (cut the test around them)"]
    # without --lenient the reader names the first empty cell
    caplog.clear()
    assert main(["discover", str(tmp_path / "declared_model.json"), str(tmp_path)]) == 2
    assert "test_high_01.csv:1002 (column acc2_mps2): not a number: ''" in caplog.text
