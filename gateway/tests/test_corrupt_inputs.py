"""Malformed input of every reader, through the CLI in-process (cli.main): a corpus generated
here (truncated, bit-flipped, foreign, oversized, non-UTF-8, deeply nested files for the CSV,
whitespace text, DROPBEAR text, BRFD JSON, MCAP, UFF 58, MDF 4, HDF5, MATLAB, model and
channel-map readers; the CSV also as ';' with decimal commas after a '#' preamble) must give
exit 2 and one error line naming the file, or exit 0 with finite numbers: never a traceback,
an internal error or a hang. Plus property tests of the readers (hypothesis)."""
from __future__ import annotations

import json
import logging
import math
import random
import signal
import struct
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval import cli

REPO = Path(__file__).resolve().parents[2]
DECLARED = REPO / "data" / "lanl4dof-sim" / "clean" / "declared_model.json"
CASE_TIMEOUT_S = 20  # a case that takes longer hangs
COLUMNS = ("time_s", "force_N", "acc1_mps2", "acc2_mps2", "acc3_mps2", "acc4_mps2")


@contextmanager
def deadline(seconds: int) -> Iterator[None]:
    def fail(*_: object) -> None:
        raise TimeoutError(f"no answer within {seconds} s (a hang)")

    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@dataclass
class Outcome:
    rc: int
    errors: list[logging.LogRecord]
    stdout: str


def run_cli(argv: list[str], caplog: pytest.LogCaptureFixture,
            capsys: pytest.CaptureFixture[str]) -> Outcome:
    caplog.clear()
    capsys.readouterr()
    with caplog.at_level(logging.INFO), deadline(CASE_TIMEOUT_S):
        rc = cli.main(argv)
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    return Outcome(rc, errors, capsys.readouterr().out)


def assert_clean(out: Outcome, path: Path, *, must_fail: bool) -> None:
    """Exit 2 with one error line naming the file, or (unless must_fail) exit 0; never an
    internal error or a traceback; exit 0 output holds finite numbers only."""
    msgs = [r.getMessage() for r in out.errors]
    assert all(r.exc_info is None for r in out.errors), msgs
    assert not any("internal error" in m for m in msgs), msgs
    if out.rc == 2:
        assert len(msgs) == 1 and "\n" not in msgs[0], msgs
        assert path.name in msgs[0], msgs
        return
    assert not must_fail, f"exit {out.rc} for a malformed {path.name}: {out.stdout[:200]}"
    assert out.rc == 0, (out.rc, msgs)
    if out.stdout.lstrip().startswith("{"):
        assert_finite(json.loads(out.stdout))


def assert_finite(x: Any) -> None:
    if isinstance(x, dict):
        for v in x.values():
            assert_finite(v)
    elif isinstance(x, list):
        for v in x:
            assert_finite(v)
    elif isinstance(x, float):
        assert np.isfinite(x), x


# ---- valid seeds -------------------------------------------------------------------------------
def csv_text(n: int = 200, seed: int = 1) -> str:
    rng = np.random.default_rng(seed)
    rows = [",".join(COLUMNS)]
    for i in range(n):
        rows.append(",".join([f"{i / 640:.7f}", *(f"{v:.6g}" for v in rng.normal(size=5))]))
    return "\n".join(rows) + "\n"


def brfd_text(n: int = 64) -> str:
    rows = [[i / 1024, 0.1 * np.sin(i / 5), 0.2 * np.cos(i / 7), 0.3, 4.0 + i, 5.0]
            for i in range(n)]
    return json.dumps({"data": rows, "dt": 1 / 1024, "sampling freq": 1024,
                       "displacement units": "in", "friction force units": "kip",
                       "actuator force units": "lb"})


DROPBEAR_HEAD = ["C:\\x\\test0.txt", "Programmer - None", "Striker Velocity - 0.001",
                 "Sampling Frequency - 5000", "Mon, Jun 6, 2022 11:17 AM",
                 "Low G Accel\tAccel\tPinLoc\tTime",
                 "Voltage (unscaled)\tVoltage (unscaled)\tVoltage (unscaled)\tSec",
                 "0.0 0.0 0\t\t\t", ""]


