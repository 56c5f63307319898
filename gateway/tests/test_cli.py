"""The CLI: `dynval features` on good and bad files, exit codes and one-line errors."""
from __future__ import annotations

import importlib
import json
import logging
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


def test_a_dead_or_constant_channel_has_its_undefined_features_null(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """An all-zero channel (a sensor recorded but not wired) has no central time, RMS
    duration, skew, kurtosis or crest factor, a constant one no skew or kurtosis: null in
    the JSON and n/a in the table, with a warning naming the file and channel; the file's
    other channels as usual (the core's DV_ENUMERIC failed the whole file before)."""
    p = write(tmp_path, "time_s,force_N,acc1_mps2,acc2_mps2\n" + "".join(
        f"{i / 100:.2f},0,2.5,{(i % 5) * 0.5}\n" for i in range(200)))
    assert main(["features", "--json", str(p)]) == 0
    res = json.loads(capsys.readouterr().out)["channels"]
    dead, const, live = res["force_N"], res["acc1_mps2"], res["acc2_mps2"]
    assert [dead[k] for k in ("energy", "rms", "peak")] == [0.0, 0.0, 0.0]
    assert all(dead[k] is None for k in ("central_time", "rms_duration", "skew", "kurt", "crest"))
    assert const["skew"] is None and const["kurt"] is None and const["crest"] == 1.0
    assert const["central_time"] == pytest.approx(0.995)  # the middle of 0..1.99 s
    assert all(live[k] is not None for k in ("skew", "kurt", "crest", "central_time"))
    assert any(f"{p}: channel force_N: every sample is 0" in r.getMessage()
               for r in caplog.records if r.levelname == "WARNING")
    assert main(["features", str(p)]) == 0
    assert capsys.readouterr().out.splitlines()[2].split()[-2:] == ["n/a", "n/a"]


# a one-DOF model driven by force_N, measured by acc1_mps2
ONE_DOF = {"format": "dynval-model/1", "masses_kg": [1.0], "stiffness_n_per_m": [1e4],
           "damping": {"type": "modal", "zeta": [0.02]},
           "input": {"kind": "force", "dof": 1, "channel": "force_N"},
           "outputs": {"acc1_mps2": {"kind": "acc", "dof": 1}}}


def test_residual_of_a_channel_measured_as_zero_is_null_not_nan(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """A model output measured as zero throughout (a sensor not wired): its RMSE is the
    prediction's RMS, its NRMSE undefined: null in the JSON (NaN was written, which strict
    JSON readers refuse) and n/a in the table, with a warning naming the file and channel."""
    model = write(tmp_path, json.dumps(ONE_DOF), "m.json")
    p = write(tmp_path, "time_s,force_N,acc1_mps2\n" + "".join(
        f"{i / 100:.2f},{(i % 7) - 3},0\n" for i in range(200)))
    assert main(["residual", "--json", str(model), str(p)]) == 0

    def refuse(name: str) -> None:
        raise ValueError(name)

    ch = json.loads(capsys.readouterr().out, parse_constant=refuse)["tests"][0]["channels"]
    v = ch["acc1_mps2"]
    assert v["nrmse"] is None and v["rms_measured"] == 0.0 and v["rmse"] > 0
    assert any(f"{p}: channel acc1_mps2 is measured as zero throughout" in r.getMessage()
               for r in caplog.records if r.levelname == "WARNING")
    assert main(["residual", str(model), str(p)]) == 0
    assert capsys.readouterr().out.splitlines()[-1].split()[3] == "n/a"


def test_residual_refusing_a_lenient_records_missing_input_names_the_file(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A missing input sample kept by --lenient: the band-limited interpolation cannot run,
    and the one-line error names the file (it named none)."""
    model = write(tmp_path, json.dumps(ONE_DOF), "m.json")
    p = write(tmp_path, "time_s,force_N,acc1_mps2\n" + "".join(
        f"{i / 100:.2f},{'nan' if i == 50 else (i % 7) - 3},{i % 3}\n" for i in range(200)))
    assert main(["residual", "--lenient", str(model), str(p)]) == 2
    (err,) = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert err.startswith(f"{p}: the input has 1 non-finite samples")
    assert "--oversample 1" in err and "\n" not in err


@pytest.mark.parametrize("text, where, what", [
    ("", ":1", "empty file"),
    ("time_s,force_N\n0,1\n0.01,abc\n0.02,3\n", ":3 (column force_N)", "not a number"),
    ("time_s,force_N\n0,1\n0.01,nan\n0.02,3\n", ":3 (column force_N)", "non-finite"),
    ("time_s,force_N\n0,1\n0.01,2\n0.005,3\n", ":4 (column time_s)",
     "does not increase (0.01 then 0.005)"),  # numbers as written, no numpy reprs
    ("time_s,force_N\n0,1\n0.01,2\n0.02,3\n0.05,4\n0.06,5\n", ":5 (column time_s)",
     "irregular sampling: step 0.03 s where the period is 0.01 s"),
    ("time_s,force_N,acc1_mps2\n0,1,2\n0.01,2,3\n0.02,3", ":4", "truncated"),
    ("1,2\n3,4\n", ":1", "header"),
    # a binary file read as text: its 'header' escaped and cut, on one line
    ("\x01\x82garbage\x1b[2J" + "x" * 200 + ",y\n0,1\n", ":1",
     "found '\\x01\\x82garbage\\x1b[2J" + "x" * 18 + "...' (not a CSV text file?)"),
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
    assert main(["features", str(tmp_path / "nope.csv")]) == 2  # bad input
    assert main([]) == 64  # a usage error (sysexits EX_USAGE), not bad data


def test_usage_errors_are_64_and_third_party_info_is_quiet(
        tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["features", "--no-such-option", "x.csv"])
    assert e.value.code == 64 and "usage: dynval" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["simulate"])  # missing arguments
    assert e.value.code == 64
    p = write(tmp_path, "time_s,force_N\n0,1\n0.01,2\n0.02,3")
    assert main(["features", str(p)]) == 0
    logging.getLogger("numexpr.utils").info("NumExpr defaulting to 2 threads.")
    assert not [r for r in caplog.records if r.name.startswith("numexpr")]


@pytest.mark.parametrize("argv, what", [
    (["validate", "--level", "1.5"], "--level: must be in (0, 1): 1.5"),
    (["validate", "--seed", "-1"], "--seed: must be >= 0: -1"),
    (["validate", "--workers", "-1"], "--workers: must be >= 0: -1"),
    (["validate", "--runs", "-5"], "--runs: must be >= 1: -5"),
    (["calibrate", "--steps", "0"], "--steps: must be >= 1: 0"),
    (["calibrate", "--oversample", "x"], "--oversample: not an integer: 'x'"),
    # silently wrapped into the DV_CTRL frame's u32, or accepted and meaningless, before
    (["replay", "--record-id", "-1"], "--record-id: must be 0..4294967295: -1"),
    (["discover", "--min-gain", "-1"], "--min-gain: must be in [0, 1): -1"),
    (["discover", "--max-effects", "-1"], "--max-effects: must be >= 0: -1"),
    (["features", "--seg-len", "0"], "--seg-len: must be >= 2: 0"),  # a ZeroDivisionError
    (["features", "--fs", "nan"], "--fs: must be in (0, inf): nan"),
    (["log", "--chunk-kb", "0"], "--chunk-kb: must be >= 1: 0"),
    (["run", "--win", "0"], "--win: must be >= 1: 0"),
])
def test_out_of_range_options_are_usage_errors(
        argv: list[str], what: str, capsys: pytest.CaptureFixture[str]) -> None:
    """The study's were internal errors (exit 3, 'a bug in dynval') deep in it: numpy's
    percentile, a process pool, a seed or an array size refused them."""
    rest = {"validate": ["--model", "m.json", "--experiments", "t.csv", "--features", "rms"],
            "discover": ["m.json", "t.csv"], "run": ["-o", "x.mcap", "m.json", "t.csv"],
            "log": ["-o", "x.mcap"]}
    rest["calibrate"] = rest["validate"]
    with pytest.raises(SystemExit) as e:
        main([*argv, *rest.get(argv[0], ["t.csv"])])
    assert e.value.code == 64 and what in capsys.readouterr().err


@pytest.mark.parametrize("command", ["discover", "validate"])
def test_an_output_that_cannot_be_written_is_refused_before_the_work(
        command: str, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """discover wrote its reports after the whole run and only then failed on a missing
    folder; now the paths are checked first (the model is not even read here)."""
    out = tmp_path / "no" / "r.json"
    argv = {"discover": ["discover", "--json", str(out), "m.json", "t.csv"],
            "validate": ["validate", "--json", str(out), "--model", "m.json",
                         "--experiments", "t.csv", "--features", "rms"]}[command]
    assert main(argv) == 2
    msgs = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert msgs == [f"{out}: cannot write: no folder {out.parent}"]


def test_real_data_file(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = shared_data / "synthetic" / "lanl4dof-clean" / "test_high_01.csv"
    assert main(["features", "--json", str(f)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["n_samples"] == 8192 and res["fs_hz"] == pytest.approx(640.0)
    # the declared force level is 12 N RMS (meta.json); 1 % sensor noise on top
    assert res["channels"]["force_N"]["rms"] == pytest.approx(12.0, rel=0.05)


# ---- one way to read tests, on every command ------------------------------------------------
TEST_READING = ("features", "simulate", "residual", "replay", "log", "run", "discover",
                "validate", "calibrate")
MINIMAL_ARGS = {"features": ["t.csv"], "simulate": ["m.json", "t.csv", "-o", "p.csv"],
                "residual": ["m.json", "t.csv"], "replay": ["t.csv"], "log": ["-o", "x.mcap"],
                "run": ["t.csv", "-o", "out"], "discover": ["m.json", "t.csv"],
                "validate": ["--model", "m.json", "--experiments", "t.csv", "--features", "rms"],
                "calibrate": ["--model", "m.json", "--experiments", "t.csv", "--features",
                              "rms"]}


def test_every_command_but_inspect_recover_and_convert_reads_tests() -> None:
    from dynval.cli import COMMANDS

    assert set(COMMANDS) - set(TEST_READING) == {"inspect", "recover", "convert"}


@pytest.mark.parametrize("cmd", TEST_READING)
def test_every_test_reading_command_takes_the_shared_options(cmd: str) -> None:
    from dynval.cli import build_parser

    args = build_parser().parse_args([cmd, *MINIMAL_ARGS[cmd], "--channel-map", "map.yaml",
                                      "--lenient", "--fs", "100"])
    assert args.channel_map == Path("map.yaml") and args.lenient and args.fs == 100.0


def test_residual_discover_and_validate_read_the_same_files_of_a_folder(
        tmp_path: Path, shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A folder with the model, its metadata and tests of several formats: every command that
    takes a model and tests reads the same tests (io.collect_tests, the model left out)."""
    import shutil

    from dynval import cli_common
    from dynval.errors import ConfigError

    model = tmp_path / "declared_model.json"
    shutil.copy(shared_data / "synthetic" / "lanl4dof-clean" / "declared_model.json", model)
    for name in ("b.csv", "a.json", "c.mcap", "d.txt", "meta.json", "run1_meta.json",
                 "notes.md"):
        (tmp_path / name).write_text("")
    (tmp_path / "sub.csv").mkdir()  # a folder is not a test
    read: dict[str, list[str]] = {}
    real = cli_common.read_tests

    def spy(*a: object, **kw: object) -> None:
        real(*a, **kw)  # collect and read (read_test records the names)
        raise ConfigError("stop here")

    for cmd, argv in (("residual", ["residual", str(model), str(tmp_path)]),
                      ("discover", ["discover", str(model), str(tmp_path)]),
                      ("validate", ["validate", "--model", str(model), "--experiments",
                                    str(tmp_path), "--features", "rms"])):
        seen = read.setdefault(cmd, [])
        monkeypatch.setattr(cli_common, "read_test", lambda p, seen=seen, **kw: seen.append(p.name))
        for mod in (cli_common, importlib.import_module(f"dynval.cmd_{cmd}")):
            monkeypatch.setattr(mod, "read_tests", spy, raising=False)
        assert main(argv) == 2
    assert read == {c: ["a.json", "b.csv", "c.mcap", "d.txt"]
                    for c in ("residual", "discover", "validate")}


def test_a_folder_without_tests_and_a_missing_path_are_one_line_errors(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "meta.json").write_text("{}")
    for argv, what in ((["residual", "m.json", str(tmp_path)], "folder holds no tests"),
                       (["features", str(tmp_path / "nope")], "no such file")):
        caplog.clear()
        assert main(argv) == 2
        msgs = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
        assert len(msgs) == 1 and what in msgs[0]


# ---- the core is loaded lazily ----------------------------------------------------------------
_HIDDEN = """
import sys
from pathlib import Path
import dynval._core as core
core._LIB_DIR = Path(sys.argv[1])
from dynval.cli import main
code = main(sys.argv[2:])
assert "ffi" not in core._loaded and "lib" not in core._loaded
sys.exit(code)
"""


@pytest.mark.parametrize("argv", [["--help"], ["features", "--help"], ["run", "--help"],
                                  ["discover", "--help"]])
def test_help_works_with_the_core_hidden(tmp_path: Path, argv: list[str]) -> None:
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", _HIDDEN, str(tmp_path), *argv],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "usage: dynval" in r.stdout and r.stderr == ""


@pytest.mark.parametrize("cmd", TEST_READING)
def test_a_missing_core_is_one_line_and_exit_2(tmp_path: Path, cmd: str) -> None:
    import subprocess
    import sys

    (tmp_path / "t.csv").write_text(GOOD)
    # a valid model, so that the command gets as far as needing the core
    (tmp_path / "m.json").write_text(json.dumps(
        {**ONE_DOF, "stiffness_n_per_m": [1000.0], "fs_hz": 100.0}))
    argv = [cmd, *(a if a not in ("t.csv", "m.json") else str(tmp_path / a)
                   for a in MINIMAL_ARGS[cmd])]
    if cmd == "log":
        argv += ["--test", str(tmp_path / "t.csv"), "--bus", "virtual"]
    if cmd in ("replay", "run"):
        argv += ["--bus", "virtual"]
    lib = tmp_path / "no_lib"
    lib.mkdir()
    r = subprocess.run([sys.executable, "-c", _HIDDEN.replace('assert "ffi"', '# "ffi"'),
                        str(lib), *argv], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "not installed" in lines[0] and str(lib) in lines[0], r.stderr


def test_inspect_prints_words_not_python_reprs(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 18: 'fs 639.9999999998545 Hz' and a raw status dict leaked into inspect."""
    from dynval import bus
    from dynval.mcap_log import McapLog

    p = tmp_path / "x.mcap"
    with McapLog(p, meta={"fs_hz": "639.9999999998545", "test": "t"}) as log:
        # DV_STATUS: state recording | observer on, beat 7, lost 2 (u16), dup 0, late 1
        log.on_frame(1_000, bus.ID_STATUS, bytes([0x03, 7, 2, 0, 0, 1, 0, 0]))
    capsys.readouterr()
    assert main(["inspect", str(p)]) == 0
    out = capsys.readouterr().out
    assert "fs 640 Hz," in out
    assert "last DV_STATUS: recording, obs on (state 0x03), beat 7, lost 2, dup 0, late 1" in out
    assert "{" not in out and "np." not in out


@pytest.mark.parametrize("name", ["libdynval-f64.so.0", "libdynval-f64.dylib", "dynval-f64.dll",
                                  "libdynval-f64.dll"])
def test_the_core_is_looked_for_under_each_platforms_name(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    """Linux, macOS and Windows names of the shared library are found (an empty file here:
    found, then refused by the loader, naming it)."""
    import shutil

    import dynval._core as core
    from dynval.errors import CoreNotBuiltError

    for cdef in core._LIB_DIR.glob("*_cdef.h"):  # the declarations the FFI needs
        shutil.copy(cdef, tmp_path)
    (tmp_path / name).write_bytes(b"")
    monkeypatch.setattr(core, "_LIB_DIR", tmp_path)
    with pytest.raises(CoreNotBuiltError, match=rf"{name}: cannot load"):
        core._dlopen("dynval-f64")
