"""The CAN side: codec use (C codec through the binding), the frame plan, sequence tracking,
and the drift-free replay scheduler on python-can's virtual bus."""
from __future__ import annotations

import re
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from dynval import bus, contract
from dynval.io.recording import Channel, Recording

can = pytest.importorskip("can")


def _rec(n: int = 300, nch: int = 2, fs: float = 640.0) -> Recording:
    rng = np.random.default_rng(1)
    return Recording("r", fs, [Channel(f"c{i}", rng.standard_normal(n) * (i + 1))
                               for i in range(nch)])


def test_ids_match_the_dbc_table():
    assert bus.IDS == {"ctrl": 0x100, "chcfg": 0x101, "samples": 0x200, "status": 0x080,
                       "feature": 0x300, "resid": 0x380}


def test_samples_layout_and_decode_round_trip():
    cid, data = bus.encode_samples(3, 257, (1, -2, bus.RAW_MISSING))
    assert cid == 0x200 and data == struct.pack("<BBhhh", 3, 1, 1, -2, -32768)
    d = bus.decode(cid, data)
    assert isinstance(d, bus.Decoded) and d.fields == {"channel": 3, "seq": 1,
                                                       "raw": [1, -2, -32768]}
    assert bus.decode(0x7FF, bytes(8)) == -6  # unknown id: DV_ERANGE
    assert bus.decode(0x200, bytes(5)) == -2  # bad DLC: DV_ESIZE


def test_quantise_is_the_c_rounding():
    x = np.array([0.5, -0.5, 1.5, 2.49, np.nan, 1e9, -1e9])
    assert bus.quantise(x, 1.0).tolist() == [1, -1, 2, 2, -32768, 32767, -32767]
    assert np.isnan(bus.dequantise(np.array([-32768]), 0.5)[0])


def test_plan_pads_and_frames_each_record():
    plan = bus.make_plan(_rec(301))
    assert plan.padded == 2 and plan.raw[0].size == 303
    batches = list(plan.batches())
    first, last = batches[0][1], batches[-1][1]
    assert [f[0] for f in first] == [0x100, 0x101, 0x101, 0x100]
    assert first[0][1][0] == bus.CTRL_CLEAR and first[-1][1][0] == bus.CTRL_START
    assert last == [(0x100, bus.encode_ctrl(bus.CTRL_STOP, 1)[1])]
    # frame k is due at the time of its last sample
    assert batches[2][0] == round(5 * 1e9 / 640)
    assert plan.n_sample_frames == 2 * 101
    lsb = struct.unpack("<f", first[1][1][4:])[0]
    assert lsb == plan.lsb[0] and np.log2(lsb) == int(np.log2(lsb))


def test_plan_refuses_non_integer_rate():
    with pytest.raises(bus.ConfigError, match="integer"):
        bus.make_plan(_rec(fs=640.5))


def test_seq_tracker_counts_gap_dup_late():
    t = bus.SeqTracker()
    assert [t.update(s) for s in (0, 1, 4, 4, 2)] == ["ok", "ok", "gap", "dup", "late"]
    assert t.counts() == {"ok": 3, "lost": 1, "dup": 1, "late": 1, "stale": 0}


def test_timing_stats_drift_and_percentile():
    st = bus.TimingStats()
    for k in range(1000):
        st.add_batch(k / 100, [50_000 + 1000 * k / 100])  # 50 us + 1 us/s
    r = st.report()
    assert r["drift_us_per_s"] == pytest.approx(1.0, rel=1e-6)
    assert 50 <= r["mean_us"] <= 56 and r["p95_us"] == pytest.approx(60, abs=1.5)


def test_replay_virtual_paced_no_loss_no_drift():
    rx = can.Bus(interface="virtual", channel="t-replay")
    tx = can.Bus(interface="virtual", channel="t-replay")
    got: list = []
    stop = threading.Event()

    def take():
        while not stop.is_set():
            m = rx.recv(0.05)
            if m is not None:
                got.append(m)

    th = threading.Thread(target=take)
    th.start()
    try:
        plan = bus.make_plan(_rec(3 * 640, nch=5, fs=2560.0))  # 0.75 s at 2560 Hz
        t0 = time.perf_counter()
        res = bus.replay(tx, plan)
        wall = time.perf_counter() - t0
    finally:
        time.sleep(0.2)
        stop.set()
        th.join()
        rx.shutdown()
        tx.shutdown()
    assert res.frames_sent == plan.n_frames == len(got)
    assert 0.74 < wall < 1.0
    t = res.timing
    assert t["frames"] == plan.n_frames
    # timing figures belong to the benchmark (bench/RESULTS.gateway.md), not to a test on a
    # loaded machine; the end time above is the check: sleep(dt) accumulation overshoots it
    assert {"mean_us", "p95_us", "max_us", "drift_us_over_run"} <= set(t)
    seqs = [m.data[1] for m in got if m.arbitration_id == 0x200 and m.data[0] == 4]
    assert seqs == [k & 0xFF for k in range(640)]


def test_codec_names_and_ids_come_from_the_dbc_and_the_header():
    dbc = (Path(__file__).resolve().parents[2] / "can" / "dynval.dbc")
    if not dbc.is_file():
        pytest.skip("can/dynval.dbc not beside the package")
    text = dbc.read_text()
    msgs = {n.removeprefix("DV_").lower(): int(i) for i, n in
            re.findall(r"^BO_ (\d+) (\w+):", text, re.M)}
    assert bus.IDS == msgs
    feats = {int(v) for v in contract.named("DV_FEAT_").values()}
    assert set(bus.FEATURE_NAMES) == feats
    assert bus.FEATURE_NAMES[0x22] == "tm_rms_duration"
    assert {bus.CTRL_START, bus.CTRL_STOP, bus.CTRL_CLEAR, bus.CTRL_STATUS} == set(
        contract.DBC_VALUES[(bus.ID_CTRL, "cmd")])
