"""dynval run in-process: replay -> the firmware loop (libdv_simcore through cffi) -> MCAP on
python-can's virtual bus. The features in the MCAP equal features.channel_records on the same
quantised samples, bit for bit in float32 as sent; faults on the bus are counted; the CLI."""
from __future__ import annotations

import re
import shutil
import struct
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from dynval import bus, cli, contract, features, mcap_log, runloop
from dynval.cmd_inspect import inspect
from dynval.io import read_test
from dynval.io.mcapfile import iter_messages
from dynval.io.recording import Channel, Recording

pytest.importorskip("can")
WIN, SEG, NSEG, FS = 64, 32, 16, 640
REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "data" / "lanl4dof-sim" / "clean"


def _f32(v: float) -> int:
    return struct.unpack("<I", struct.pack("<f", v))[0]


def _rec(n: int = 3 * SEG * NSEG + 7) -> Recording:
    rng = np.random.default_rng(3)
    t = np.arange(n) / FS
    chans = [Channel("force", 30 * rng.standard_normal(n), "N", "input", 1)]
    for c in range(1, 5):
        x = 3 * np.sin(2 * np.pi * (17 + 9 * c) * t) + 0.3 * rng.standard_normal(n) + 0.05 * c
        chans.append(Channel(f"acc{c}", x, "m/s^2", "output", c))
    return Recording("synthetic", float(FS), chans)


def test_round_trip_features_bit_for_bit(tmp_path):
    rec = _rec()
    out = tmp_path / "rt.mcap"
    choice = runloop.choose_bus("virtual")
    r = runloop.run_test(rec, out, choice, asap=True,
                         fw_kw={"win_len": WIN, "seg_len": SEG, "n_seg": NSEG})
    got: dict[tuple[int, int, int], int] = {}
    for m in iter_messages(out, topics={"/dv/features"}):
        d = m.data
        assert _f32(d["value"]) == d["bits"]
        got[(d["channel"], d["feat_id"], d["index"])] = d["bits"]
    plan = bus.make_plan(rec)
    want: dict[tuple[int, int, int], int] = {}
    for c in range(5):
        recs, nan = features.channel_records(plan.values(c), FS, WIN, SEG, NSEG)
        assert len(recs) == 3 and nan == 0
        for rf in recs:
            s, tm = rf.stats, rf.temporal
            vals = {0x10: s.mean, 0x11: s.std, 0x12: s.rms, 0x13: s.skew, 0x14: s.kurt,
                    0x15: s.peak, 0x16: s.min, 0x17: s.max, 0x18: s.crest, 0x19: s.kfactor}
            assert tm is not None
            vals.update({0x20: tm.energy, 0x21: tm.central_time, 0x22: tm.rms_duration,
                         0x23: tm.central_skew, 0x24: tm.central_kurt,
                         0x25: tm.root_energy_amp})
            for fid, v in vals.items():
                want[(c, fid, rf.index)] = _f32(v)
            for i, v in enumerate(rf.segstd):
                want[(c, 0x01, rf.index * NSEG + i)] = _f32(float(v))
            assert rf.window is not None
            last = rf.index * NSEG + NSEG - 1
            for fid, v in ((0x08, rf.window.mean), (0x09, rf.window.std),
                           (0x0A, rf.window.rms), (0x0B, rf.window.peak)):
                want[(c, fid, last)] = _f32(v)
    sub = {k: got[k] for k in want if k in got}
    assert len(want) == 5 * 3 * (16 + NSEG + 4)  # record, segment, window at record end
    assert len(sub) == len(want) and sub == want
    assert r.counters["lost"] == 0 and r.counters["samples"] == 5 * rec.n_samples
    assert r.log_summary["sequence"]["acc1"]["ok"] == plan.n_frames_per_channel


