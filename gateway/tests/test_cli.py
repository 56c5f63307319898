"""The CLI: `dynval features` on good and bad files, exit codes and one-line errors."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from dynval.cli import main


def write(tmp_path: Path, text: str, name: str = "t.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = "time_s,force_N,acc1_mps2\n" + "".join(
    f"{i / 100:.2f},{(i % 7) - 3},{(i % 5) * 0.5}\n" for i in range(200))


def test_features_table_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = write(tmp_path, GOOD)
    assert main(["features", str(p)]) == 0
    out = capsys.readouterr().out
    assert "force_N" in out and "acc1_mps2" in out and "200 samples at 100 Hz" in out
    assert main(["features", "--json", str(p)]) == 0
    res = json.loads(capsys.readouterr().out)
    mean = sum((i % 7) - 3 for i in range(200)) / 200
    assert res["channels"]["force_N"]["mean"] == pytest.approx(mean)
    assert res["fs_hz"] == pytest.approx(100.0)


@pytest.mark.parametrize("text, where, what", [
    ("", ":1", "empty file"),
    ("time_s,force_N\n0,1\n0.01,abc\n0.02,3\n", ":3 (column force_N)", "not a number"),
    ("time_s,force_N\n0,1\n0.01,nan\n0.02,3\n", ":3 (column force_N)", "non-finite"),
    ("time_s,force_N\n0,1\n0.01,2\n0.005,3\n", ":4 (column time_s)", "does not increase"),
    ("time_s,force_N\n0,1\n0.01,2\n0.02,3\n0.05,4\n0.06,5\n", ":5 (column time_s)", "irregular"),
    ("time_s,force_N,acc1_mps2\n0,1,2\n0.01,2,3\n0.02,3", ":4", "truncated"),
    ("1,2\n3,4\n", ":1", "header"),
])
def test_bad_files_exit_2_with_file_line_column(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                                text: str, where: str, what: str) -> None:
    p = write(tmp_path, text)
    assert main(["features", str(p)]) == 2
    msgs = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert len(msgs) == 1
    assert f"{p}{where}" in msgs[0] and what in msgs[0]


def test_lenient_counts_instead_of_failing(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    p = write(tmp_path, "time_s,force_N\n0,1\n0.01,nan\n0.02,3\n0.03,4\n0.04,5")
    assert main(["features", "--json", "--lenient", str(p)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["warnings"] == 1
    assert res["channels"]["force_N"]["count"] == 4  # the NaN was dropped and counted by the core


def test_missing_file_and_no_command(tmp_path: Path) -> None:
    assert main(["features", str(tmp_path / "nope.csv")]) == 2
    assert main([]) == 2


def test_real_data_file(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = shared_data / "synthetic" / "lanl4dof-clean" / "test_high_01.csv"
    assert main(["features", "--json", str(f)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["n_samples"] == 8192 and res["fs_hz"] == pytest.approx(640.0)
    # the declared force level is 12 N RMS (meta.json); 1 % sensor noise on top
    assert res["channels"]["force_N"]["rms"] == pytest.approx(12.0, rel=0.05)
