"""firmware_sim never publishes a non-finite value and never fails silently, without CAN
(-i none, frames fed with --replay):

* an lsb beyond SIM_LSB_MAX is refused (DV_CHCFG counted in BAD_CFG, Modbus exception 3): the
  issue's lsb 1e6 with raw +-3000 made the record kurtosis NaN in every record, lsb 1e27 was
  accepted;
* at the largest lsb and full-scale raw counts (spikes of +-32767 included) every feature
  frame is finite and none is held back (SIM_IR_NONFINITE stays 0);
* a log that cannot be written (/dev/full) ends the program with exit status 1 and a message;
* unparsable replay lines are counted and reported, the good ones still fed in.
Needs build/e2e or DV_E2E_BUILD.
"""

from __future__ import annotations

import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "e2e"))
import dv_e2e as E  # noqa: E402

pytestmark = pytest.mark.skipif(not E.SIM_BIN.exists(),
                                reason=f"{E.SIM_BIN} not built (tests/e2e/run_e2e.sh)")

LSB_MAX = 512.0  # SIM_LSB_MAX (sim_regmap.h)


def write_log(path: Path, frames: list[E.Frame]) -> None:
    with open(path, "w") as f:
        for i, fr in enumerate(frames):
            ident = f"{fr.id:08X}" if fr.extended else f"{fr.id:03X}"
            f.write(f"({1700000000 + i * 1e-3:.6f}) vcan0 {ident}#{fr.data.hex().upper()}\n")


def feature_values(log: Path) -> list[tuple[int, int, float]]:
    """(feat_id, channel, value) of every DV_FEATURE frame the program sent."""
    out = []
    for ln in log.read_text().splitlines():
        ident, data = ln.split()[2].split("#")
        if int(ident, 16) == E.ID_FEATURE and len(ident) == 3:
            b = bytes.fromhex(data)
            out.append((b[0], b[1], struct.unpack("<f", b[4:8])[0]))
    return out


def run_replay(tmp_path: Path, frames: list[E.Frame]) -> tuple[list[int], Path]:
    log = tmp_path / "in.log"
    write_log(log, frames)
    s = E.Sim(["-i", "none", "--replay", str(log), *E.SIM_ARGS, "-H", "0"], tmp_path)
    try:
        rsp = E.raw_modbus(s.port, struct.pack(">BHH", 4, 0, 100))
        regs = list(struct.unpack(">100H", rsp[2:]))
    finally:
        assert s.stop() == 0, s.stderr()
    return regs, s.log


def noisy_raw(n: int, amp: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    raw = np.clip(np.round(rng.normal(0, amp / 3, (n, E.N_CHAN))), -32767, 32767)
    raw[::97] = 32767  # full-scale spikes
    raw[50::131] = -32767
    return raw.astype(np.int64)


def test_lsb_beyond_max_refused_and_nothing_nonfinite_sent(tmp_path):
    rm = E.regmap()
    n = 2 * E.SEG * E.NSEG
    setup = [E.chcfg(c, E.FS_HZ, 1e6 if c < 2 else 1e27 if c == 2 else 2.0**-10)
             for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START)]
    regs, log = run_replay(tmp_path, setup + E.sample_frames(noisy_raw(n, 3000, 1)))
    assert E.u32(regs, rm["SIM_IR_BAD_CFG"]) == 3
    vals = feature_values(log)
    assert vals, "no features sent"
    assert all(math.isfinite(v) for _, _, v in vals)
    assert E.u32(regs, rm["SIM_IR_NONFINITE"]) == 0


def test_largest_lsb_full_scale_every_feature_finite(tmp_path):
    rm = E.regmap()
    n = 2 * E.SEG * E.NSEG
    setup = [E.chcfg(c, E.FS_HZ, LSB_MAX) for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START)]
    regs, log = run_replay(tmp_path, setup + E.sample_frames(noisy_raw(n, 32767, 2)))
    assert E.u32(regs, rm["SIM_IR_BAD_CFG"]) == 0
    vals = feature_values(log)
    ids = {f for f, _, _ in vals}
    assert {0x11, 0x13, 0x14, 0x20, 0x24}.issubset(ids)  # record STD, skew, kurt, E, K
    assert all(math.isfinite(v) for _, _, v in vals)
    assert E.u32(regs, rm["SIM_IR_NONFINITE"]) == 0
    assert E.u32(regs, rm["SIM_IR_NAN_SAMPLES"]) == 0


def test_modbus_lsb_write_beyond_max_is_exception_3(tmp_path):
    rm = E.regmap()
    s = E.Sim(["-i", "none", "-H", "0"], tmp_path)
    try:
        for lsb in (1e6, 1e27, LSB_MAX * 1.01):
            b = struct.unpack(">I", struct.pack(">f", lsb))[0]
            pdu = struct.pack(">BHHBHH", 0x10, rm["SIM_HR_LSB"], 2, 4, b >> 16, b & 0xFFFF)
            assert E.raw_modbus(s.port, pdu) == bytes([0x90, 3])
        b = struct.unpack(">I", struct.pack(">f", LSB_MAX))[0]
        pdu = struct.pack(">BHHBHH", 0x10, rm["SIM_HR_LSB"], 2, 4, b >> 16, b & 0xFFFF)
        assert E.raw_modbus(s.port, pdu)[0] == 0x10
    finally:
        assert s.stop() == 0, s.stderr()


def test_log_write_failure_exits_1(tmp_path):
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    log = tmp_path / "in.log"
    write_log(log, [E.ctrl(E.CTRL_START)] * 100)
    r = subprocess.run([str(E.SIM_BIN), "-i", "none", "-p", str(E.free_port()), "-l",
                        "/dev/full", "--replay", str(log)], capture_output=True, text=True,
                       timeout=30, check=False)
    assert r.returncode == 1
    assert "cannot write log /dev/full" in r.stderr
    assert "ready" not in r.stdout


def test_replay_parse_errors_counted_and_reported(tmp_path):
    log = tmp_path / "in.log"
    good = "(1700000000.000000) vcan0 100#0100000000000000\n"
    log.write_text(good + "(1.0) vcan0 1G0#00\n\n(1.0) vcan0 100#0\n(1.0) vcan0 100#0Z\n"
                   "garbage\n(1.0) vcan0 100#000000000000000000\n" + good)
    s = E.Sim(["-i", "none", "--replay", str(log), "-H", "0"], tmp_path)
    try:
        rm = E.regmap()
        rsp = E.raw_modbus(s.port, struct.pack(">BHH", 4, rm["SIM_IR_RX_FRAMES"], 2))
        assert struct.unpack(">I", rsp[2:6])[0] == 2  # the two good lines only
        assert "5 unparsable line(s) skipped, first at line 2" in s.stderr()
    finally:
        assert s.stop() == 0, s.stderr()
