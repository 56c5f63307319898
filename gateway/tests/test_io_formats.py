"""The test engineers' formats, written by their own libraries (pyuff, asammdf, h5py,
scipy.io.savemat, pandas) and read back through `dynval features` and the reader API; and the
CSV dialects (quoted cells, ';' with decimal commas, '#' preambles) with their line numbers."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval.cli import main
from dynval.errors import InputFileError
from dynval.io import read_dataframe, read_test

FS = 640.0
N = 1024
T = np.arange(N) / FS
FORCE = np.random.default_rng(3).normal(size=N)
ACC = 2.0 * np.sin(2 * np.pi * 20.0 * T)  # rms sqrt(2) exactly over whole periods


def features_json(p: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> Any:
    capsys.readouterr()
    assert main(["-q", "features", str(p), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def check(res: dict[str, Any], *, places: int = 12) -> None:
    assert res["fs_hz"] == pytest.approx(FS, rel=1e-9) and res["n_samples"] == N
    f, a = res["channels"]["force"], res["channels"]["acc1"]
    assert (f["unit"], f["role"], a["unit"], a["role"]) == ("N", "input", "m/s^2", "output")
    assert f["mean"] == pytest.approx(FORCE.mean(), abs=10.0 ** -places)
    assert f["std"] == pytest.approx(FORCE.std(), rel=10.0 ** -places)
    assert a["rms"] == pytest.approx(np.sqrt(2.0), rel=10.0 ** -places)
    assert a["peak"] == pytest.approx(np.abs(ACC).max(), rel=10.0 ** -places)


def write_uff(p: Path) -> None:
    pyuff = pytest.importorskip("pyuff")
    sets = [pyuff.prepare_58(
        binary=0, func_type=1, rsp_node=k + 1, rsp_dir=3, ref_node=1, ref_dir=3, ord_data_type=4,
        id1=name, abscissa_spacing=1, abscissa_inc=1 / FS, abscissa_min=0.0, data=data, x=T,
        ordinate_axis_units_lab=unit, ordinate_spec_data_type=spec, abscissa_spec_data_type=17,
        abscissa_axis_units_lab="s", orddenom_spec_data_type=0, z_axis_spec_data_type=0)
        for k, (name, data, spec, unit) in enumerate((("force", FORCE, 13, "N"),
                                                      ("acc1", ACC, 12, "m/s^2")))]
    pyuff.UFF(str(p)).write_sets(sets, mode="overwrite")


def write_mdf(p: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(FORCE, T, name="force", unit="N"),
                asammdf.Signal(ACC, T, name="acc1", unit="m/s^2")])
    mdf.append([asammdf.Signal(np.arange(10.0), np.arange(10) / 10.0, name="temp", unit="C")])
    mdf.save(p, overwrite=True)
    mdf.close()


def write_h5(p: Path) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(p, "w") as f:
        g = f.create_group("run1")
        g.attrs["sampling_rate"] = FS
        g["force"] = FORCE
        g["force"].attrs["unit"] = "N"
        g["acc1"] = ACC
        g["acc1"].attrs["units"] = b"m/s^2"


def write_mat(p: Path) -> None:
    from scipy.io import savemat

    savemat(p, {"time": T, "force": FORCE, "acc1": ACC.reshape(-1, 1),
                "units": {"force": "N", "acc1": "m/s^2"}})


@pytest.mark.parametrize("suffix, write, places", [
    (".uff", write_uff, 10),  # UFF 58 ASCII keeps 12 significant digits
    (".mf4", write_mdf, 12), (".h5", write_h5, 12), (".mat", write_mat, 12)])
def test_format_through_dynval_features(suffix: str, write: Any, places: int, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"test1{suffix}"
    write(p)
    check(features_json(p, capsys), places=places)
    rec = read_test(p)
    np.testing.assert_allclose(rec.channel("acc1").data, ACC, rtol=0, atol=1e-10)


def test_mdf_channels_on_another_time_base_are_left_out(tmp_path: Path) -> None:
    p = tmp_path / "t.mf4"
    write_mdf(p)
    assert read_test(p).names == ["force", "acc1"]  # 'temp' at 10 Hz is reported, not mixed in


def test_mat_without_units_takes_a_channel_map(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    from scipy.io import savemat

    p = tmp_path / "raw.mat"
    savemat(p, {"Fs": FS, "ch1": FORCE * 1000.0, "ch2": ACC})
    cmap = tmp_path / "map.json"
    cmap.write_text(json.dumps({"channels": [
        {"column": "ch1", "name": "force", "unit": "N", "scale": 1e-3, "role": "input"},
        {"column": "ch2", "name": "acc1", "unit": "m/s^2"}]}))
    check(features_json(p, capsys, "--channel-map", str(cmap)))


def test_dataframe_in_the_python_api() -> None:
    pd = pytest.importorskip("pandas")
    df = pd.DataFrame({"time_s": T, "force_N": FORCE, "acc1": ACC})
    df.attrs["units"] = {"acc1": "m/s^2"}
    rec = read_dataframe(df, name="df")
    assert rec.fs_hz == pytest.approx(FS) and rec.names == ["force_N", "acc1"]
    assert [c.unit for c in rec.channels] == ["N", "m/s^2"]
    assert rec.channel("force_N").role == "input"
    np.testing.assert_array_equal(rec.channel("acc1").data, ACC)
    idx = pd.to_timedelta(T, unit="s")
    rec2 = read_dataframe(pd.DataFrame({"acc1": ACC}, index=idx))
    assert rec2.fs_hz == pytest.approx(FS, rel=1e-9)
    rec3 = read_dataframe(pd.DataFrame({"acc1": ACC}), fs_hz=FS, units={"acc1": "g"})
    assert rec3.channels[0].unit == "g" and rec3.n_samples == N
    rec4 = read_dataframe(pd.DataFrame({"t": T + 2.0, "acc1": ACC}), fs_hz=FS)
    assert rec4.names == ["acc1"] and rec4.fs_hz == FS and rec4.t0_s == 2.0
    with pytest.raises(InputFileError, match="no time channel and no sampling rate"):
        read_dataframe(pd.DataFrame({"acc1": ACC}))


@pytest.mark.parametrize("name, body, what", [
    ("ragged.h5", None, "samples where the other channels have"),
    ("notime.mat", None, "no time channel and no sampling rate"),
    ("fake.uff", b"    -1\n    58\nacc\n" + b"x" * 200, "no dataset 58"),
    ("fake.mf4", b"MDF     4.10    " + bytes(200), "not a readable MDF file"),
    ("fake.h5", b"\x89HDF\r\n\x1a\n" + bytes(100), "not a readable HDF5 file"),
    ("fake.mat", b"MATLAB 5.0 MAT-file" + bytes(200), "not a readable MATLAB file"),
])
def test_damaged_formats_are_one_line(name: str, body: bytes | None, what: str, tmp_path: Path,
                                      caplog: pytest.LogCaptureFixture) -> None:
    p = tmp_path / name
    if name == "ragged.h5":
        h5py = pytest.importorskip("h5py")
        with h5py.File(p, "w") as f:
            f["time"], f["a"] = T, ACC[:-1]
    elif name == "notime.mat":
        from scipy.io import savemat

        savemat(p, {"a": ACC, "b": FORCE})
    else:
        p.write_bytes(body or b"")
    caplog.clear()
    assert main(["features", str(p)]) == 2
    errors = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert len(errors) == 1 and name in errors[0] and what in errors[0], errors


def test_truncated_uff_is_refused_not_a_lost_channel(tmp_path: Path,
                                                     caplog: pytest.LogCaptureFixture) -> None:
    """pyuff skips an unclosed last dataset: a truncated file read as one channel fewer."""
    whole = tmp_path / "whole.uff"
    write_uff(whole)
    data = whole.read_bytes()
    closing = data.rindex(b"    -1")  # the last dataset's end tag
    cuts = {"mid_data": len(data) * 3 // 4, "in_end_tag": closing + 5, "before_end_tag": closing}
    for name, cut in cuts.items():
        p = tmp_path / f"{name}.uff"
        p.write_bytes(data[:cut])
        caplog.clear()
        assert main(["features", str(p)]) == 2, name
        errors = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
        assert len(errors) == 1 and p.name in errors[0] and "not closed" in errors[0], errors
    p = tmp_path / "end_tag_kept.uff"  # cut after the end tag's '-1': nothing is lost
    p.write_bytes(data[:closing + 6])
    assert read_test(p).names == ["force", "acc1"]


# ---- CSV dialects ------------------------------------------------------------------------------
def test_csv_quoted_cells_and_preamble(tmp_path: Path) -> None:
    p = tmp_path / "q.csv"
    p.write_text("# logger: DAQ-7\n# date: 2026-11-25\n\n"
                 '"time_s","force_N","acc1_mps2"\n'
                 + "".join(f'"{i / FS!r}","{i}",{0.5 * i}\n' for i in range(10)))
    rec = read_test(p)
    assert rec.fs_hz == pytest.approx(FS) and rec.names == ["force_N", "acc1_mps2"]
    np.testing.assert_array_equal(rec.channel("force_N").data, np.arange(10.0))
    np.testing.assert_array_equal(rec.channel("acc1_mps2").data, 0.5 * np.arange(10))


def test_csv_semicolons_and_decimal_commas(tmp_path: Path) -> None:
    p = tmp_path / "eu.csv"
    rows = [f"{i / 100:.2f};{1.25 * i:.2f};-{0.5 * i:.1f}".replace(".", ",") for i in range(50)]
    p.write_text("# Messung 3\ntime_s;force_N;acc1_mps2\n" + "\n".join(rows) + "\n")
    rec = read_test(p)
    assert rec.fs_hz == pytest.approx(100.0)
    np.testing.assert_array_equal(rec.channel("force_N").data, 1.25 * np.arange(50))
    np.testing.assert_array_equal(rec.channel("acc1_mps2").data, -0.5 * np.arange(50))


@pytest.mark.parametrize("fast", [True, False])
def test_csv_errors_keep_their_line_after_a_preamble(tmp_path: Path, fast: bool,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import dynval.io.csvfile as csvfile

    if not fast:
        monkeypatch.setattr(csvfile, "_pd", None)  # numpy's block parser
    monkeypatch.setattr(csvfile, "_BLOCK_BYTES", 256)  # many blocks
    rows = [f"{i / 100};{i},5;{i}" for i in range(100)]
    rows[70] = "0,70;x;1"
    p = tmp_path / "bad.csv"
    p.write_text("# a\n# b\ntime_s;force_N;acc1\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputFileError, match=r"bad.csv:74 \(column force_N\): not a number: 'x'"):
        read_test(p)
    rows[70] = "0,7;70;1"
    rows[40] = "0,2;40;1"  # time goes back at line 44
    p.write_text("# a\n# b\ntime_s;force_N;acc1\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputFileError, match=r"bad.csv:44 \(column time_s\): time does not"):
        read_test(p)
    rows[40] = "0,4;40;1"
    p.write_text("# a\n# b\ntime_s;force_N;acc1\n" + "\n".join(rows) + "\n")
    rec = read_test(p)
    assert rec.n_samples == 100 and rec.channel("force_N").data[3] == 3.5


def test_matlab_v73_is_read_as_hdf5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A v7.3 .mat is HDF5 after a 512-byte text header (MATLAB writes column vectors n x 1)."""
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "v73.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        f["t"] = T.reshape(-1, 1)
        f["force"] = FORCE.reshape(-1, 1)
        f["force"].attrs["unit"] = "N"
        f["acc1"] = ACC.reshape(-1, 1)
        f["acc1"].attrs["unit"] = "m/s^2"
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Wed Nov 25 2026 HDF5 schema")
    check(features_json(p, capsys))


