"""firmware_sim on the host without CAN (-i none): frames fed from a candump -L file with
--replay, then a real Modbus TCP client (pymodbus) reads features and counters, writes
configuration, and gets proper exceptions for bad requests. Also: busy port, missing
interface. Needs build/e2e (tests/e2e/run_e2e.sh builds it) or DV_E2E_BUILD.
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "e2e"))
import dv_e2e as E  # noqa: E402

pymodbus_client = pytest.importorskip("pymodbus.client")
pytestmark = pytest.mark.skipif(not E.SIM_BIN.exists(),
                                reason=f"{E.SIM_BIN} not built (tests/e2e/run_e2e.sh)")

N_SAMPLES = 2 * E.SEG * E.NSEG


def write_log(path: Path, frames: list[E.Frame]) -> None:
    with open(path, "w") as f:
        for i, fr in enumerate(frames):
            ident = f"{fr.id:08X}" if fr.extended else f"{fr.id:03X}"
            f.write(f"({1700000000 + i * 1e-3:.6f}) vcan0 {ident}#{fr.data.hex().upper()}\n")


def logged_features(path: Path, ident_want: int = E.ID_FEATURE) -> dict:
    out = {}
    for ln in path.read_text().splitlines():
        _, _, fr = ln.split()
        ident, data = fr.split("#")
        if int(ident, 16) == ident_want and len(ident) == 3:
            key = E.feature_key if ident_want == E.ID_FEATURE else E.resid_key
            k, v = key(bytes.fromhex(data))
            assert k not in out, f"frame {k} sent twice"
            out[k] = v
    return out


@pytest.fixture
def damaged(tmp_path):
    x = E.test_signal(N_SAMPLES, seed=21)
    lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
    clean = E.sample_frames(E.quantise(x, lsbs))
    frames, inj = E.inject_faults(clean, E.N_CHAN * 200, np.random.default_rng(9), n_each=4)
    setup = [E.chcfg(c, E.FS_HZ, lsbs[c]) for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START)]
    log = tmp_path / "in.log"
    write_log(log, setup + frames)
    return log, setup + frames, inj, lsbs


@pytest.fixture
def sim(tmp_path, damaged):
    s = E.Sim(["-i", "none", "--replay", str(damaged[0]), *E.SIM_ARGS], tmp_path)
    yield s
    assert s.stop() == 0, s.stderr()


def test_sim_replay_counters_and_features(sim, damaged):
    _, frames, inj, lsbs = damaged
    rm = E.regmap()
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        regs = E.read_inputs(c, rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_STRIDE"] * rm["SIM_MAX_CHAN"])
    assert regs[rm["SIM_IR_VERSION"]] == rm["SIM_REGMAP_VERSION"]
    assert regs[rm["SIM_IR_N_CHAN"]] == E.N_CHAN
    got = {k: E.u32(regs, rm[f"SIM_IR_{k}"]) for k in
           ("RX_FRAMES", "LOST", "DUP", "LATE", "BAD_DLC", "UNKNOWN_ID", "NAN_SAMPLES", "STALE")}
    assert got == {"RX_FRAMES": len(frames), "LOST": inj.lost, "DUP": inj.dup,
                   "LATE": inj.late, "BAD_DLC": inj.bad_dlc, "UNKNOWN_ID": inj.unknown,
                   "NAN_SAMPLES": inj.nan, "STALE": 0}
    want = E.offline_features(E.accepted_stream(frames), lsbs)
    assert logged_features(sim.log) == want
    for ch in range(E.N_CHAN):
        b = rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_STRIDE"] * ch
        last_rec = max(k[2] for k in want if k[0] == ch and k[1] == 0x11)
        assert E.u32(regs, b + rm["SIM_IR_CH_REC_STD"]) == want[(ch, 0x11, last_rec)]
        assert E.u32(regs, b + rm["SIM_IR_CH_RECORDS"]) == last_rec + 1
    # stage status registers: observer and AR are reported, not faked
    assert regs[rm["SIM_IR_OBS_STATUS"]] in (rm["SIM_STAGE_NOT_CONFIGURED"],
                                             rm["SIM_STAGE_RUNNING"])


def test_sim_replay_ar_and_observer_bit_exact(tmp_path):
    """AR stage (baseline fit + residual RMS/outliers) and observer residual frames equal the
    library run offline on the same samples."""
    x = E.test_signal(3 * E.SEG * E.NSEG, seed=4)
    lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
    frames = E.sample_frames(E.quantise(x, lsbs))
    setup = [E.chcfg(c, E.FS_HZ, lsbs[c]) for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START)]
    log = tmp_path / "in.log"
    write_log(log, setup + frames)
    s = E.Sim(["-i", "none", "--replay", str(log), *E.SIM_ARGS, "-A", str(E.AR_ORDER),
               "-o", str(E.OUTLIER_X100), "-d", "3", "-m", E.model_arg(E.LANL_MODEL)], tmp_path)
    try:
        rm = E.regmap()
        with pymodbus_client.ModbusTcpClient("127.0.0.1", port=s.port, timeout=10) as c:
            regs = E.read_inputs(c, 200)
        assert regs[rm["SIM_IR_OBS_STATUS"]] == rm["SIM_STAGE_RUNNING"]
        assert regs[rm["SIM_IR_AR_STATUS"]] == rm["SIM_STAGE_RUNNING"]
        assert E.u32(regs, rm["SIM_IR_OBS_STEPS"]) == 3 * E.SEG * E.NSEG
    finally:
        assert s.stop() == 0, s.stderr()
    feats, resid = E.offline_run(E.accepted_stream(frames), lsbs, ar=(E.AR_ORDER, E.OUTLIER_X100),
                                 model=E.LANL_MODEL, decim=3)
    got = logged_features(s.log)
    assert got == feats
    assert {k for k in feats if k[1] == 0x40} == {(c, 0x40, r) for c in range(E.N_CHAN)
                                                 for r in (1, 2)}
    assert logged_features(s.log, E.ID_RESID) == resid
    assert len(resid) == 4 * (3 * E.SEG * E.NSEG // 3)


def test_sim_replay_observer_stays_aligned_across_faults(tmp_path, damaged):
    """Lost frames become NaN placeholders for the observer: its residuals on a damaged stream
    equal the library's on the same stream with the gaps filled by missing samples."""
    log, frames, inj, lsbs = damaged
    assert inj.lost > 0 and inj.late > 0
    s = E.Sim(["-i", "none", "--replay", str(log), *E.SIM_ARGS, "-m", E.model_arg(E.LANL_MODEL)],
              tmp_path)
    assert s.stop() == 0, s.stderr()
    feats, resid = E.offline_run(E.accepted_stream(frames, placeholders=True), lsbs,
                                 model=E.LANL_MODEL)
    assert logged_features(s.log) == feats
    got = logged_features(s.log, E.ID_RESID)
    assert got == resid
    n_steps = min(len(v) for v in E.accepted_stream(frames, placeholders=True).values())
    assert len(resid) == 4 * n_steps