def dropbear_text(n: int = 40) -> str:
    rows = [f"{0.01 * i:.5E}\t{0.02 * (i % 3):.5E}\t1.2\t{i * 2e-4:.5E}" for i in range(n)]
    return "\n".join(DROPBEAR_HEAD + rows) + "\n"


def whitespace_text(n: int = 100) -> str:
    rng = np.random.default_rng(2)
    return "\n".join(" ".join(f"{v:.5g}" for v in r) for r in rng.normal(size=(n, 5))) + "\n"


def model_text() -> str:
    return json.dumps({
        "format": "dynval-model/1", "masses_kg": [6.54, 6.66, 6.86, 6.8],
        "stiffness_n_per_m": [10.0, 399790.0, 399790.0, 399790.0],
        "damping": {"type": "modal", "zeta": [0.01, 0.05, 0.01, 0.01]},
        "input": {"kind": "force", "dof": 1, "channel": "force_N"},
        "outputs": {f"acc{i}_mps2": {"kind": "acc", "dof": i} for i in range(1, 5)},
        "elements": [{"type": "contact", "between": [3, 4], "gap_m": 1e-4, "kb_n_per_m": 1e6}],
        "simulation": {"substeps": 4, "oversample": 1}}, indent=1)


def cmap_text() -> str:
    return json.dumps({"channels": [{"column": "force_N", "role": "input"},
                                    {"column": "acc1_mps2", "scale": 2.0, "dof": 1}]})


def _uff(p: Path) -> None:
    pyuff = pytest.importorskip("pyuff")
    rng = np.random.default_rng(4)
    pyuff.UFF(str(p)).write_sets([pyuff.prepare_58(
        binary=0, func_type=1, rsp_node=k + 1, rsp_dir=3, ref_node=1, ref_dir=3, ord_data_type=4,
        id1=name, abscissa_spacing=1, abscissa_inc=1 / 640, abscissa_min=0.0,
        data=rng.normal(size=200), x=np.arange(200) / 640, ordinate_axis_units_lab=unit,
        ordinate_spec_data_type=spec, abscissa_spec_data_type=17, abscissa_axis_units_lab="s",
        orddenom_spec_data_type=0, z_axis_spec_data_type=0)
        for k, (name, spec, unit) in enumerate((("force", 13, "N"), ("acc1", 12, "m/s^2")))],
        mode="overwrite")


def _mdf(p: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    t = np.arange(200) / 640
    rng = np.random.default_rng(5)
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(rng.normal(size=200), t, name=n, unit=u)
                for n, u in (("force", "N"), ("acc1", "m/s^2"))])
    mdf.save(p, overwrite=True)
    mdf.close()


def _h5(p: Path) -> None:
    h5py = pytest.importorskip("h5py")
    rng = np.random.default_rng(6)
    with h5py.File(p, "w") as f:
        f["time_s"] = np.arange(200) / 640
        f["force_N"] = rng.normal(size=200)
        f["acc1"] = rng.normal(size=200)
        f["acc1"].attrs["unit"] = "m/s^2"


def _mat(p: Path) -> None:
    from scipy.io import savemat

    rng = np.random.default_rng(7)
    savemat(p, {"fs": 640.0, "force_N": rng.normal(size=200), "acc1_mps2": rng.normal(size=200)})


FORMAT_WRITERS: dict[str, Callable[[Path], None]] = {"uff": _uff, "mdf": _mdf, "h5": _h5,
                                                     "mat": _mat}
FORMAT_SUFFIX = {"uff": ".uff", "mdf": ".mf4", "h5": ".h5", "mat": ".mat"}


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("seeds")
    out = {"csv": d / "ok.csv", "brfd": d / "ok.json", "dropbear": d / "drop.txt",
           "text": d / "ws.txt", "model": d / "model.json", "cmap": d / "map.json"}
    out["csv"].write_text(csv_text())
    out["brfd"].write_text(brfd_text())
    out["dropbear"].write_text(dropbear_text())
    out["text"].write_text(whitespace_text())
    out["model"].write_text(model_text())
    out["cmap"].write_text(cmap_text())
    for name, write in FORMAT_WRITERS.items():
        out[name] = d / f"ok{FORMAT_SUFFIX[name]}"
        write(out[name])
    out["csv_eu"] = d / "eu.csv"
    out["csv_eu"].write_text("# preamble\n" + csv_text().replace(",", ";").replace(".", ","))
    logdir = d / "log"
    assert cli.main(["-q", "run", str(out["csv"]), "-o", str(logdir), "--bus", "virtual",
                     "--asap", "--no-model"]) == 0
    out["mcap"] = next(logdir.glob("*.mcap"))
    return out


