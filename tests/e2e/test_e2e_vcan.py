"""End-to-end on a real vcan bus: firmware_sim on vcan0, a recorded test sent frame by frame
with python-can, feature frames compared bit for bit with the library run offline on the same
quantised samples, injected faults counted exactly, Modbus read/write with pymodbus.

Needs vcan0 up (tests/e2e/run_e2e.sh provides it, directly or in a VM); skipped otherwise
unless DV_E2E_REQUIRE_VCAN=1.
"""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import numpy as np
import pytest

import dv_e2e as E

can = pytest.importorskip("can")
pymodbus_client = pytest.importorskip("pymodbus.client")

HAVE_VCAN = Path("/sys/class/net/vcan0").exists()
if not HAVE_VCAN and os.environ.get("DV_E2E_REQUIRE_VCAN") == "1":
    raise RuntimeError("DV_E2E_REQUIRE_VCAN=1 but vcan0 does not exist")
pytestmark = pytest.mark.skipif(not HAVE_VCAN, reason="no vcan0 (run tests/e2e/run_e2e.sh)")

N_SAMPLES = 3 * E.SEG * E.NSEG  # three records per channel
SO_RCVBUFFORCE = 33


@pytest.fixture
def outdir(tmp_path):
    d = Path(os.environ.get("VCAN_OUT", tmp_path))
    return d


@pytest.fixture
def bus():
    b = can.Bus(interface="socketcan", channel="vcan0", receive_own_messages=False)
    try:
        b.socket.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 8 << 20)
    except OSError:
        pass
    yield b
    b.shutdown()


@pytest.fixture
def sim(outdir):
    s = E.Sim(["-i", "vcan0", *E.SIM_ARGS], outdir)
    yield s
    rc = s.stop()
    assert rc == 0, f"firmware_sim exit {rc}: {s.stderr()}"


class Link:
    """Sender + collector over python-can; barriers use DV_CTRL STATUS -> DV_STATUS."""

    def __init__(self, bus):
        self.bus = bus
        self.sent = 0
        self.features: dict[tuple[int, int, int], int] = {}
        self.resid: dict[tuple[int, int], int] = {}
        self.repeats = 0
        self.last_status: bytes | None = None
        self.n_status = 0

    def _take(self, m) -> bool:
        if m.arbitration_id == E.ID_FEATURE and len(m.data) == 8:
            k, v = E.feature_key(bytes(m.data))
            if k in self.features:
                self.repeats += 1
            self.features[k] = v
        elif m.arbitration_id == E.ID_RESID and len(m.data) == 8:
            k, v = E.resid_key(bytes(m.data))
            if k in self.resid:
                self.repeats += 1
            self.resid[k] = v
        elif m.arbitration_id == E.ID_STATUS:
            self.last_status = bytes(m.data)
            self.n_status += 1
            return True
        return False

    def send(self, f: E.Frame) -> None:
        self.bus.send(can.Message(arbitration_id=f.id, data=f.data, is_extended_id=f.extended))
        self.sent += 1
        while (m := self.bus.recv(timeout=0)) is not None:
            self._take(m)

    def barrier(self, timeout: float = 60.0) -> bytes:
        n0 = self.n_status  # the answer may already be taken while send() drains
        self.send(E.ctrl(E.CTRL_STATUS))
        deadline = time.monotonic() + timeout
        while self.n_status == n0 and time.monotonic() < deadline:
            m = self.bus.recv(timeout=1.0)
            if m is not None:
                self._take(m)
        if self.n_status > n0:
            return self.last_status
        raise TimeoutError("no DV_STATUS answer from firmware_sim")

    def send_all(self, frames: list[E.Frame], barrier_every: int) -> None:
        for i, f in enumerate(frames):
            self.send(f)
            if (i + 1) % barrier_every == 0:
                self.barrier()
        self.barrier()


def setup_frames(lsbs):
    return [E.chcfg(c, E.FS_HZ, lsbs[c]) for c in range(E.N_CHAN)] + [E.ctrl(E.CTRL_START, 1)]


