"""dv_pacer (firmware_sim/pacer.c) and its driver (dynval.pacing.run_pacer): every frame sent
once, in order, byte for byte; batches and deadlines as the recorded offsets / speed say; bad
setups as one-line errors. Compiled here from the sources; frames go to its file sink (this
host may have no SocketCAN). How close to the deadlines: bench/bench_replay.py, not a test."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynval import bus, pacing
from dynval.cli import main
from dynval.io.recording import Channel, Recording

REPO = Path(__file__).resolve().parents[2]
SRC = REPO / "firmware_sim" / "pacer.c"
#: struct can_frame as the sink writes it
CAN_FRAME = np.dtype([("can_id", "=u4"), ("len", "u1"), ("pad", "u1", 3), ("data", "u1", 8)])


@pytest.fixture(scope="module")
def exe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None or not SRC.is_file() or not sys.platform.startswith("linux"):
        pytest.skip("no C compiler, no firmware_sim/pacer.c beside the package, or not Linux")
    out = tmp_path_factory.mktemp("pacer") / "dv_pacer"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                    str(SRC), "-o", str(out)], check=True)
    return out


def _run(exe: Path, records: bytes, *args: str) -> tuple[np.ndarray, int, str]:
    r = subprocess.run([str(exe), *args], input=records, capture_output=True, timeout=60)
    return (np.frombuffer(r.stdout, dtype=pacing.PACER_OUT), r.returncode,
            r.stderr.decode())


def _rec(n: int, nch: int, fs: float = 2560.0) -> Recording:
    rng = np.random.default_rng(3)
    return Recording("p", fs, [Channel(f"c{i}", rng.standard_normal(n)) for i in range(nch)])


def test_every_frame_of_a_plan_arrives_once_in_order_byte_for_byte(exe, tmp_path):
    # 5 x 3000 frames: more than the pacer's 4096-record read buffer, batches across its edge
    plan = bus.make_plan(_rec(9000, nch=5))
    sink = tmp_path / "sink.bin"
    res = pacing.run_pacer(exe, plan.batches(), sink=sink, speed=100.0)
    want = [f for _, frames in plan.batches() for f in frames]
    got = np.fromfile(sink, dtype=CAN_FRAME)
    assert res.frames_sent == len(got) == len(want) == plan.n_frames
    assert res.send_errors == 0 and res.timing["frames"] == plan.n_frames
    assert [(int(g["can_id"]), bytes(g["data"][: g["len"]])) for g in got] == want
    # the firmware's view: channel 3's samples in order
    seqs = [int(g["data"][1]) for g in got if g["can_id"] == bus.ID_SAMPLES and g["data"][0] == 3]
    assert seqs == [k & 0xFF for k in range(3000)]


def test_batches_and_deadlines_are_the_offsets_over_the_speed(exe):
    offsets = [0, 0, 1_000_000, 3_000_000, 3_000_000, 3_000_000] + [5_000_000] * 70
    records = b"".join(pacing.PACER_IN.pack(o, 0x200 + k, 2, bytes([k & 0xFF, 7]))
                       for k, o in enumerate(offsets))
    for speed in (1.0, 4.0, 3.0):
        rep, rc, err = _run(exe, records, "-o", "/dev/null", "-s", repr(speed))
        assert rc == 0 and err == ""
        # equal offsets are one batch, at most 64 frames per sendmmsg (the 70 split 64 + 6)
        assert rep["frames"].tolist() == [2, 1, 3, 64, 6]
        assert rep["failed"].tolist() == [0] * 5
        # deadline = start + offset / speed, truncated like the gateway's int(offset / speed)
        assert rep["offset_ns"].tolist() == [int(o / speed) for o in
                                             (0, 1_000_000, 3_000_000, 5_000_000, 5_000_000)]


def test_extended_ids_carry_the_eff_flag_and_short_frames_their_length(exe, tmp_path):
    sink = tmp_path / "sink.bin"
    res = pacing.run_pacer(exe, [(0, [(0x1ABCDEF, b"\x01\x02\x03")])], sink=sink,
                           extended=True)
    got = np.fromfile(sink, dtype=CAN_FRAME)
    assert res.frames_sent == 1
    assert int(got[0]["can_id"]) == 0x1ABCDEF | 0x80000000
    assert int(got[0]["len"]) == 3 and bytes(got[0]["data"]).startswith(b"\x01\x02\x03")


def test_input_cut_inside_a_record_sends_the_whole_records_and_says_so(exe):
    records = b"".join(pacing.PACER_IN.pack(k * 1000, 0x200, 1, b"\x05") for k in range(3))
    rep, rc, err = _run(exe, records[:-5], "-o", "/dev/null")
    assert rep["frames"].sum() == 2 and rc == 0
    assert "input ends inside a record" in err


def test_bad_usage_and_a_missing_interface_are_errors(exe, tmp_path):
    assert _run(exe, b"", "-s", "2")[1] == 2  # neither -i nor -o
    assert _run(exe, b"", "-o", "/dev/null", "-s", "0")[1] == 2
    with pytest.raises(bus.BusError, match="dv_pacer.*(CAN socket|not found)"):
        pacing.run_pacer(exe, [(0, [(0x200, b"\x00")])], interface="nope-can0")


def test_replay_pacer_c_refuses_a_bus_that_is_not_socketcan(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,a\n0,0.1\n0.01,0.2\n0.02,0.3\n")
    assert main(["replay", "--pacer", "c", "-i", "virtual", "-c", "x", str(p)]) == 2