# ---- mutations ---------------------------------------------------------------------------------
Mutation = Callable[[bytes, random.Random], bytes]


def truncate(frac: float) -> Mutation:
    return lambda b, _r: b[: max(1, int(len(b) * frac))]


def flip_bits(n: int) -> Mutation:
    def f(b: bytes, r: random.Random) -> bytes:
        a = bytearray(b)
        for _ in range(n):
            i = r.randrange(len(a))
            a[i] ^= 1 << r.randrange(8)
        return bytes(a)
    return f


def splice(junk: bytes) -> Mutation:
    def f(b: bytes, r: random.Random) -> bytes:
        i = r.randrange(len(b) // 4, len(b))
        return b[:i] + junk + b[i:]
    return f


def replace_with(blob: bytes) -> Mutation:
    return lambda _b, _r: blob


FOREIGN = {"empty": b"", "png": b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4,
           "zeros": bytes(4096), "random": random.Random(7).randbytes(4096),
           "nested": b"[" * 100_000 + b"]" * 100_000,
           "nested_obj": b'{"data": ' + b"[" * 50_000 + b"]" * 50_000 + b"}",
           "bigint": b'{"data": [[0, ' + b"9" * 5000 + b", 0, 0, 0, 0]]}",
           "latin1": "Accélération,x\n1,2\n".encode("latin-1")}

COMMON: dict[str, Mutation] = {
    **{f"truncate_{int(f * 100)}": truncate(f) for f in (0.01, 0.3, 0.77, 0.999)},
    **{f"flip{n}_{k}": flip_bits(n) for n in (1, 8) for k in range(4)},
    "latin1_bytes": splice("é\xff".encode("latin-1")),
    "nul_bytes": splice(b"\x00" * 16),
    "long_line": splice(b"1" * 300_000),
    "huge_number": splice(b"1e999"),
    "long_digits": splice(b"9" * 5000),
    **{f"foreign_{k}": replace_with(v) for k, v in FOREIGN.items()},
}
# mutations that cannot leave a valid file behind (exit 2 required)
MUST_FAIL = {"foreign_empty", "foreign_png", "foreign_zeros", "foreign_random", "foreign_nested",
             "foreign_nested_obj", "foreign_bigint", "latin1_bytes", "foreign_latin1",
             "truncate_1"}

# reader -> (seed name, file suffix, argv builder(path, seeds, tmp))
Argv = Callable[[Path, dict[str, Path], Path], list[str]]
READERS: dict[str, tuple[str, str, Argv]] = {
    "csv": ("csv", ".csv", lambda p, s, t: ["features", str(p), "--json"]),
    "brfd": ("brfd", ".json", lambda p, s, t: ["features", str(p), "--json"]),
    "dropbear": ("dropbear", ".txt", lambda p, s, t: ["features", str(p), "--json"]),
    "text": ("text", ".txt", lambda p, s, t: ["features", str(p), "--json", "--fs", "100"]),
    "csv_eu": ("csv_eu", ".csv", lambda p, s, t: ["features", str(p), "--json"]),
    **{k: (k, FORMAT_SUFFIX[k], lambda p, s, t: ["features", str(p), "--json"])
       for k in FORMAT_WRITERS},
    "mcap": ("mcap", ".mcap", lambda p, s, t: ["features", str(p), "--json"]),
    "mcap_inspect": ("mcap", ".mcap", lambda p, s, t: ["inspect", str(p), "--json"]),
    "model": ("model", ".json", lambda p, s, t: ["simulate", str(p), str(s["csv"]), "-o",
                                                 str(t / "pred.csv")]),
    "cmap": ("cmap", ".json", lambda p, s, t: ["features", str(s["csv"]), "--json",
                                               "--channel-map", str(p)]),
}
CASES = [(reader, name) for reader in READERS for name in COMMON]


@pytest.mark.parametrize("reader, mutation", CASES, ids=[f"{a}-{b}" for a, b in CASES])
def test_corrupt_file_is_one_line_or_a_right_answer(
        reader: str, mutation: str, seeds: dict[str, Path], tmp_path: Path,
        caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]) -> None:
    seed, suffix, argv = READERS[reader]
    rnd = random.Random(f"{reader}/{mutation}")
    p = tmp_path / f"bad_{mutation}{suffix}"
    p.write_bytes(COMMON[mutation](seeds[seed].read_bytes(), rnd))
    out = run_cli(argv(p, seeds, tmp_path), caplog, capsys)
    # inspect reports a damaged or footer-less log (its job: exit 0, "NO FOOTER")
    reports = reader == "mcap_inspect" and not mutation.startswith("foreign")
    assert_clean(out, p, must_fail=mutation in MUST_FAIL and not reports)