def modbus_counters(port: int) -> dict[str, int]:
    rm = E.regmap()
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=port, timeout=10) as c:
        regs = E.read_inputs(c, 500)
    names = ["RX_FRAMES", "TX_FRAMES", "DROPPED", "LOST", "DUP", "LATE", "STALE", "BAD_DLC",
             "UNKNOWN_ID", "NAN_SAMPLES", "BAD_CHAN", "IGNORED", "BAD_CFG", "SAMPLES"]
    out = {n: E.u32(regs, rm[f"SIM_IR_{n}"]) for n in names}
    out["_regs"] = regs  # type: ignore[assignment]
    return out


def f32_regs(values):
    out = []
    for v in values:
        b = E.f32_bits(v)
        out += [b >> 16, b & 0xFFFF]
    return out


def test_e2e_clean_stream_features_bit_exact(sim, bus):
    """Features, AR residual features and observer residuals, all configured over Modbus."""
    rm = E.regmap()
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        assert not c.write_register(rm["SIM_HR_AR_ORDER"], E.AR_ORDER).isError()
        assert not c.write_register(rm["SIM_HR_OUTLIER_X100"], E.OUTLIER_X100).isError()
        assert not c.write_register(rm["SIM_HR_RESID_DECIM"], 1).isError()
        assert not c.write_registers(rm["SIM_HR_MODEL"], f32_regs(E.LANL_MODEL)).isError()
        st = c.read_input_registers(rm["SIM_IR_OBS_STATUS"], count=1).registers[0]
        assert st == rm["SIM_STAGE_RUNNING"]
    x = E.test_signal(N_SAMPLES)
    lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
    raw = E.quantise(x, lsbs)
    frames = E.sample_frames(raw)
    link = Link(bus)
    link.send_all(setup_frames(lsbs) + frames, barrier_every=100)
    want, want_resid = E.offline_run(E.accepted_stream(frames), lsbs,
                                     ar=(E.AR_ORDER, E.OUTLIER_X100), model=E.LANL_MODEL)
    n_ar = E.N_CHAN * 2 * 2  # records 1 and 2 (record 0 is the baseline): RMS + outliers
    assert len(want) == E.N_CHAN * (3 * E.NSEG * 5 - 4 * ((E.WIN - 1) // E.SEG) + 3 * 16) + n_ar
    assert len(want_resid) == 4 * N_SAMPLES
    assert link.resid == want_resid
    missing = set(want) - set(link.features)
    extra = set(link.features) - set(want)
    assert not missing and not extra, (sorted(missing)[:5], sorted(extra)[:5])
    diff = [k for k in want if want[k] != link.features[k]]
    assert not diff, [(k, hex(want[k]), hex(link.features[k])) for k in diff[:5]]
    assert link.repeats == 0
    n = modbus_counters(sim.port)
    assert n["RX_FRAMES"] == link.sent
    assert n["TX_FRAMES"] == len(want) + len(want_resid) + (link.sent - len(frames) - E.N_CHAN - 1)
    for k in ("DROPPED", "LOST", "DUP", "LATE", "STALE", "BAD_DLC", "UNKNOWN_ID", "NAN_SAMPLES",
              "BAD_CHAN", "IGNORED", "BAD_CFG"):
        assert n[k] == 0, k
    assert n["SAMPLES"] == E.N_CHAN * (N_SAMPLES // 3) * 3


def test_e2e_faults_counted_exactly_features_of_accepted_stream(sim, bus):
    x = E.test_signal(N_SAMPLES, seed=11)
    lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
    raw = E.quantise(x, lsbs)
    clean = E.sample_frames(raw)
    # damage only after the first record of every channel has gone out
    start = E.N_CHAN * (E.SEG * E.NSEG // 3 + 1)
    frames, inj = E.inject_faults(clean, start, np.random.default_rng(3), n_each=6)
    link = Link(bus)
    # bursts: 2000 frames back to back between barriers
    link.send_all(setup_frames(lsbs) + frames, barrier_every=2000)
    n = modbus_counters(sim.port)
    assert n["DROPPED"] == 0
    assert (n["LOST"], n["DUP"], n["LATE"], n["BAD_DLC"], n["UNKNOWN_ID"], n["NAN_SAMPLES"]) == (
        inj.lost, inj.dup, inj.late, inj.bad_dlc, inj.unknown, inj.nan)
    assert n["STALE"] == 0 and n["BAD_CHAN"] == 0
    assert n["RX_FRAMES"] == link.sent
    # the heartbeat frame says the same (8-bit saturating fields)
    st = link.last_status
    assert st is not None
    assert (int.from_bytes(st[2:4], "little"), st[4], st[5], st[6], st[7]) == (
        inj.lost, inj.dup, inj.late, inj.bad_dlc, inj.unknown)
    # per-channel gaps
    rm = E.regmap()
    for c in range(E.N_CHAN):
        base = rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_STRIDE"] * c
        assert E.u32(n["_regs"], base + rm["SIM_IR_CH_LOST"]) == inj.per_chan_lost.get(c, 0)
    # features: bit-exact against the library on the samples the firmware accepted
    want = E.offline_features(E.accepted_stream(frames), lsbs)
    assert link.features == want
    # and the undamaged first record is what the clean stream gives
    clean_want = E.offline_features(E.accepted_stream(clean), lsbs)
    rec0 = {k: v for k, v in clean_want.items()
            if (k[1] >= 0x10 and k[2] == 0) or (k[1] < 0x10 and k[2] < E.NSEG)}
    assert rec0 and all(link.features[k] == v for k, v in rec0.items())
    # the damaged part differs from the clean stream (the faults did reach the features)
    assert any(link.features.get(k) != v for k, v in clean_want.items())


def test_e2e_modbus_config_takes_effect(sim, bus):
    rm = E.regmap()
    seg, nseg = 16, 8
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        wr = c.write_registers(rm["SIM_HR_SEG_LEN"], [seg, nseg])
        assert not wr.isError(), wr
        rr = c.read_holding_registers(rm["SIM_HR_SEG_LEN"], count=2)
        assert list(rr.registers) == [seg, nseg]
        bad = c.write_register(rm["SIM_HR_SEG_LEN"], 1)  # < 2: refused, nothing changes
        assert bad.isError() and bad.exception_code == 3
    x = E.test_signal(3 * seg * nseg, seed=2)  # whole frames, whole records
    lsbs = [E.lsb_for(x[:, c]) for c in range(E.N_CHAN)]
    frames = E.sample_frames(E.quantise(x, lsbs))
    link = Link(bus)
    link.send_all(setup_frames(lsbs) + frames, barrier_every=100)
    want = E.offline_features(E.accepted_stream(frames), lsbs, seg=seg, nseg=nseg)
    assert link.features == want
    assert max(k[2] for k in want if k[1] == 0x01) == 3 * nseg - 1  # segments of 16 samples
    with pymodbus_client.ModbusTcpClient("127.0.0.1", port=sim.port, timeout=10) as c:
        regs = E.read_inputs(c, 500)
    for ch in range(E.N_CHAN):
        b = rm["SIM_IR_CH_BASE"] + rm["SIM_IR_CH_STRIDE"] * ch
        assert E.u32(regs, b + rm["SIM_IR_CH_RECORDS"]) == 3
        assert E.u32(regs, b + rm["SIM_IR_CH_REC_STD"]) == want[(ch, 0x11, 2)]
        assert E.u32(regs, b + rm["SIM_IR_CH_SEG_STD"]) == want[(ch, 0x01, 3 * nseg - 1)]


def test_e2e_missing_interface_is_a_clear_error(outdir):
    with pytest.raises(RuntimeError) as e:
        E.Sim(["-i", "vcan9"], outdir, timeout=20)
    assert "rc 3" in str(e.value) and "vcan9" in str(e.value)
