"""Malformed files of the non-CSV readers (UFF 58, MDF 4, HDF5, MATLAB, MCAP) that a fuzz run
found read with a channel lost, a number silently wrong or an internal error: each now gives
exit 2 and one line naming the file and the place, or exit 0 with a counted, logged warning.
One test per class of defect, through `dynval features` in-process."""
from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval import cli

FS = 640.0
N = 256
T = np.arange(N) / FS
RNG = np.random.default_rng(11)
FORCE = RNG.normal(size=N)
ACC = RNG.normal(size=N)


def run(argv: list[str], caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], list[str], str]:
    caplog.clear()
    capsys.readouterr()
    with caplog.at_level(logging.INFO):
        rc = cli.main(argv)
    assert all(r.exc_info is None for r in caplog.records)
    msgs = [(r.levelno, r.getMessage()) for r in caplog.records]
    return (rc, [m for lv, m in msgs if lv >= logging.ERROR],
            [m for lv, m in msgs if lv == logging.WARNING], capsys.readouterr().out)


def refused(p: Path, what: str, caplog: pytest.LogCaptureFixture,
            capsys: pytest.CaptureFixture[str], *extra: str) -> str:
    """Exit 2 and one error line that starts with the file and says `what`."""
    rc, errors, _, _ = run(["features", str(p), "--json", *extra], caplog, capsys)
    assert rc == 2 and len(errors) == 1, errors
    assert "\n" not in errors[0] and errors[0].startswith(str(p)), errors
    assert what in errors[0], errors
    return errors[0]


def counted(p: Path, what: str, caplog: pytest.LogCaptureFixture,
            capsys: pytest.CaptureFixture[str], *extra: str, n: int = 1) -> dict[str, Any]:
    """Exit 0, n reader warnings counted in the output, one of them logged and saying `what`."""
    rc, errors, warns, out = run(["features", str(p), "--json", *extra], caplog, capsys)
    assert rc == 0 and not errors, errors
    res: dict[str, Any] = json.loads(out)
    assert res["warnings"] == n, (res["warnings"], warns)
    assert not what or any(what in w and str(p) in w for w in warns), warns
    return res


# ---- writers -------------------------------------------------------------------------------
def uff(p: Path, sets: list[dict[str, Any]] | None = None) -> None:
    pyuff = pytest.importorskip("pyuff")
    sets = sets or [{"id1": "force", "data": FORCE}, {"id1": "acc1", "data": ACC}]
    pyuff.UFF(str(p)).write_sets([pyuff.prepare_58(**{
        "binary": 0, "func_type": 1, "rsp_node": k + 1, "rsp_dir": 3, "ref_node": 1,
        "ref_dir": 3, "ord_data_type": 4, "abscissa_spacing": 1, "abscissa_inc": 1 / FS,
        "abscissa_min": 0.0, "x": T, "ordinate_axis_units_lab": "m/s^2",
        "ordinate_spec_data_type": 12, "abscissa_spec_data_type": 17,
        "abscissa_axis_units_lab": "s", "orddenom_spec_data_type": 0,
        "z_axis_spec_data_type": 0, **s}) for k, s in enumerate(sets)], mode="overwrite")


def uff_edit(p: Path, edit: Callable[[list[bytes], list[int]], list[bytes]]) -> None:
    """Rewrite a UFF file's lines; edit gets them and the indices of its '    -1' lines."""
    uff(p)
    lines = p.read_bytes().splitlines(keepends=True)
    tags = [i for i, ln in enumerate(lines) if ln.rstrip() == b"    -1"]
    p.write_bytes(b"".join(edit(lines, tags)))


def mdf(p: Path, signals: list[Any] | None = None) -> None:
    asammdf = pytest.importorskip("asammdf")
    m = asammdf.MDF(version="4.10")
    m.append(signals or [asammdf.Signal(FORCE, T, name="force_N", unit="N"),
                         asammdf.Signal(ACC, T, name="acc1_mps2", unit="m/s^2")])
    m.save(p, overwrite=True)
    m.close()


def mdf_with(p: Path, **sig: Any) -> None:
    asammdf = pytest.importorskip("asammdf")
    mdf(p, [asammdf.Signal(FORCE, T, name="force_N", unit="N"),
            asammdf.Signal(ACC, T, name="acc1_mps2", unit="m/s^2"),
            asammdf.Signal(**{"timestamps": T, **sig})])