def test_sim_modbus_write_config_takes_effect(sim):
    rm = E.regmap()
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        before = E.read_inputs(c, 200)
        assert E.u32(before, rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_RECORDS"]) > 0
        w = c.write_register(rm["SIM_HR_WIN_LEN"], 128)
        assert not w.isError()
        assert c.read_holding_registers(rm["SIM_HR_WIN_LEN"], count=1).registers == [128]
        after = E.read_inputs(c, 200)
        # re-initialised: record count restarts, latest features read NaN until recomputed
        b = rm["SIM_IR_CH_BASE"]
        assert E.u32(after, b + rm["SIM_IR_CH_RECORDS"]) == 0
        assert np.isnan(E.f32(after, b + rm["SIM_IR_CH_REC_STD"]))
        assert E.u32(after, rm["SIM_IR_CFG_WRITES"]) == E.u32(before, rm["SIM_IR_CFG_WRITES"]) + 1
        # counters are kept across re-init
        assert E.u32(after, rm["SIM_IR_LOST"]) == E.u32(before, rm["SIM_IR_LOST"])
        # a float register pair: the lsb of channel 2
        lsb = struct.unpack(">I", struct.pack(">f", 0.5))[0]
        w = c.write_registers(rm["SIM_HR_LSB"] + 4, [lsb >> 16, lsb & 0xFFFF])
        assert not w.isError()
        r = c.read_holding_registers(rm["SIM_HR_LSB"] + 4, count=2).registers
        assert E.bits_f32((r[0] << 16) | r[1]) == 0.5


def test_sim_modbus_bad_requests_get_exceptions(sim):
    rm = E.regmap()
    n_in = rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_STRIDE"] * rm["SIM_MAX_CHAN"]
    n_hold = rm["SIM_HR_MODEL"] + 2 * rm["SIM_N_MODEL"]
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        r = c.read_input_registers(n_in - 1, count=2)  # runs past the end
        assert r.isError() and r.exception_code == 2
        r = c.read_holding_registers(n_hold, count=1)
        assert r.isError() and r.exception_code == 2
        r = c.read_coils(0, count=1)  # no coils in this map
        assert r.isError() and r.exception_code == 2
        for addr, val in [(rm["SIM_HR_N_CHAN"], 0), (rm["SIM_HR_N_CHAN"], 9),
                          (rm["SIM_HR_N_SEG"], 5000), (rm["SIM_HR_FORCE_CHAN"], 7)]:
            r = c.write_register(addr, val)
            assert r.isError() and r.exception_code == 3, (addr, val)
        nan = struct.unpack(">I", struct.pack(">f", float("nan")))[0]
        r = c.write_registers(rm["SIM_HR_LSB"], [nan >> 16, nan & 0xFFFF])
        assert r.isError() and r.exception_code == 3
        r = c.write_register(n_hold, 1)
        assert r.isError() and r.exception_code == 2
        assert c.read_holding_registers(rm["SIM_HR_N_CHAN"], count=1).registers == [E.N_CHAN]
    # functions the server does not implement: exception 1 (illegal function)
    for fc in (0x08, 0x2B, 0x41):
        rsp = E.raw_modbus(sim.port, bytes([fc, 0, 0, 0, 0]))
        assert rsp == bytes([fc | 0x80, 1]), (fc, rsp)
    # still serving
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        assert not c.read_input_registers(0, count=1).isError()


def test_sim_busy_port_and_bad_usage(sim, tmp_path):
    import subprocess
    r = subprocess.run([str(E.SIM_BIN), "-i", "none", "-p", str(sim.port)], capture_output=True,
                       text=True, timeout=20)
    assert r.returncode == 4 and "busy" in r.stderr
    r = subprocess.run([str(E.SIM_BIN), "-w", "1"], capture_output=True, text=True, timeout=20)
    assert r.returncode == 2 and "usage" in r.stderr
    r = subprocess.run([str(E.SIM_BIN), "-i", "none", "-a", "999.1.1.1", "-p", str(E.free_port())],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode == 4 and "not an IPv4 address" in r.stderr


def test_sim_missing_can_interface(tmp_path):
    import subprocess
    r = subprocess.run([str(E.SIM_BIN), "-i", "nosuchcan0", "-p", str(E.free_port())],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode == 3 and "CAN" in r.stderr


def test_sim_heartbeat_and_sigint(tmp_path):
    """DV_STATUS every HEARTBEAT_MS (logged even without CAN); SIGINT is a clean shutdown."""
    import signal
    import time
    s = E.Sim(["-i", "none", "-H", "100"], tmp_path)
    time.sleep(1.05)
    s.proc.send_signal(signal.SIGINT)
    assert s.proc.wait(timeout=10) == 0
    s.stop()
    beats = [ln for ln in s.log.read_text().splitlines() if " 080#" in ln]
    assert 8 <= len(beats) <= 11, len(beats)
    counters = [int(b.split("#")[1][2:4], 16) for b in beats]
    assert counters == list(range(counters[0], counters[0] + len(beats)))


def test_sim_core_in_process_via_ctypes():
    """The firmware loop without sockets, loaded from libdv_simcore as the gateway would run
    it in-process: same frames in, same feature frames out as the offline library run."""
    import ctypes
    import re
    libs = sorted((E.BUILD / "firmware_sim").glob("libdv_simcore-*.so"))
    if not libs:
        pytest.skip("libdv_simcore not built")
    hdr = (E.ROOT / "firmware_sim" / "sim_core.h").read_text()
    max_out = int(re.search(r"#define SIM_CORE_MAX_OUT (\d+)", hdr).group(1))

    class CanFrame(ctypes.Structure):
        _fields_ = [("id", ctypes.c_uint32), ("dlc", ctypes.c_uint8),
                    ("data", ctypes.c_uint8 * 8)]

    try:
        lib = ctypes.CDLL(str(libs[0]))
    except OSError as e:  # e.g. a sanitizer build: its runtime must be preloaded
        pytest.skip(f"cannot load {libs[0].name}: {e}")
    lib.sim_core_new.restype = ctypes.c_void_p
    lib.sim_core_new.argtypes = [ctypes.c_void_p]
    lib.sim_core_delete.argtypes = [ctypes.c_void_p]
    lib.sim_core_handle.restype = ctypes.c_size_t
    lib.sim_core_handle.argtypes = [ctypes.c_void_p, ctypes.POINTER(CanFrame),
                                    ctypes.POINTER(CanFrame)]
    core = lib.sim_core_new(None)  # defaults: 5 channels, window 256, 64 x 64, 640 Hz
    assert core
    try:
        x = E.test_signal(2 * 4096, seed=8)
        lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
        frames = E.sample_frames(E.quantise(x, lsbs))
        setup = [E.chcfg(c, 640, lsbs[c]) for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START)]
        out = (CanFrame * max_out)()
        got = {}
        for f in setup + frames:
            fin = CanFrame(f.id, len(f.data), (ctypes.c_uint8 * 8)(*f.data.ljust(8, b"\0")))
            for i in range(lib.sim_core_handle(core, ctypes.byref(fin), out)):
                if out[i].id == E.ID_FEATURE:
                    k, v = E.feature_key(bytes(out[i].data))
                    got[k] = v
    finally:
        lib.sim_core_delete(core)
    want = E.offline_features(E.accepted_stream(frames), lsbs, win=256, seg=64, nseg=64, fs=640)
    assert len(want) > 1000 and got == want


def test_sim_log_reads_with_python_can(sim):
    """The --log file is candump -L format: python-can's CanutilsLogReader reads it."""
    can = pytest.importorskip("can")
    msgs = list(can.CanutilsLogReader(str(sim.log)))
    assert len(msgs) > 100
    assert {m.arbitration_id for m in msgs} >= {E.ID_SAMPLES, E.ID_FEATURE, E.ID_CHCFG}
    assert any(m.is_extended_id for m in msgs)  # the injected 29-bit id
