"""The MCAP dynval writes, read by Foxglove's own code (gateway/tests/foxglove/check_mcap.mjs:
@mcap/core's indexed reader and the open-source Foxglove Studio's parseChannel, with its
JSON-schema and protobuf parsers): every schema parses, every sample is a plot point at its
time on the test's clock (a missing one a NaN gap), the events are foxglove.Log messages with
the Foxglove SDK's schema; the first layout's ["number", "null"] is what that parser refuses.

Needs node with gateway/tests/foxglove's packages (scripts/setup.sh installs both); skipped
without them unless DV_FOXGLOVE_CHECK=1 (scripts/test_all.sh), where that is a failure."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval import bus
from dynval.io.mcapfile import read_mcap
from dynval.io.recording import Channel, Recording
from dynval.mcap_log import FOXGLOVE_LOG, McapLog

HERE = Path(__file__).resolve().parent / "foxglove"
T0 = 1_700_000_000_000_000_000  # receive time of the first frame, ns
T_START = T0 + 3000  # of DV_CTRL START, after CLEAR and two DV_CHCFG (1 us apart)


def _node() -> str:
    node = shutil.which("node")
    missing = ("node is not installed" if node is None else
               "gateway/tests/foxglove has no node_modules" if not
               (HERE / "node_modules" / ".foxglove-studio" / "mcap-support.js").is_file()
               else "")
    if missing:
        if os.environ.get("DV_FOXGLOVE_CHECK") == "1":
            pytest.fail(f"DV_FOXGLOVE_CHECK=1 but {missing} (scripts/setup.sh installs it)")
        pytest.skip(f"{missing}: scripts/setup.sh installs node, npm and the Foxglove packages")
    assert node is not None
    return node


def foxglove_read(path: Path) -> dict[str, Any]:
    out = subprocess.run([_node(), str(HERE / "check_mcap.mjs"), str(path)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)  # type: ignore[no-any-return]


def _logged(tmp_path: Path) -> tuple[Path, bus.Plan]:
    """A replay logged as --asap delivers it: every frame 1 us after the one before."""
    rng = np.random.default_rng(5)
    a = rng.standard_normal(31)
    a[4] = np.nan  # a missing sample
    rec = Recording("r", 640.0, [Channel("a", a), Channel("b", rng.standard_normal(31) * 3)])
    plan = bus.make_plan(rec)
    p = tmp_path / "x.mcap"
    k = 0
    with McapLog(p, meta={"fs_hz": "640", "n_samples": "31"}, channel_names=["a", "b"]) as mc:
        for _, frames in plan.batches():
            for cid, data in frames:
                mc.on_frame(T0 + k * 1000, cid, data)
                k += 1
            if k == 20:  # a DV_FEATURE and a DV_RESID mid-record
                mc.on_frame(T0 + k * 1000, 0x300, bytes([0x12, 1, 0, 0]) + b"\x00\x00\x80\x3f")
                mc.on_frame(T0 + k * 1000, 0x380, bytes([0, 0, 5, 0]) + b"\x00\x00\x00\x40")
    return p, plan


def test_foxglove_parses_every_schema_and_plots_each_sample_on_the_test_clock(
        tmp_path: Path) -> None:
    p, plan = _logged(tmp_path)
    fx = foxglove_read(p)
    topics = fx["topics"]
    assert {t: v["error"] for t, v in topics.items() if "error" in v} == {}
    assert {"/can/raw", "/dv/samples/a", "/dv/samples/b", "/dv/features", "/dv/residuals",
            "/dv/control", "/dv/events", "/dv/log"} <= set(topics)
    for c, name in enumerate(("a", "b")):
        t = topics[f"/dv/samples/{name}"]
        assert t["messageEncoding"] == "protobuf" and t["schemaEncoding"] == "protobuf"
        defs = t["datatypes"]["dynval.Sample"]["definitions"]
        fields = {d["name"]: d["type"] for d in defs if not d.get("isConstant")}
        assert fields == {"channel": "uint32", "index": "uint64", "value": "float64",
                          "verdict": "int32"}
        verdicts = {d["name"]: d["value"] for d in defs if d.get("isConstant")}
        assert verdicts == {"ok": 0, "gap": 1, "dup": 2, "late": 3, "stale": 4}
        want = plan.values(c)
        series = t["series"]["value"]  # what a plot of /dv/samples/<name>.value draws
        assert len(series) == t["count"] == plan.raw[c].size  # one message per sample
        log_ns = [int(s[0]) for s in series]
        assert log_ns == [T_START + round(i * 1e9 / 640) for i in range(len(series))]
        assert [int(s[1]) for s in series] == log_ns  # publish time too
        got = np.array([np.nan if s[2] is None else s[2] for s in series])
        # the values exactly; a missing sample (and the 2 padding ones) is NaN: a plot gap
        assert np.array_equal(got[: want.size], want, equal_nan=True)
        assert np.isnan(got[want.size:]).all() and np.isnan(got).sum() == (3 if c == 0 else 2)
    # the feature and residual frames arrived after 8 sample frames per channel: logged at
    # the test time of sample 23, published at their receive time
    f = topics["/dv/features"]["series"]["value"]
    assert f == [[str(T_START + round(23 * 1e9 / 640)), str(T0 + 20 * 1000), 1.0]]
    assert topics["/dv/residuals"]["series"]["value"][0][2] == 2.0
    assert topics["/can/raw"]["count"] == plan.n_frames + 2
    assert topics["/can/raw"]["first"]["id"] == bus.ID_CTRL
    # the dynval reader sees the same samples
    r = read_mcap(p)
    assert np.array_equal(r.channels[0].data, plan.values(0), equal_nan=True)


def test_events_are_foxglove_log_messages_with_the_sdk_schema(tmp_path: Path) -> None:
    p, _ = _logged(tmp_path)
    fx = foxglove_read(p)
    t = fx["topics"]["/dv/log"]
    assert t["schemaName"] == "foxglove.Log" and t["count"] == 2  # START, STOP
    assert t["first"]["message"] == "START record 1: 2 channel(s) at 640 Hz"
    assert t["first"]["level"] == 2
    assert t["first"]["timestamp"] == {"sec": T_START // 10**9, "nsec": T_START % 10**9}

    def strip(d: Any) -> Any:
        if isinstance(d, dict):
            return {k: strip(v) for k, v in d.items() if k not in ("description", "$comment")}
        return [strip(v) for v in d] if isinstance(d, list) else d

    assert strip(FOXGLOVE_LOG) == strip(fx["foxgloveLogSchema"])


def test_the_old_layout_is_what_foxglove_refuses(tmp_path: Path) -> None:
    """The schema of logs written before (three samples per message, missing ones null) fails
    in Foxglove's parser, the reason for the new layout; dynval still reads such files."""
    from mcap.writer import Writer

    p = tmp_path / "old.mcap"
    with open(p, "wb") as f:
        w = Writer(f)
        w.start()
        w.add_metadata("dynval", {"fs_hz": "640"})
        schema = {"type": "object", "properties": {
            "channel": {"type": "integer"}, "index": {"type": "integer"},
            "values": {"type": "array", "items": {"type": ["number", "null"]}},
            "verdict": {"type": "string"}}}
        sid = w.register_schema("dynval.Samples", "jsonschema", json.dumps(schema).encode())
        cid = w.register_channel("/dv/samples/a", "json", sid)
        for k in range(2):
            d = {"channel": 0, "seq": k, "index": 3 * k, "values": [1.0, None, 2.0 + k],
                 "verdict": "ok"}
            w.add_message(cid, log_time=k, publish_time=k, data=json.dumps(d).encode())
        w.finish()
    err = foxglove_read(p)["topics"]["/dv/samples/a"]["error"]
    assert err == 'Unsupported type ["number","null"] for array item values'
    x = read_mcap(p, lenient=True).channels[0].data
    assert np.array_equal(x, [1.0, np.nan, 2.0, 1.0, np.nan, 3.0], equal_nan=True)


