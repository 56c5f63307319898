"""`dynval simulate` and `dynval residual`: columns, numbers, formats, folders, exit codes."""
from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from dynval import model as mdl
from dynval.cli import main
from dynval.io import read_test


@pytest.fixture
def clean(shared_data: Path) -> Path:
    return shared_data / "synthetic" / "lanl4dof-clean"


def test_simulate_writes_test_columns_and_prediction(clean: Path, tmp_path: Path) -> None:
    out = tmp_path / "pred.csv"
    test = clean / "test_high_02.csv"
    assert main(["simulate", str(clean / "declared_model.json"), str(test), "-o", str(out)]) == 0
    header = out.read_text().splitlines()[0]
    assert header == test.read_text().splitlines()[0]  # time_s,force_N,acc1_mps2,...
    pred = read_test(out)
    rec = read_test(test)
    np.testing.assert_allclose(pred.channel("force_N").data, rec.channel("force_N").data,
                               rtol=1e-9)
    want = mdl.simulate_recording(mdl.load(clean / "declared_model.json"), rec)
    for c, y in want.items():
        np.testing.assert_allclose(pred.channel(c).data, y, rtol=1e-8, atol=1e-12)
    t = np.loadtxt(out, delimiter=",", skiprows=1)[:, 0]
    np.testing.assert_allclose(t, np.loadtxt(test, delimiter=",", skiprows=1)[:, 0], atol=1e-9)


def test_simulate_with_dynval_format_and_extra_outputs(clean: Path, tmp_path: Path) -> None:
    m = mdl.load(clean / "declared_model.json")
    m2 = dataclasses.replace(m, outputs={**m.outputs, "x4_m": mdl.Output("disp", 4)})
    mdl.save(m2, tmp_path / "m.yaml")
    out = tmp_path / "p.csv"
    assert main(["simulate", str(tmp_path / "m.yaml"), str(clean / "test_low_01.csv"),
                 "-o", str(out)]) == 0
    assert out.read_text().splitlines()[0].endswith("acc4_mps2,x4_m")


def test_residual_table_and_json(clean: Path, shared_data: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    model = str(clean / "declared_model.json")
    assert main(["residual", model, str(clean / "test_high_01.csv")]) == 0
    text = capsys.readouterr().out
    assert "acc4_mps2" in text and "nrmse_%" in text
    bumper = shared_data / "synthetic" / "lanl4dof-bumper"
    assert main(["residual", model, str(clean / "test_high_01.csv"), str(bumper), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert [Path(t["file"]).name for t in res["tests"]] == ["test_high_01.csv"] + sorted(
        p.name for p in bumper.glob("*.csv"))
    clean_nr = res["tests"][0]["channels"]
    assert all(v["nrmse"] < 0.02 for v in clean_nr.values())
    hi4 = res["tests"][4]["channels"]  # bumper test_high_04
    assert max(v["nrmse"] for v in hi4.values()) > 0.1
    for v in clean_nr.values():
        assert v["nrmse"] == pytest.approx(v["rmse"] / v["rms_measured"], rel=1e-12)


def test_bad_model_exits_2(clean: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    d = json.loads((clean / "declared_model.json").read_text())
    d["masses_kg"][1] = 0.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    assert main(["residual", str(bad), str(clean / "test_high_01.csv")]) == 2
    assert "field 'masses_kg[1]'" in caplog.text and "bad.json" in caplog.text
    d["masses_kg"][1] = 6.66
    d["story_stiffness_N_per_m"]["k3_DOF2_DOF3"] = -1.0
    bad.write_text(json.dumps(d))
    assert main(["simulate", str(bad), str(clean / "test_high_01.csv"), "-o",
                 str(tmp_path / "p.csv")]) == 2
    assert "stiffness_n_per_m[2]" in caplog.text


def test_missing_channels_exit_2(clean: Path, tmp_path: Path,
                                 caplog: pytest.LogCaptureFixture) -> None:
    test = tmp_path / "t.csv"
    shutil.copy(clean / "test_low_02.csv", test)
    text = test.read_text().replace("force_N", "drive_N", 1)
    test.write_text(text)
    assert main(["residual", str(clean / "declared_model.json"), str(test)]) == 2
    assert "no input column 'force_N'" in caplog.text
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["residual", str(clean / "declared_model.json"), str(empty)]) == 2