# ---- the cases the issue found, one each -------------------------------------------------------
def _model(**changes: Any) -> dict[str, Any]:
    d: dict[str, Any] = json.loads(model_text())
    d.update(changes)
    return d


def _csv_with(cell: str, row: int = 50, col: int = 3) -> str:
    lines = csv_text().splitlines()
    cells = lines[row].split(",")
    cells[col] = cell
    lines[row] = ",".join(cells)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("name, model, what", [
    ("typo", _model(element=[]), "did you mean 'elements'"),
    ("typo_nested", _model(simulation={"substep": 4}), "did you mean 'substeps'"),
    ("ragged", _model(damping={"type": "matrix", "c_n_s_per_m": [[1, 0, 0, 0], [0, 1, 0],
                                                                 [0, 0, 1, 0], [0, 0, 0, 1]]}),
     "c_n_s_per_m[1]"),
    ("diverged", _model(elements=[{"type": "vv_damper", "between": [3, 4],
                                   "c2_n_s2_per_m2": 1e8}], simulation={"oversample": 1}),
     "elements[0] (vv_damper, c2_n_s2_per_m2 = 1e+08)"),
    ("huge_mass", _model(masses_kg=[10 ** 400, 1, 1, 1]), "masses_kg[0]"),
    # finite and > 0, but 1e200 times lighter than the others: the core's modal arithmetic
    # refuses it (a bare "refused by the core's check" named no field before)
    ("tiny_mass", _model(masses_kg=[6.5, 1e-200, 6.8, 6.8]), "masses_kg[1]': 1e-200 is out"),
])
def test_model_errors_name_the_field(name: str, model: dict[str, Any], what: str,
                                     seeds: dict[str, Path], tmp_path: Path,
                                     caplog: pytest.LogCaptureFixture,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"{name}.json"
    p.write_text(json.dumps(model))
    for cmd in (["simulate", str(p), str(seeds["csv"]), "-o", str(tmp_path / "o.csv")],
                ["residual", str(p), str(seeds["csv"])]):
        out = run_cli(cmd, caplog, capsys)
        assert_clean(out, p, must_fail=True)
        assert what in out.errors[0].getMessage()
    assert not (tmp_path / "o.csv").exists()


def test_non_utf8_model_is_one_line(seeds: dict[str, Path], tmp_path: Path,
                                    caplog: pytest.LogCaptureFixture,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "m.json"
    p.write_bytes(model_text().replace("force_N", "forcé").encode("latin-1"))
    out = run_cli(["simulate", str(p), str(seeds["csv"]), "-o", str(tmp_path / "o.csv")],
                  caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert "not UTF-8" in out.errors[0].getMessage()


def test_features_drop_and_count_a_sample_beyond_the_core_range(
        tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "one_1e200.csv"
    p.write_text(_csv_with("1e200"))
    out = run_cli(["features", str(p), "--json"], caplog, capsys)
    assert out.rc == 0
    row = json.loads(out.stdout)["channels"]["acc2_mps2"]
    assert row["dropped_out_of_range"] == 1 and row["count"] == 199
    assert all(math.isfinite(v) for v in row.values() if isinstance(v, float))
    assert any("beyond the features' range" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("name, text, what", [
    ("time_only", "time_s\n0\n0.1\n0.2\n", "no channel columns"),
    ("spans_1e308", "time_s,acc1_mps2\n0,1e308\n0.1,-1e308\n", "no sample within the features"),
    ("zero_step", "time_s,a\n0,1\n0,2\n", "time does not increase"),
    ("tiny_step", "time_s,a\n0,1\n1e-300,2\n2e-300,3\n", "not a usable sample period"),
])
def test_features_on_degenerate_csv(name: str, text: str, what: str, tmp_path: Path,
                                    caplog: pytest.LogCaptureFixture,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"{name}.csv"
    p.write_text(text)
    out = run_cli(["features", str(p), "--json"], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert what in out.errors[0].getMessage()


def test_simulate_reads_an_mcap_test(seeds: dict[str, Path], tmp_path: Path,
                                     caplog: pytest.LogCaptureFixture,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    out_csv = tmp_path / "pred.csv"
    out = run_cli(["simulate", str(seeds["model"]), str(seeds["mcap"]), "-o", str(out_csv)],
                  caplog, capsys)
    assert out.rc == 0, [r.getMessage() for r in out.errors]
    pred = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert pred.shape == (200, 6) and np.isfinite(pred).all()
    assert out_csv.read_text().splitlines()[0].startswith("time_s,force_N,acc1_mps2")


@pytest.mark.parametrize("name, peak, what", [("denormal", 5e-324, "peaks at 4.94e-324"),
                                              ("float32_overflow", 1e39, "peaks at 1e+39"),
                                              ("float32_edge", 3e38, "peaks at 3e+38")])
def test_replay_refuses_a_channel_the_bus_cannot_carry(
        name: str, peak: float, what: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"{name}.csv"
    p.write_text("time_s,force_N,acc1_mps2\n" + "".join(
        f"{i / 640},{peak if i % 2 else 0},{0.1 * i}\n" for i in range(64)))
    out = run_cli(["replay", str(p), "--bus", "virtual", "--asap"], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert what in out.errors[0].getMessage() and "force_N" in out.errors[0].getMessage()


def test_run_enforces_the_models_channels(seeds: dict[str, Path], tmp_path: Path,
                                          caplog: pytest.LogCaptureFixture,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    m = _model(outputs={"acc2_mps2": {"kind": "acc", "dof": 1}}, elements=[])
    p = tmp_path / "m.json"
    p.write_text(json.dumps(m))
    out = run_cli(["run", str(seeds["csv"]), "-o", str(tmp_path / "o"), "--bus", "virtual",
                   "--asap", "--model", str(p)], caplog, capsys)
    assert out.rc == 2
    msg = out.errors[0].getMessage()
    assert "acc1_mps2" in msg and "as the acceleration of DOF 1" in msg and "not an output" in msg


@pytest.mark.parametrize("name, make, what", [
    ("zero_force", lambda t: t.replace_col("force_N", 0.0), "zero throughout"),
    ("three_rows", lambda t: t.head(3), "at least 64 samples"),
    ("one_1e308", lambda t: t.set(50, "acc2_mps2", 1e308), "beyond what discover"),
])
def test_discover_guards(name: str, make: Callable[[Any], str], what: str,
                         tmp_path: Path, caplog: pytest.LogCaptureFixture,
                         capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"{name}.csv"
    p.write_text(make(_Table(csv_text())))
    out = run_cli(["discover", str(DECLARED), str(p)], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert what in out.errors[0].getMessage()


def test_discover_huge_element_coefficient(seeds: dict[str, Path], tmp_path: Path,
                                           caplog: pytest.LogCaptureFixture,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "m.json"
    p.write_text(json.dumps(_model(elements=[{"type": "cubic_spring", "between": [3, 4],
                                              "k3_n_per_m3": 1e200}])))
    out = run_cli(["discover", str(p), str(seeds["csv"])], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert "elements[0] (cubic_spring, k3_n_per_m3 = 1e+200)" in out.errors[0].getMessage()


def test_run_refuses_a_mass_beyond_binary32(seeds: dict[str, Path], tmp_path: Path,
                                            caplog: pytest.LogCaptureFixture,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "m.json"
    p.write_text(json.dumps(_model(masses_kg=[1e39, 6.66, 6.86, 6.8], elements=[])))
    out = run_cli(["run", str(seeds["csv"]), "-o", str(tmp_path / "o"), "--bus", "virtual",
                   "--asap", "--model", str(p)], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert "'masses_kg[0]': 1e+39 is beyond the firmware's binary32 range" in \
        out.errors[0].getMessage()


def test_residual_counts_the_samples_of_each_rmse(seeds: dict[str, Path], tmp_path: Path,
                                                  caplog: pytest.LogCaptureFixture,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "nan.csv"
    p.write_text(_csv_with("nan", row=20, col=3))  # acc2_mps2 of one row
    out = run_cli(["residual", str(seeds["model"]), str(p), "--lenient", "--json"], caplog,
                  capsys)
    assert out.rc == 0
    ch = json.loads(out.stdout)["tests"][0]["channels"]
    assert ch["acc2_mps2"]["n_used"] == 199 and ch["acc1_mps2"]["n_used"] == 200


def test_residual_of_a_sample_whose_square_overflows_is_one_line(
        seeds: dict[str, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A sample at 1e308 (a saturated or mis-scaled sensor): its square overflowed the RMSE
    and `residual` printed inf and nan with exit 0 and numpy's RuntimeWarning."""
    p = tmp_path / "one_1e308.csv"
    p.write_text(_csv_with("1e308", row=20, col=3))  # acc2_mps2 of one row
    out = run_cli(["residual", str(seeds["model"]), str(p)], caplog, capsys)
    assert_clean(out, p, must_fail=True)
    assert "channel acc2_mps2: sample 19 is 1e+308" in out.errors[0].getMessage()


def test_csv_memory_is_a_small_multiple_of_the_samples(tmp_path: Path) -> None:
    import tracemalloc

    from dynval.io import read_test

    n = 100_000
    p = tmp_path / "big.csv"
    t = np.arange(n) / 640.0
    np.savetxt(p, np.column_stack([t, np.sin(t)[:, None] * np.ones((1, 5))]), delimiter=",",
               fmt="%.9g", header=",".join(COLUMNS), comments="")
    kept = n * len(COLUMNS) * 8
    tracemalloc.start()
    rec = read_test(p)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert rec.n_samples == n
    assert peak < 3 * kept, f"peak {peak / 1e6:.1f} MB for {kept / 1e6:.1f} MB of samples"


def test_piped_into_head_exits_quietly(seeds: dict[str, Path]) -> None:
    import os
    import subprocess
    import sys

    import dynval

    # 300 tables of residuals: over 64 KiB, more than a pipe holds, so the writer must block
    argv = ["residual", str(seeds["model"]), *[str(seeds["csv"])] * 300]
    env = {**os.environ, "PYTHONPATH": str(Path(dynval.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-m", "dynval", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline().startswith(b"model ")
    proc.stdout.close()  # what `head -1` does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == cli.EXIT_PIPE, err
    assert "Traceback" not in err and "Error" not in err, err


class _Table:
    def __init__(self, text: str) -> None:
        lines = text.splitlines()
        self.head_line = lines[0]
        self.rows = [r.split(",") for r in lines[1:]]

    def _text(self, rows: list[list[str]]) -> str:
        return "\n".join([self.head_line, *(",".join(r) for r in rows)]) + "\n"

    def replace_col(self, col: str, v: float) -> str:
        j = COLUMNS.index(col)
        return self._text([[*r[:j], repr(v), *r[j + 1:]] for r in self.rows])

    def head(self, n: int) -> str:
        return self._text(self.rows[:n])

    def set(self, i: int, col: str, v: float) -> str:
        rows = [list(r) for r in self.rows]
        rows[i][COLUMNS.index(col)] = repr(v)
        return self._text(rows)


# ---- MCAP files that are not dynval's, and damaged chunks -------------------------------------
def _foreign_mcap(path: Path, payloads: list[bytes], meta: dict[str, str] | None = None,
                  summary: dict[str, str] | None = None) -> None:
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("x", "jsonschema", b"{}")
        cid = w.register_channel("/dv/samples/acc1_mps2", "json", sid)
        for i, p in enumerate(payloads):
            w.add_message(cid, log_time=i, data=p, publish_time=i)
        w.add_metadata("dynval", meta if meta is not None else {"fs_hz": "640"})
        if summary is not None:
            w.add_metadata("dynval.summary", summary)
        w.finish()


def _sample(**kw: Any) -> bytes:
    d = {"channel": 0, "seq": 0, "index": 0, "values": [1.0, 2.0, 3.0], "verdict": "ok", **kw}
    return json.dumps(d).encode()


FOREIGN_MCAPS: dict[str, tuple[list[bytes], dict[str, str] | None]] = {
    "not_json": ([b"\x00\x01\x02"], None),
    "json_list": ([b"[1, 2, 3]"], None),
    "channel_str": ([_sample(channel="x")], None),
    "index_huge": ([_sample(index=8 * 10 ** 12)], None),
    "index_negative": ([_sample(index=-5)], None),
    "values_long": ([_sample(values=[1.0] * 1000)], None),
    "values_text": ([_sample(values=["a", "b", "c"])], None),
    "values_nested": ([_sample(values=[[1], [2], [3]])], None),
    "fs_text": ([_sample()], {"fs_hz": "fast"}),
    "fs_inf": ([_sample()], {"fs_hz": "1e999"}),
    "units_not_json": ([_sample()], {"fs_hz": "640", "units": "{oops"}),
    "n_samples_text": ([_sample()], {"fs_hz": "640", "n_samples": "many"}),
}


@pytest.mark.parametrize("name", list(FOREIGN_MCAPS))
def test_foreign_mcap_with_dynval_topics(name: str, tmp_path: Path,
                                         caplog: pytest.LogCaptureFixture,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / f"{name}.mcap"
    payloads, meta = FOREIGN_MCAPS[name]
    _foreign_mcap(p, payloads, meta)
    assert_clean(run_cli(["features", str(p), "--json"], caplog, capsys), p, must_fail=True)


def test_inspect_non_json_summary(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "s.mcap"
    _foreign_mcap(p, [_sample()], summary={"sequence": "not json"})
    assert_clean(run_cli(["inspect", str(p)], caplog, capsys), p, must_fail=True)


def _chunk_data_offsets(b: bytes) -> list[int]:
    """Offsets of the compressed records of each chunk of an MCAP file."""
    out, off = [], 8
    while off + 9 <= len(b):
        op, length = struct.unpack_from("<BQ", b, off)
        if op == 0x06:
            comp_len = struct.unpack_from("<I", b, off + 9 + 28)[0]
            out.append(off + 9 + 32 + comp_len + 8)
        off += 9 + length
    return out


def test_damaged_zstd_chunk_is_an_error(seeds: dict[str, Path], tmp_path: Path,
                                        caplog: pytest.LogCaptureFixture,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    b = bytearray(seeds["mcap"].read_bytes())
    offs = _chunk_data_offsets(bytes(b))
    assert offs, "the seed MCAP has chunks"
    b[offs[0]: offs[0] + 4] = b"\xde\xad\xbe\xef"  # the zstd frame's magic
    p = tmp_path / "zstd.mcap"
    p.write_bytes(bytes(b))
    for argv in (["features", str(p)], ["inspect", str(p)]):
        out = run_cli(argv, caplog, capsys)
        if argv[0] == "features":
            assert_clean(out, p, must_fail=True)
            assert "damaged" in out.errors[0].getMessage()
        else:
            assert_clean(out, p, must_fail=False)
            assert "read error: damaged" in out.stdout


def test_an_input_error_quoting_several_lines_is_logged_on_one(
        monkeypatch: pytest.MonkeyPatch, seeds: dict[str, Path],
        caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]) -> None:
    import dynval.cmd_features as cf
    from dynval.errors import InputFileError

    def refuse(*_: object, **__: object) -> None:  # a library's refusal quoted as it was
        raise InputFileError(seeds["csv"], "the reader said:\n  bad name\n\tat 'x'", line=3)

    monkeypatch.setattr(cf, "compute", refuse)
    out = run_cli(["features", str(seeds["csv"])], caplog, capsys)
    assert out.rc == 2 and len(out.errors) == 1
    msg = out.errors[0].getMessage()
    assert msg == f"{seeds['csv']}:3: the reader said: bad name at 'x'"


def test_internal_error_is_one_line_and_debug_shows_it(
        monkeypatch: pytest.MonkeyPatch, seeds: dict[str, Path],
        caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]) -> None:
    import dynval.cmd_features as cf

    def boom(*_: object, **__: object) -> None:
        raise ZeroDivisionError("a planted bug")

    monkeypatch.setattr(cf, "compute", boom)
    out = run_cli(["features", str(seeds["csv"])], caplog, capsys)
    assert out.rc == 3 and len(out.errors) == 1
    msg = out.errors[0].getMessage()
    assert "internal error: ZeroDivisionError: a planted bug" in msg and "--debug" in msg
    assert out.errors[0].exc_info is None
    for argv in (["--debug", "features", str(seeds["csv"])],
                 ["features", str(seeds["csv"]), "--debug"]):
        out = run_cli(argv, caplog, capsys)
        assert out.rc == 3 and any(r.exc_info for r in out.errors)


def test_broken_pipe_exits_quietly(monkeypatch: pytest.MonkeyPatch, seeds: dict[str, Path],
                                   caplog: pytest.LogCaptureFixture,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    import dynval.cmd_features as cf

    def closed(*_: object, **__: object) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(cf, "compute", closed)
    out = run_cli(["features", str(seeds["csv"])], caplog, capsys)
    assert out.rc == cli.EXIT_PIPE and not out.errors


# ---- I/O errors: one line, exit 2, no wait -------------------------------------------------------
def test_run_with_a_full_disk_is_one_line(monkeypatch: pytest.MonkeyPatch,
                                          seeds: dict[str, Path], tmp_path: Path,
                                          caplog: pytest.LogCaptureFixture,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    import time

    from dynval import mcap_log

    def full(self: Any, *_: object) -> None:
        raise mcap_log.LogError(f"{self.path}: cannot write the log: No space left on device")

    monkeypatch.setattr(mcap_log.McapLog, "on_frames", full)
    t0 = time.monotonic()
    out = run_cli(["run", str(seeds["csv"]), "-o", str(tmp_path / "o"), "--bus", "virtual",
                   "--asap", "--no-model"], caplog, capsys)
    assert out.rc == 2 and time.monotonic() - t0 < 10  # not the 120 s status wait
    msgs = [r.getMessage() for r in out.errors]
    assert len(msgs) == 1 and "No space left on device" in msgs[0] and ".mcap" in msgs[0]


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_writing_to_a_full_device_is_one_line(seeds: dict[str, Path],
                                              caplog: pytest.LogCaptureFixture,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    full = Path("/dev/full")
    out = run_cli(["simulate", str(seeds["model"]), str(seeds["csv"]), "-o", str(full)],
                  caplog, capsys)
    assert_clean(out, full, must_fail=True)
    assert "No space left on device" in out.errors[0].getMessage()
    from dynval import mcap_log

    with pytest.raises(mcap_log.LogError, match="/dev/full: cannot write the log"):
        mcap_log.McapLog(full).close()


def test_a_diverging_sweep_run_is_failed_not_a_prefix_rmse() -> None:
    from dynval import model as mdl
    from dynval.validate import doe, featvec

    m = mdl.from_dict(_model(elements=[{"type": "vv_damper", "between": [3, 4],
                                        "c2_n_s2_per_m2": 1.0}]), source="m.json")
    u = np.random.default_rng(3).normal(size=1024) * 20
    fset = featvec.parse("rms@acc4_mps2").resolve(list(m.outputs))
    job = doe.make_job(m, [u], 640.0, fset, oversample=1,
                       rmse_refs={"acc4_mps2": np.zeros(1024)})
    feats, rmse, failed = doe._chunk_run(job, [{"e1.c2_n_s2_per_m2": 1.0},
                                               {"e1.c2_n_s2_per_m2": 1e8}])
    assert failed == [1] and np.isnan(rmse[1]).all() and np.isnan(feats[1]).all()
    assert np.isfinite(rmse[0]).all() and rmse[0, 0] > 0
