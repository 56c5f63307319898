"""Property tests of the readers (hypothesis): whatever the bytes or the JSON, a reader returns
a Recording (or a Model) or raises the DynvalError that names the file; and the CSV reader's
block parser gives exactly the numbers Python's float() reads from each cell."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from dynval import model as mdl  # noqa: E402
from dynval.errors import ConfigError, DynvalError, InputFileError  # noqa: E402
from dynval.io import read_test  # noqa: E402
from dynval.io.channelmap import channel_map_from_dict  # noqa: E402

# derandomized: the same examples on every run (CI stays reproducible and bounded in time)
FAST = settings(max_examples=150, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=12), inner,
                                                                 max_size=5),
    max_leaves=30)

HEADER = "time_s,force_N,acc1_mps2\n"


def _check_recording(rec: Any) -> None:
    assert rec.n_samples >= 2 and 0 < rec.fs_hz < math.inf
    for c in rec.channels:
        assert c.data.size == rec.n_samples
        assert not np.isinf(c.data).any()  # NaN only where a lenient reader counted it


@FAST
@given(body=st.binary(max_size=400), lenient=st.booleans())
def test_csv_any_bytes_read_or_named(tmp_path: Path, body: bytes, lenient: bool) -> None:
    p = tmp_path / "t.csv"
    p.write_bytes(HEADER.encode() + body)
    try:
        rec = read_test(p, lenient=lenient)
    except InputFileError as exc:
        assert "t.csv" in str(exc) and "\n" not in str(exc)
        return
    _check_recording(rec)


cell = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
                 st.integers(-10 ** 6, 10 ** 6).map(str),
                 st.floats(-1e6, 1e6).map(lambda v: f" {v:.3e} "),
                 st.sampled_from(["1_000", "0x10", "+1.5", "-0", ".5", "5.", "1e-320", "١٢"]))


@FAST
@given(rows=st.lists(st.tuples(cell, cell), min_size=2, max_size=40))
def test_csv_numbers_are_what_float_reads(tmp_path: Path, rows: list[tuple[str, str]]) -> None:
    lines = [f"{i * 0.01:.2f},{a},{b}" for i, (a, b) in enumerate(rows)]
    p = tmp_path / "n.csv"
    p.write_text(HEADER + "\n".join(lines) + "\n", encoding="utf-8")
    want = []
    for a, b in rows:
        try:
            want.append((float(a), float(b)))
        except ValueError:
            with pytest.raises(InputFileError, match="not a number"):
                read_test(p)
            return
    if not all(math.isfinite(v) for r in want for v in r):
        with pytest.raises(InputFileError):
            read_test(p)
        return
    rec = read_test(p)
    np.testing.assert_array_equal(rec.channel("force_N").data, [a for a, _ in want])
    np.testing.assert_array_equal(rec.channel("acc1_mps2").data, [b for _, b in want])


@FAST
@given(doc=json_values)
def test_model_from_any_json(doc: Any) -> None:
    try:
        m = mdl.from_dict(doc if isinstance(doc, dict) else {"x": doc}, source="p.json")
    except ConfigError as exc:
        assert str(exc).startswith("p.json") and "\n" not in str(exc)
        return
    assert m.n_dof >= 1


MODEL = {"format": "dynval-model/1", "masses_kg": [1.0, 2.0], "stiffness_n_per_m": [10.0, 20.0],
         "damping": {"type": "modal", "zeta": [0.01, 0.02]},
         "input": {"kind": "force", "dof": 1, "channel": "force_N"},
         "outputs": {"acc1_mps2": {"kind": "acc", "dof": 1}}}


@FAST
@given(key=st.sampled_from(sorted(MODEL)), value=json_values)
def test_model_with_one_field_replaced(key: str, value: Any) -> None:
    try:
        mdl.from_dict({**MODEL, key: value}, source="q.json")
    except ConfigError as exc:
        assert str(exc).startswith("q.json") and "\n" not in str(exc)


@FAST
@given(doc=json_values)
def test_channel_map_from_any_json(doc: Any) -> None:
    try:
        channel_map_from_dict(doc, "map.json")
    except ConfigError as exc:
        assert str(exc).startswith("map.json")


@FAST
@given(rows=st.lists(st.lists(json_values, min_size=6, max_size=6), min_size=0, max_size=6),
       extra=st.dictionaries(st.sampled_from(["dt", "sampling freq", "displacement units"]),
                             json_values, max_size=3))
def test_brfd_any_rows(tmp_path: Path, rows: list[list[Any]], extra: dict[str, Any]) -> None:
    p = tmp_path / "b.json"
    p.write_text(json.dumps({"data": rows, **extra}))
    try:
        rec = read_test(p, lenient=True)
    except InputFileError as exc:
        assert "b.json" in str(exc)
        return
    _check_recording(rec)


@FAST
@given(payloads=st.lists(st.one_of(
    json_values.map(lambda v: json.dumps(v).encode()),
    st.fixed_dictionaries({"channel": st.integers(-2, 300), "index": st.integers(-5, 10 ** 13),
                           "values": st.lists(st.none() | st.floats(), max_size=5),
                           "verdict": st.sampled_from(["ok", "gap", "dup"])})
    .map(lambda d: json.dumps(d).encode())), min_size=1, max_size=6),
    meta=st.dictionaries(st.sampled_from(["fs_hz", "n_samples", "units", "roles"]),
                         st.text(max_size=10), max_size=4))
def test_mcap_any_sample_payloads(tmp_path: Path, payloads: list[bytes],
                                  meta: dict[str, str]) -> None:
    from mcap.writer import Writer

    p = tmp_path / "f.mcap"
    with open(p, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("x", "jsonschema", b"{}")
        cid = w.register_channel("/dv/samples/a", "json", sid)
        for i, data in enumerate(payloads):
            w.add_message(cid, log_time=i, data=data, publish_time=i)
        w.add_metadata("dynval", meta)
        w.finish()
    try:
        rec = read_test(p, lenient=True)
    except DynvalError as exc:
        assert "f.mcap" in str(exc)
        return
    assert rec.n_samples <= 3 * len(payloads) * 64 + 3 and 0 < rec.fs_hz < math.inf
