"""Readers of recorded tests: whitespace text, BRFD JSON, DROPBEAR text, channel maps, and
bad input named by file, line and column (or counted with lenient=True)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dynval.errors import ConfigError, InputFileError
from dynval.io import apply_channel_map, read_test
from dynval.io.channelmap import channel_map_from_dict


def _text(tmp_path: Path, rows: list[str], name: str = "t.txt") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(rows) + "\n")
    return p


def test_text_default_layout_force_and_four_accelerations(tmp_path):
    x = np.arange(50.0).reshape(10, 5)
    p = _text(tmp_path, [" ".join(f"{v:g}" for v in r) for r in x])
    rec = read_test(p, fs_hz=320.0)
    assert rec.fs_hz == 320.0 and rec.n_samples == 10
    assert rec.names == ["force_N", "acc1_mps2", "acc2_mps2", "acc3_mps2", "acc4_mps2"]
    assert [c.role for c in rec.channels] == ["input"] + ["output"] * 4
    assert [c.dof for c in rec.channels] == [1, 1, 2, 3, 4]
    np.testing.assert_array_equal(rec.channel("acc2_mps2").data, x[:, 2])


def test_text_needs_a_rate(tmp_path):
    p = _text(tmp_path, ["1 2", "3 4"])
    with pytest.raises(InputFileError, match="sampling rate"):
        read_test(p)


def test_text_header_and_bad_cell_named(tmp_path):
    p = _text(tmp_path, ["a b c", "1 2 3", "4 x 6", "7 8 9"])
    with pytest.raises(InputFileError) as e:
        read_test(p, fs_hz=10)
    assert e.value.line == 3 and e.value.column == "b" and "not a number" in str(e.value)


def test_text_truncated_last_row_strict_and_lenient(tmp_path):
    p = _text(tmp_path, ["1 2 3", "4 5 6", "7 8"])
    with pytest.raises(InputFileError, match="truncated") as e:
        read_test(p, fs_hz=10)
    assert e.value.line == 3
    rec = read_test(p, fs_hz=10, lenient=True)
    assert rec.n_samples == 2 and len(rec.warnings) == 1


def test_text_nan_strict_and_lenient(tmp_path):
    p = _text(tmp_path, ["1 2", "nan 4", "5 6"])
    with pytest.raises(InputFileError, match="non-finite") as e:
        read_test(p, fs_hz=10)
    assert e.value.line == 2 and e.value.column == "ch1"
    rec = read_test(p, fs_hz=10, lenient=True)
    assert np.isnan(rec.channels[0].data[1]) and len(rec.warnings) == 1


def _brfd(tmp_path: Path, rows: list[list[float]], **kw: object) -> Path:
    d = {"data": rows, "dt": 1 / 1024, "sampling freq": 1024, "displacement units": "in",
         "time units": "s", "friction force units": "kip", "actuator force units": "lb", **kw}
    p = tmp_path / "b.json"
    p.write_text(json.dumps(d))
    return p


def test_brfd_layout_and_roles(tmp_path):
    rows = [[i / 1024, 0.1 * i, 0.2 * i, 0.3, 4.0, 5.0] for i in range(8)]
    rec = read_test(_brfd(tmp_path, rows))
    assert rec.fs_hz == 1024 and rec.n_samples == 8
    assert rec.names[:2] == ["displacement", "friction_force"]
    assert rec.channels[0].role == "input" and rec.channels[0].unit == "in"
    assert rec.channels[1].unit == "kip" and rec.channels[2].unit == "in/s"


def test_brfd_bad_time_and_ragged_row(tmp_path):
    rows = [[i / 1024, 0.0, 0.0, 0.0, 0.0, 0.0] for i in range(8)]
    rows[5][0] = 0.5
    with pytest.raises(InputFileError, match="time step") as e:
        read_test(_brfd(tmp_path, rows))
    assert e.value.column == "t"
    rows = [[i / 1024, 0.0, 0.0, 0.0, 0.0, 0.0] for i in range(8)]
    rows[3] = rows[3][:4]
    with pytest.raises(InputFileError, match="values") as e:
        read_test(_brfd(tmp_path, rows))
    assert e.value.line == 4


def test_brfd_truncated_json(tmp_path):
    p = _brfd(tmp_path, [[i / 1024, 0, 0, 0, 0, 0] for i in range(8)])
    p.write_text(p.read_text()[:-30])
    with pytest.raises(InputFileError, match="truncated"):
        read_test(p)


def test_brfd_real_file(shared_data):
    p = shared_data / "real/friction-damper-brfd/dataset-2/characterization datasets" \
        / "1Hz30lbtension1amplitude.json"
    rec = read_test(p)
    assert rec.n_samples == 7169 and rec.fs_hz == 1024 and len(rec.channels) == 5
    assert rec.sha256 and not rec.warnings


DROPBEAR_HEAD = ["C:\\x\\test0.txt", "Programmer - None", "Striker Velocity - 0.001",
                 "Sampling Frequency - 5000", "Mon, Jun 6, 2022 11:17 AM",
                 "Low G Accel\tAccel\tPinLoc\tTime",
                 "Voltage (unscaled)\tVoltage (unscaled)\tVoltage (unscaled)\tSec",
                 "0.0 0.0 0\t\t\t", ""]


def test_dropbear_layout_and_artefact_counted(tmp_path):
    rows = [f"{0.01 * i:.5E}\t{(-1.4 if i % 5 == 3 else 0.02):.5E}\t1.2\t{i * 2e-4:.5E}"
            for i in range(20)]
    p = _text(tmp_path, DROPBEAR_HEAD + rows)
    rec = read_test(p)
    assert rec.fs_hz == 5000 and rec.names == ["low_g_accel", "accel", "pinloc"]
    assert rec.n_samples == 20 and any("artefact" in w and " 4 samples" in w
                                       for w in rec.warnings)
    from dynval.io.dropbear import read_dropbear

    m = read_dropbear(p, mask_artefact=True)
    assert int(np.isnan(m.channel("accel").data).sum()) == 4


def test_dropbear_time_off_clock(tmp_path):
    rows = [f"0\t0\t0\t{i * 2e-4:.5E}" for i in range(10)]
    rows[6] = "0\t0\t0\t5.00000E-3"
    p = _text(tmp_path, DROPBEAR_HEAD + rows)
    with pytest.raises(InputFileError, match="clock") as e:
        read_test(p)
    assert e.value.line == 16 and e.value.column == "Time"


def test_dropbear_bad_rows(tmp_path):
    from dynval.io.dropbear import read_dropbear

    rows = [f"0.1\t0.2\t0.3\t{i * 2e-4:.5E}" for i in range(10)]
    p = _text(tmp_path, DROPBEAR_HEAD + rows + ["0.1\t0.2"])  # cut off mid-row
    with pytest.raises(InputFileError, match="truncated file") as e:
        read_dropbear(p)
    assert e.value.line == 20
    rows[4] = "0.1\tnan\t0.3\t8.00000E-4"
    p = _text(tmp_path, DROPBEAR_HEAD + rows + ["0.1\t0.2"])
    with pytest.raises(InputFileError, match="non-finite") as e:
        read_dropbear(p)
    assert e.value.line == 14 and e.value.column == "Accel"
    rec = read_dropbear(p, lenient=True)  # the short last row dropped, the NaN kept
    assert rec.n_samples == 10
    assert int(np.isnan(rec.channel("accel").data).sum()) == 1
    assert any("truncated last row dropped" in w for w in rec.warnings)
    assert any("non-finite Accel" in w for w in rec.warnings)
    rows[4] = "0.1\tnan\t0.3\t8.00000E-4"
    rows[7] = "0.1\t0.2\t0.3\tinf"  # the time column must be finite even when lenient
    p = _text(tmp_path, DROPBEAR_HEAD + rows)
    with pytest.raises(InputFileError, match="non-finite") as e:
        read_dropbear(p, lenient=True)
    assert e.value.line == 17 and e.value.column == "Time"
    rows[7] = "0.1\tabc\t0.3\t1.40000E-3"
    p = _text(tmp_path, DROPBEAR_HEAD + rows)
    with pytest.raises(InputFileError, match="not a number") as e:
        read_dropbear(p, lenient=True)
    assert e.value.line == 17 and e.value.column == "Accel"


def test_dropbear_real_file(shared_data):
    p = shared_data / "real/dropbear-dataset8/Random Index Set Random Dwell/set0/trial data" \
        / "test0.txt"
    rec = read_test(p)
    assert rec.n_samples == 60000 and rec.fs_hz == 5000 and len(rec.channels) == 5
    assert any("artefact" in w for w in rec.warnings)


def test_channel_map_selects_renames_scales(tmp_path):
    x = np.arange(50.0).reshape(10, 5)
    p = _text(tmp_path, [" ".join(f"{v:g}" for v in r) for r in x])
    cmap = channel_map_from_dict({"channels": [
        {"column": 0, "name": "F", "unit": "kN", "scale": 0.001, "role": "input"},
        {"column": "acc4_mps2", "name": "top", "dof": 4}]})
    rec = read_test(p, fs_hz=100, channel_map=cmap)
    assert rec.names == ["F", "top"]
    np.testing.assert_allclose(rec.channels[0].data, x[:, 0] * 0.001)
    assert rec.channels[1].dof == 4 and rec.channels[1].unit == "m/s^2"
    with pytest.raises(ConfigError, match="no channel"):
        apply_channel_map(read_test(p, fs_hz=100),
                          channel_map_from_dict({"channels": [{"column": "nope"}]}))
    with pytest.raises(ConfigError, match="role"):
        channel_map_from_dict({"channels": [{"column": 0, "role": "sideways"}]})