def test_damaged_mdf_is_one_stderr_line_in_a_real_run(tmp_path: Path) -> None:
    """asammdf's half-built MDF4 fails in its destructor too: that must not reach stderr."""
    import os
    import subprocess
    import sys

    import dynval

    good = tmp_path / "t.mf4"
    write_mdf(good)
    bad = tmp_path / "bad.mf4"
    bad.write_bytes(good.read_bytes()[:3000])
    env = {**os.environ, "PYTHONPATH": str(Path(dynval.__file__).parents[1])}
    r = subprocess.run([sys.executable, "-m", "dynval", "features", str(bad)], env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.mf4: not a readable MDF file" in lines[0], r.stderr


def test_hdf5_contiguous_datasets_are_memory_mapped(tmp_path: Path) -> None:
    """Issue 21: a contiguous float dataset is mapped (a long record is read page by page as it
    is used), at the file's offsets of the data (a 512-byte user block before them here); a
    compressed (chunked) one and an integer one are read into memory. The same samples."""
    from dynval.io.arrays import mapped

    h5py = pytest.importorskip("h5py")
    p = tmp_path / "t.h5"
    with h5py.File(p, "w", userblock_size=512) as f:
        f.attrs["fs_hz"] = FS
        f.create_dataset("force_N", data=FORCE)
        f.create_dataset("acc1_mps2", data=ACC, compression="gzip")
        f.create_dataset("acc2_mps2", data=(1000 * ACC).astype(np.int32))
        f.create_dataset("acc3_mps2", data=ACC.astype(">f8"))
    rec = read_test(p)
    assert {c.name: mapped(c.data) for c in rec.channels} == {
        "force_N": True, "acc1_mps2": False, "acc2_mps2": False,
        "acc3_mps2": False}  # big-endian: mapped, then converted into memory
    assert np.array_equal(rec.channel("force_N").data, FORCE)
    assert np.array_equal(rec.channel("acc1_mps2").data, ACC)
    assert np.array_equal(rec.channel("acc2_mps2").data, (1000 * ACC).astype(np.int32))
    assert np.array_equal(rec.channel("acc3_mps2").data, ACC)
    rec.channel("force_N").data[0] = 7.0  # copy-on-write: the file keeps its sample
    assert np.array_equal(read_test(p).channel("force_N").data, FORCE)