def test_faults_on_the_bus_are_counted(tmp_path):
    """Unknown ids, a bad DLC and a sequence gap injected between the replay's frames."""
    import can

    rec = _rec(600)
    plan = bus.make_plan(rec)
    out = tmp_path / "faults.mcap"
    log = runloop.McapLog(out, channel_names=rec.names)
    tx = can.Bus(interface="virtual", channel="t-faults")
    rx = can.Bus(interface="virtual", channel="t-faults")
    skipped = 0
    for _, frames in plan.batches():
        for cid, data in frames:
            if cid == bus.ID_SAMPLES and data[0] == 2 and data[1] in (10, 11, 12):
                skipped += 1
                continue  # three frames of channel 2 lost
            tx.send(can.Message(arbitration_id=cid, data=data, is_extended_id=False))
    tx.send(can.Message(arbitration_id=0x7F0, data=bytes(8), is_extended_id=False))
    tx.send(can.Message(arbitration_id=0x1ABCDEF, data=bytes(8), is_extended_id=True))
    tx.send(can.Message(arbitration_id=0x200, data=bytes(5), is_extended_id=False))
    n = runloop.log_bus(rx, log, idle_timeout_s=0.3)
    s = log.close()
    tx.shutdown()
    rx.shutdown()
    assert n == plan.n_frames - skipped + 3
    assert s["events"] == {"seq_gap": 3, "unknown_id": 2, "bad_dlc": 1}
    assert s["sequence"]["acc2"]["lost"] == 3 and s["sequence"]["acc1"]["lost"] == 0
    ev = [m.data for m in iter_messages(out, topics={"/dv/events"})]
    assert {e["event"] for e in ev} == {"seq_gap", "unknown_id", "bad_dlc"}