def h5(p: Path, fill: Callable[[Any], None] | None = None, *, time: bool = True) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(p, "w") as f:
        if time:
            f["time_s"] = T
        else:
            f.attrs["fs_hz"] = FS
        f["force_N"] = FORCE
        f["acc1_mps2"] = ACC
        if fill is not None:
            fill(f)


def mat(p: Path, **extra: Any) -> None:
    from scipy.io import savemat

    savemat(p, {"time_s": T, "force_N": FORCE, "acc1_mps2": ACC, **extra})


def mcap(p: Path, *, meta: dict[str, str | None] | None = None,
         topics: dict[str, str] | None = None, numbers: dict[str, int] | None = None,
         index: dict[str, list[int]] | None = None,
         data: dict[str, np.ndarray] | None = None) -> None:
    from mcap.writer import Writer

    md = {"fs_hz": "640", "n_samples": str(N), "roles": json.dumps({"force_N": "input"}),
          **(meta or {})}
    with open(p, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("dynval.Sample", "jsonschema", b"{}")
        chans = {"force_N": FORCE, "acc1_mps2": ACC, **(data or {})}
        for k, (name, x) in enumerate(chans.items()):
            cid = w.register_channel((topics or {}).get(name, f"/dv/samples/{name}"), "json",
                                     sid)
            idx = (index or {}).get(name, range(N))
            for i, v in zip(idx, x[:len(idx)], strict=True):
                d = {"channel": (numbers or {}).get(name, k), "index": i, "value": v,
                     "verdict": "ok"}
                w.add_message(cid, log_time=i, publish_time=i, data=json.dumps(d).encode())
        w.add_metadata("dynval", {k: v for k, v in md.items() if v is not None})
        w.finish()


# ---- UFF: datasets pyuff passes over -----------------------------------------------------
def _cut_after_open_tag(lines: list[bytes], tags: list[int]) -> list[bytes]:
    return lines[:tags[2]] + [lines[tags[2]].rstrip()]  # '    -1' of dataset 2, then the end


UFF_STRUCTURE: dict[str, Callable[[list[bytes], list[int]], list[bytes]]] = {
    "cut_after_an_opening_tag": _cut_after_open_tag,
    "closing_tag_lost": lambda ln, t: ln[:t[1]] + ln[t[1] + 1:],
    "dataset_number_damaged": lambda ln, t: ln[:t[2] + 1] + [b"    5x\n"] + ln[t[2] + 2:],
}


@pytest.mark.parametrize("case", list(UFF_STRUCTURE))
def test_uff_dataset_that_pyuff_passes_over_is_refused(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """pyuff pairs the '    -1' lines and skips a pair without a dataset number and an
    unpaired last one: read as a file with one channel fewer, exit 0."""
    p = tmp_path / f"{case}.uff"
    uff_edit(p, UFF_STRUCTURE[case])
    msg = refused(p, "not closed", caplog, capsys)
    assert f"{p}: line " in msg


# ---- UFF: a header its data contradicts --------------------------------------------------
def _npts(lines: list[bytes], tags: list[int]) -> list[bytes]:
    i = tags[2] + 8  # record 7 of dataset 2: data type, number of points, spacing, ...
    lines[i] = lines[i].replace(b"       256", b"       257", 1)
    return lines


def _junk_value(lines: list[bytes], tags: list[int]) -> list[bytes]:
    i = tags[2] + 13  # the first data line of dataset 2
    lines[i] = b"                 abc" + lines[i][20:]
    return lines


def _uneven(p: Path) -> None:
    """Dataset 2 with a time per point (spacing 0), one of them off the grid that its header's
    increment (the rate it is read at) gives."""
    x = T.copy()
    x[100] += 0.5 / FS
    uff(p, [{"id1": "force", "data": FORCE},
            {"id1": "acc1", "data": ACC, "abscissa_spacing": 0, "x": x}])
    lines = p.read_bytes().splitlines(keepends=True)
    tags = [i for i, ln in enumerate(lines) if ln.rstrip() == b"    -1"]
    i = tags[2] + 8  # record 7: '4 256 0 <start> <increment> 0', pyuff writes increment 0
    lines[i] = lines[i][:43] + b"  1.56250e-03" + lines[i][56:]
    p.write_bytes(b"".join(lines))


UFF_HEADER: dict[str, tuple[Callable[[Path], None], str]] = {
    "point_count": (lambda p: uff_edit(p, _npts),
                    "dataset 58 #2 (acc1): the header gives 257 points, the data 256"),
    "uneven_abscissa": (_uneven, "dataset 58 #2 (acc1): uneven abscissa: point 100"),
    "unreadable_value": (lambda p: uff_edit(p, _junk_value), "dataset #2 is not a readable "
                         "dataset 58 (ValueError: could not convert string to float"),
}


@pytest.mark.parametrize("case", list(UFF_HEADER))
def test_uff_header_its_data_contradicts_is_refused(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """pyuff reads the values there are whatever the header's point count, and the times of an
    uneven abscissa were ignored (the channel read at the increment's rate); a value it cannot
    parse was 'Error when reading data-set(s)', no dataset, no line."""
    p = tmp_path / f"{case}.uff"
    write, what = UFF_HEADER[case]
    write(p)
    msg = refused(p, what, caplog, capsys)
    assert case != "unreadable_value" or f"{p}: line " in msg


# ---- duplicate channel names ----------------------------------------------------------------
def _mdf_dup(p: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    mdf(p, [asammdf.Signal(FORCE, T, name="acc1", unit="m/s^2"),
            asammdf.Signal(ACC, T, name="acc1", unit="m/s^2")])


@pytest.mark.parametrize("suffix, write, second", [
    (".uff", lambda p: uff(p, [{"id1": "acc1", "data": FORCE}, {"id1": "acc1", "data": ACC}]),
     "acc1_2"),
    (".mf4", _mdf_dup, "acc1_1")])
def test_duplicate_channel_names_are_a_counted_warning(
        suffix: str, write: Callable[[Path], None], second: str, tmp_path: Path,
        caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]) -> None:
    """The second channel of a name was renamed without a word (a model's channel of that
    name gets the first)."""
    p = tmp_path / f"dup{suffix}"
    write(p)
    res = counted(p, f"a second channel named 'acc1', read as '{second}'", caplog, capsys)
    assert list(res["channels"]) == ["acc1", second]


# ---- arrays passed over without a word ------------------------------------------------------
def _h5_put(name: str, value: Any) -> Callable[[Path], None]:
    def fill(f: Any) -> None:
        f[name] = value
    return lambda p: h5(p, fill)


def _h5_link(p: Path) -> None:
    h5py = pytest.importorskip("h5py")
    h5(p, lambda f: f.__setitem__("acc2_mps2", h5py.SoftLink("/nowhere")))


def _h5_two_groups(p: Path) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(p, "w") as f:
        for g in ("run1", "run2"):
            f[f"{g}/time_s"], f[f"{g}/acc1_mps2"] = T, ACC


def _sparse(p: Path) -> None:
    from scipy import sparse

    mat(p, acc2_mps2=sparse.csr_matrix(ACC.reshape(1, -1)))


def _mdf_text(p: Path) -> None:
    mdf_with(p, samples=(np.arange(N) % 2).astype(np.uint8), name="state", conversion={
        "val_0": 0, "text_0": b"off", "val_1": 1, "text_1": b"on", "val_default": b"?"})


LEFT_OUT: dict[str, tuple[str, Callable[[Path], None], str]] = {
    "h5_complex": (".h5", _h5_put("acc2_mps2", ACC + 1j * ACC), "acc2_mps2 (complex)"),
    "h5_empty": (".h5", _h5_put("acc2_mps2", np.zeros(0)), "acc2_mps2 (no samples)"),
    "h5_text": (".h5", _h5_put("acc2_mps2", np.array([b"1.5"] * N)), "acc2_mps2 (text)"),
    "h5_broken_link": (".h5", _h5_link, "acc2_mps2 (a broken link)"),
    "h5_second_group": (".h5", _h5_two_groups, "group /run2 (2 datasets)"),
    "mat_complex": (".mat", lambda p: mat(p, acc2_mps2=ACC + 1j * ACC), "acc2_mps2 (complex)"),
    "mat_empty": (".mat", lambda p: mat(p, acc2_mps2=np.zeros(0)), "acc2_mps2 (no samples)"),
    "mat_sparse": (".mat", _sparse, "acc2_mps2 (a sparse matrix)"),
    # a channel cut to one sample (or a gain) was read as metadata without a word
    "h5_one_value": (".h5", _h5_put("acc2_mps2", np.array([0.5])), "acc2_mps2 (one value)"),
    "mat_one_value": (".mat", lambda p: mat(p, acc2_mps2=np.array([0.5])),
                      "acc2_mps2 (one value)"),
    "uff_not_a_time_response": (".uff", lambda p: uff(p, [
        {"id1": "force", "data": FORCE}, {"id1": "acc1", "data": ACC},
        {"id1": "frf", "data": ACC, "func_type": 4}]),
        "dataset 58 #3 (function type 4, not a time response)"),
    "mdf_text_values": (".mf4", _mdf_text, "state (text)"),
}


@pytest.mark.parametrize("case", list(LEFT_OUT))
def test_arrays_not_read_as_channels_are_a_counted_warning(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A complex, empty, text, sparse or one-value array, a broken link, another group's
    datasets, a UFF dataset that is no time response: left out of the recording without a
    word (a channel lost to a type the reader passes over)."""
    suffix, write, what = LEFT_OUT[case]
    p = tmp_path / f"{case}{suffix}"
    write(p)
    counted(p, f"not read as channels: {what}", caplog, capsys)


# ---- HDF5 datasets a stopped writer left unwritten -------------------------------------------
@pytest.mark.parametrize("layout, part, what", [
    ("contiguous", False, "never"), ("chunked", False, "never"), ("chunked", True, "only partly")])
def test_unwritten_hdf5_dataset_is_refused(
        layout: str, part: bool, what: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Its unwritten samples read as the fill value: zeros that were never measured."""
    def fill(f: Any) -> None:
        d = f.create_dataset("acc2_mps2", shape=(N,), dtype="f8",
                             chunks=(64,) if layout == "chunked" else None)
        if part:
            d[:100] = ACC[:100]

    p = tmp_path / f"{layout}{part}.h5"
    h5(p, fill)
    refused(p, f"(column acc2_mps2): the dataset was {what} written", caplog, capsys)


# ---- rates that are no rate ----------------------------------------------------------------
def _h5_rate(v: Any) -> Callable[[Path], None]:
    def write(p: Path) -> None:
        h5(p, lambda f: f.attrs.__setitem__("fs_hz", v), time=False)
    return write


def _h5_slow_time(p: Path) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(p, "w") as f:
        f["time_s"], f["force_N"], f["acc1_mps2"] = np.arange(N) * 1e10, FORCE, ACC


def _mat_rate(fs: Any) -> Callable[[Path], None]:
    def write(p: Path) -> None:
        from scipy.io import savemat
        savemat(p, {"fs": fs, "force_N": FORCE, "acc1_mps2": ACC})  # no time vector
    return write


RATES: dict[str, tuple[str, Callable[[Path], None], str]] = {
    "h5_bool": (".h5", _h5_rate(True), "the sampling rate is not one number (True)"),
    "h5_two_values": (".h5", _h5_rate(np.array([FS, 320.0])), "is not one number ([640."),
    "h5_complex": (".h5", _h5_rate(FS + 1j), "the sampling rate is not one number"),
    "h5_tiny": (".h5", _h5_rate(1e-300), "1e-300 Hz is not a usable sampling rate"),
    "h5_time_steps_1e10_s": (".h5", _h5_slow_time, "time step 1e+10 s is not a usable sample "
                             "period at sample 0"),
    "mcap_tiny": (".mcap", lambda p: mcap(p, meta={"fs_hz": "1e-300"}), "no usable fs_hz"),
    "mat_logical": (".mat", _mat_rate(np.array(True)),
                    "rate variable: the sampling rate is not one number (True)"),
}


@pytest.mark.parametrize("case", list(RATES))
def test_rate_that_is_no_rate_is_refused(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A boolean rate read as 1 Hz, an array as its first value, a complex number as its real
    part (numpy's ComplexWarning on stderr); 1e-300 Hz reached the core, whose error named no
    file (a time channel's steps of 1e10 s too)."""
    suffix, write, what = RATES[case]
    p = tmp_path / f"{case}{suffix}"
    write(p)
    refused(p, what, caplog, capsys)


# ---- a file that contradicts itself ----------------------------------------------------------
def _h5_unit(unit: str) -> Callable[[Path], None]:
    return lambda p: h5(p, lambda f: f["acc1_mps2"].attrs.__setitem__("unit", unit))


SELF_CONTRADICTING: dict[str, tuple[str, Callable[[Path], None], str, int]] = {
    "h5_rate_and_time": (".h5", lambda p: h5(p, lambda f: f.attrs.__setitem__("fs", 320.0)),
                         "the file's rate 320.0 is not its time channel's 640 Hz", 1),
    "mat_rate_and_time": (".mat", lambda p: mat(p, fs=320.0),
                          "the file's rate 320.0 is not its time channel's 640 Hz", 1),
    "h5_unit_g": (".h5", _h5_unit("g"), "the file gives the unit 'g', the name's suffix says "
                  "'m/s^2'", 1),
    "mdf_unit_g": (".mf4", lambda p: mdf_with(p, samples=ACC, name="acc2_mps2", unit="g"),
                   "(column acc2_mps2): the file gives the unit 'g'", 1),
    "mcap_unit_g": (".mcap", lambda p: mcap(p, meta={"units": json.dumps({"acc1_mps2": "g"})}),
                    "(column acc1_mps2): the file gives the unit 'g'", 1),
    "uff_unit_g": (".uff", lambda p: uff(p, [{"id1": "acc1_mps2", "data": ACC,
                                              "ordinate_axis_units_lab": "g"}]),
                   "(column acc1_mps2): the file gives the unit 'g'", 1),
}


@pytest.mark.parametrize("case", list(SELF_CONTRADICTING))
def test_a_file_that_contradicts_itself_is_a_counted_warning(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A rate that the time channel contradicts was ignored, and a unit that the name's
    suffix contradicts (acc1_mps2 in g) taken, without a word."""
    suffix, write, what, n = SELF_CONTRADICTING[case]
    p = tmp_path / f"{case}{suffix}"
    write(p)
    counted(p, what, caplog, capsys, n=n)
    if case == "h5_unit_g":  # another spelling of the suffix's unit is no contradiction
        _h5_unit("m/s\u00b2")(p)
        counted(p, "", caplog, capsys, n=0)


# ---- MDF samples the file marks bad ----------------------------------------------------------
def _mdf_invalid(p: Path) -> None:
    inv = np.zeros(N, dtype=bool)
    inv[100:110] = True
    mdf_with(p, samples=ACC, name="acc2_mps2", invalidation_bits=inv)


def _mdf_nan_time(p: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    t = T.copy()
    t[30] = np.nan
    mdf(p, [asammdf.Signal(FORCE, t, name="force_N"), asammdf.Signal(ACC, t, name="acc1")])


@pytest.mark.parametrize("case, write, lenient, what", [
    ("invalid_strict", _mdf_invalid, False,
     "(column acc2_mps2): sample 100 is marked invalid (10 in the channel"),
    ("invalid_lenient", _mdf_invalid, True, "(column acc2_mps2): non-finite value nan at sample "
     "100 (10 in the channel), kept as NaN"),
    ("nan_time", _mdf_nan_time, False, "non-finite time nan at sample")])
def test_mdf_samples_marked_bad(case: str, write: Callable[[Path], None], lenient: bool,
                                what: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                capsys: pytest.CaptureFixture[str]) -> None:
    """A channel with invalidation bits was left out whole (its valid samples on 'another time
    base'), a warning not counted; a NaN time stamp was 'no channels found'."""
    p = tmp_path / f"{case}.mf4"
    write(p)
    if lenient:
        res = counted(p, what, caplog, capsys, "--lenient")
        assert res["channels"]["acc2_mps2"]["count"] == N - 10
    else:
        refused(p, what, caplog, capsys)


# ---- MCAP: channels, records and their counts ------------------------------------------------
MCAP_REFUSED: dict[str, tuple[dict[str, Any], str]] = {
    "one_number_two_topics": ({"numbers": {"acc1_mps2": 0}},
                              "channel 0 is on /dv/samples/force_N too"),
    "one_topic_two_numbers": ({"topics": {"acc1_mps2": "/dv/samples/force_N"}},
                              "/dv/samples/force_N carries channels 0 and 1"),
    "no_channel_name": ({"topics": {"acc1_mps2": "/dv/samples/"}},
                        "topic /dv/samples/: no channel name"),
    "n_samples_huge": ({"meta": {"n_samples": str(10 ** 12)}},
                       "claims 1000000000000 samples per channel"),
    "n_samples_short": ({"meta": {"n_samples": str(N - 1)}},
                        "channel force_N: sample 255 is beyond the record (n_samples 255)"),
    "inf_value": ({"data": {"acc1_mps2": np.where(np.arange(N) == 7, np.inf, ACC)}},
                  "/dv/samples/acc1_mps2 message: a sample value of inf (--lenient reads it"),
    "role_unknown": ({"meta": {"roles": json.dumps({"acc1_mps2": "banana"})}},
                     "roles: 'banana' for acc1_mps2 is not input or output"),
}


@pytest.mark.parametrize("case", list(MCAP_REFUSED))
def test_mcap_sample_records_that_do_not_fit_are_refused(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Two topics of one channel number were merged into one channel (the other's name lost),
    one topic of two numbers gave two channels of one name, a damaged n_samples of 1e12 was an
    internal MemoryError, samples beyond n_samples were cut and an Infinity sample dropped by
    the core, without a word."""
    kw, what = MCAP_REFUSED[case]
    p = tmp_path / f"{case}.mcap"
    mcap(p, **kw)
    refused(p, what, caplog, capsys)


@pytest.mark.parametrize("index, what", [
    ([*range(100), *range(101, N)], "channel acc1_mps2: 1 missing samples (NaN)"),
    ([*range(101), *range(100, N - 1)], "channel acc1_mps2: 1 samples logged twice")])
def test_mcap_missing_and_repeated_samples_are_counted_and_logged(
        index: list[int], what: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A missing sample was counted but not logged; a sample index logged twice overwrote the
    first without a count (the index it displaced counted as one missing sample only)."""
    p = tmp_path / "gaps.mcap"
    mcap(p, index={"acc1_mps2": index})
    res = counted(p, what, caplog, capsys, n=1 + ("twice" in what))
    assert res["channels"]["acc1_mps2"]["count"] == N - 1


# ---- channel maps ----------------------------------------------------------------------------
def _map(**second: Any) -> dict[str, Any]:
    return {"channels": [{"column": "ch0", "name": "force_N", "unit": "N", "role": "input"},
                         {"column": "ch1", "name": "acc2_mps2", "unit": "m/s^2", **second}]}


CHANNEL_MAPS: dict[str, tuple[dict[str, Any], str]] = {
    "name_twice": (_map(name="force_N"), "two channels named 'force_N'"),
    "column_twice_unnamed": ({"channels": [{"column": "ch1"}, {"column": "ch1"}]},
                             "two channels named 'ch1'"),
    "name_a_number": (_map(name=5), "channels[1].name: a non-empty string, got 5"),
    "name_empty": (_map(name=""), "channels[1].name: a non-empty string, got ''"),
    "unit_a_list": (_map(unit=["m"]), "channels[1].unit: a string, got ['m']"),
    "scale_beyond_floats": (_map(scale=1e308), "channels[1].scale 1e+308 takes ch1's sample"),
    "unit_g_for_mps2": (_map(unit="g"), "(column acc2_mps2): the file gives the unit 'g'"),
}


@pytest.mark.parametrize("case", list(CHANNEL_MAPS))
def test_channel_map_that_garbles_a_channel(
        case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A name twice gave two channels of one name (the second shadowed); a number or an empty
    string as a name, a list as a unit were taken; a scale taking samples beyond the float
    range made them inf with numpy's RuntimeWarning; a unit its name contradicts, no word."""
    from scipy.io import savemat

    p, cmap = tmp_path / "raw.mat", tmp_path / f"{case}.json"
    savemat(p, {"fs": FS, "ch0": FORCE, "ch1": ACC * 1e10})
    obj, what = CHANNEL_MAPS[case]
    cmap.write_text(json.dumps(obj))
    rc, errors, warns, out = run(["features", str(p), "--json", "--channel-map", str(cmap)],
                                 caplog, capsys)
    if case == "unit_g_for_mps2":  # a counted warning, the map's unit kept
        assert rc == 0 and json.loads(out)["warnings"] == 1 and any(
            w.startswith(str(cmap)) and what in w for w in warns), warns
    else:
        assert rc == 2 and len(errors) == 1 and errors[0].startswith(str(cmap)), errors
        assert what in errors[0], errors


def test_matlab_v73_text_and_empty_variables_are_not_channels(
        tmp_path: Path, caplog: pytest.LogCaptureFixture,
        capsys: pytest.CaptureFixture[str]) -> None:
    """MATLAB 7.3 writes a char variable as uint16 codes and an empty one as its dimensions:
    both were read as numeric channels of another length, and the whole file refused."""
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "v73.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        f["t"], f["acc1_mps2"] = T.reshape(1, -1), ACC.reshape(1, -1)
        f["note"] = np.frombuffer("a note".encode("utf-16-le"), dtype="<u2").reshape(-1, 1)
        f["note"].attrs["MATLAB_class"] = np.bytes_(b"char")
        f["none"] = np.array([0, 0], dtype=np.uint64)
        f["none"].attrs["MATLAB_class"] = np.bytes_(b"double")
        f["none"].attrs["MATLAB_empty"] = np.uint8(1)
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64")
    res = counted(p, "not read as channels: none (no samples)", caplog, capsys)
    assert list(res["channels"]) == ["acc1_mps2"] and res["n_samples"] == N