def test_a_killed_log_recovered_opens_in_foxglove(tmp_path: Path) -> None:
    """Issue 17: a log cut off by a kill (no footer, no index) is what `dynval recover` turns
    into a file Foxglove opens, every sample that reached the disk plotted."""
    from dynval import cli

    rng = np.random.default_rng(6)
    rec = Recording("r", 640.0, [Channel("a", rng.standard_normal(60))])
    plan = bus.make_plan(rec)
    p = tmp_path / "live.mcap"
    log = McapLog(p, meta={"fs_hz": "640", "n_samples": "60"}, channel_names=["a"],
                  max_chunk_age_s=0.0)  # every tick closes its chunk
    k = 0
    for _, frames in plan.batches():
        for cid, data in frames:
            log.on_frame(T0 + k * 1000, cid, data)
            k += 1
    log.tick()  # the writer thread has put every frame on disk
    killed = tmp_path / "killed.mcap"
    killed.write_bytes(p.read_bytes())  # the file as a SIGKILL leaves it: no footer
    log.close()
    fixed = tmp_path / "fixed.mcap"
    assert cli.main(["-q", "recover", str(killed), "-o", str(fixed)]) == 0
    topics = foxglove_read(fixed)["topics"]
    assert {t: v["error"] for t, v in topics.items() if "error" in v} == {}
    series = topics["/dv/samples/a"]["series"]["value"]
    assert np.array_equal([s[2] for s in series], plan.values(0)[:60])