@pytest.mark.skipif(not DATA.is_dir(), reason="bundled data missing")
def test_cli_run_and_inspect_on_bundled_data(tmp_path, capsys):
    rc = cli.main(["-q", "run", str(DATA / "test_low_01.csv"), "--bus", "virtual", "--asap",
                   "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "in-process" in out and "residual RMS" in out and "lost 0" in out
    mc = tmp_path / "clean_test_low_01.mcap"
    from dynval.cmd_inspect import inspect

    r = inspect(mc)
    # one message per sample (2731 frames of 3), logged on the test's clock: an --asap run
    # still shows the test's 640 Hz, evenly spaced (no gaps)
    f = r["topics"]["/dv/samples/force_N"]
    assert r["complete"] and f["count"] == 3 * 2731
    assert f["rate_hz"] == pytest.approx(640.0, rel=1e-6) and f["gaps"] == 0
    assert f["max_gap_ms"] == pytest.approx(1000 / 640, abs=1e-3)
    # cubic hold: each residual comes one sample late, none for the first sample, and none
    # for the last one (the frame padding after it is a missing sample, not an input)
    assert r["topics"]["/dv/residuals"]["count"] == 4 * 8191
    assert r["metadata"]["test"] == "test_low_01" and len(r["metadata"]["source_sha256"]) == 64
    assert r["summary"]["sequence"]["acc4_mps2"]["lost"] == 0
    # the MCAP reads back as a test: the quantised samples of the CSV
    rec = read_test(mc)
    src = read_test(DATA / "test_low_01.csv")
    plan = bus.make_plan(src)
    np.testing.assert_array_equal(rec.channel("acc3_mps2").data, plan.values(3))
    assert cli.main(["inspect", str(mc)]) == 0


def test_contract_constants_equal_what_the_c_compiler_makes_of_the_headers(tmp_path):
    """Every number dynval.contract parsed from the build's macro dump equals the C value, and
    nothing of the register map or the codec was left out by the parser."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None or not (REPO / "firmware_sim" / "sim_core.h").is_file():
        pytest.skip("no C compiler or no firmware_sim sources beside the package")
    hdr = (REPO / "firmware_sim" / "sim_regmap.h").read_text() + (
        REPO / "include" / "dynval" / "dv_codec.h").read_text()
    declared = set(re.findall(r"^#define ((?:SIM|DV)_\w+) ", hdr, re.M))
    assert declared - set(contract.MACROS) == set()
    names = sorted(contract.MACROS)
    body = "".join(f'    printf("{n} %.17g\\n", (double)({n}));\n' for n in names)
    src = tmp_path / "c.c"
    src.write_text(f'#include <stdio.h>\n#include "sim_core.h"\nint main(void)\n{{\n{body}'
                   "    return 0;\n}\n")
    exe = tmp_path / "c"
    subprocess.run([cc, "-std=c99", "-DDV_REAL_DOUBLE", "-DDV_CDEF",  # as the dump
                    f"-I{REPO / 'include'}",
                    f"-I{REPO / 'firmware_sim'}", str(src), "-o", str(exe)], check=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    c_values = {k: float(v) for k, v in (ln.split() for ln in out.splitlines())}
    assert c_values == {k: float(v) for k, v in contract.MACROS.items()}
    assert contract.IR_COUNTERS["rx_frames"] == contract.const("SIM_IR_RX_FRAMES")
    assert "ch_lost" not in contract.IR_COUNTERS and "version" not in contract.IR_COUNTERS


def test_sim_config_fields_land_in_the_contract_registers():
    """The binding's struct sim_config, through the firmware's own sim_config_to_regs, puts
    each field at the holding register dynval.contract names."""
    from dynval import _core

    ffi, lib = _core.ffi, _core.sim_lib
    c = ffi.new("struct sim_config *")
    lib.sim_config_default(c)
    c.n_chan, c.win_len, c.seg_len, c.n_seg, c.heartbeat_ms = 3, 111, 22, 7, 555
    c.fs_hz[2], c.model[contract.const("SIM_MODEL_HOLD")] = 1234, 0.5
    hr = ffi.new("uint16_t[]", contract.const("SIM_N_HOLDING"))
    lib.sim_config_to_regs(c, hr)
    k = contract.const
    assert (hr[k("SIM_HR_N_CHAN")], hr[k("SIM_HR_WIN_LEN")], hr[k("SIM_HR_SEG_LEN")],
            hr[k("SIM_HR_N_SEG")], hr[k("SIM_HR_HEARTBEAT_MS")],
            hr[k("SIM_HR_FS_CH") + 2]) == (3, 111, 22, 7, 555, 1234)
    at = k("SIM_HR_MODEL") + 2 * k("SIM_MODEL_HOLD")
    assert struct.pack(">HH", hr[at], hr[at + 1]) == struct.pack(">f", 0.5)


def test_refused_frames_are_named_after_the_firmware_counter_that_counts_them():
    core = runloop.SimCore(runloop.FirmwareConfig())
    try:
        for can_id, data, status in ((0x200, bytes(5), -2), (0x7F0, bytes(8), -6),
                                     (0x101, bytes([0, 1, 100, 0, 0, 0, 0, 0]), -4)):
            before = core.counters()
            assert bus.decode(can_id, data) == status
            core.handle(can_id, data)
            after = core.counters()
            grew = {n for n in after if after[n] != before[n]} - {"rx_frames"}
            assert grew == {mcap_log.refused_event(status)}
    finally:
        core.close()


@pytest.mark.skipif(not DATA.is_dir(), reason="bundled data missing")
def test_a_firmware_behind_the_replay_is_waited_for(tmp_path, monkeypatch):
    # a loaded host: the firmware thread stalls (1.2 s, then 0.5 s) while it works through
    # the --asap replay's backlog, so heartbeats come and the bus goes quiet before it has
    # handled the status request; every residual must still be logged (one stop at a
    # heartbeat lost a third of them, with rc 0 and "lost 0")
    handle = runloop.SimCore.handle
    seen = {"n": 0}

    def slow(self, can_id, data):
        seen["n"] += 1
        if seen["n"] in (2000, 2001):
            time.sleep(1.2 if seen["n"] == 2000 else 0.5)
        return handle(self, can_id, data)

    monkeypatch.setattr(runloop.SimCore, "handle", slow)
    assert cli.main(["-q", "run", str(DATA / "test_low_01.csv"), "--bus", "virtual", "--asap",
                     "-o", str(tmp_path)]) == 0
    r = inspect(tmp_path / "clean_test_low_01.mcap")
    assert seen["n"] > 2001
    assert r["topics"]["/dv/residuals"]["count"] == 4 * 8191
    assert r["topics"]["/dv/features"]["count"] == 3300
