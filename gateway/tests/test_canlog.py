"""python-can conventions: the bus configuration (arguments, CAN_INTERFACE, ~/.canrc), the
standard CAN log formats through python-can's own readers and writers (round trips of .blf,
.asc, .trc and candump .log), replay of a log and of a test on the virtual bus, `dynval log
-o x.blf`, MCAP <-> candump conversion, and the errors without a CAN interface."""
from __future__ import annotations

import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from dynval import bus, canlog
from dynval.cli import main
from dynval.errors import ConfigError, InputFileError
from dynval.io import read_test
from dynval.io.mcapfile import read_mcap
from dynval.io.recording import Channel, Recording
from dynval.mcap_log import McapLog

can = pytest.importorskip("can")


def _chan() -> str:
    return f"dv-test-{uuid.uuid4().hex[:8]}"


def _frames(n: int = 50) -> list[can.Message]:
    rng = np.random.default_rng(3)
    out = []
    for k in range(n):
        ext = k % 7 == 3
        out.append(can.Message(timestamp=1700000000.0 + k * 0.0015625,
                               arbitration_id=int(rng.integers(0, 0x1FFFFFFF if ext else 0x7FF)),
                               is_extended_id=ext,
                               data=bytes(rng.integers(0, 256, k % 9).tolist()),
                               channel=0))
    return out


def _csv(tmp_path: Path, n: int = 96, fs: int = 640) -> Path:
    t = np.arange(n) / fs
    p = tmp_path / "t.csv"
    rows = ["time_s,force_N,acc1_mps2"] + [
        f"{ti:.9f},{10 * np.sin(2 * np.pi * 5 * ti):.6f},{np.cos(2 * np.pi * 7 * ti):.6f}"
        for ti in t]
    p.write_text("\n".join(rows) + "\n")
    return p


# ---- configuration ----------------------------------------------------------------------------
def test_bus_config_takes_arguments_then_environment_then_canrc(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for v in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)  # no can.ini of the caller's
    assert bus.bus_config() == {"interface": "socketcan", "channel": "vcan0"}
    (tmp_path / ".canrc").write_text("[default]\ninterface = pcan\nchannel = PCAN_USBBUS1\n"
                                     "bitrate = 500000\n")
    assert bus.bus_config() == {"interface": "pcan", "channel": "PCAN_USBBUS1",
                                "bitrate": 500000}
    monkeypatch.setenv("CAN_INTERFACE", "kvaser")
    monkeypatch.setenv("CAN_CHANNEL", "0")
    assert bus.bus_config() == {"interface": "kvaser", "channel": 0, "bitrate": 500000}
    monkeypatch.setenv("CAN_INTERFACE", "nosuchbus")  # a misspelt interface is not ignored
    with pytest.raises(ConfigError, match="nosuchbus"):
        bus.bus_config()
    cfg = bus.bus_config("virtual", "x", 250000, {"receive_own_messages": True})
    assert cfg == {"interface": "virtual", "channel": "x", "bitrate": 250000,
                   "receive_own_messages": True}


def test_unknown_interface_and_bad_bus_option_are_one_line_errors(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    p = _csv(tmp_path)
    assert main(["replay", str(p), "--interface", "nosuchbus"]) == 2
    assert "nosuchbus" in caplog.text and "udp_multicast" in caplog.text
    caplog.clear()
    assert main(["replay", str(p), "-i", "virtual", "--bus-option", "fd"]) == 2
    assert "KEY=VALUE" in caplog.text


def test_without_a_can_interface_replay_and_log_say_what_to_use(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    p = _csv(tmp_path)
    for argv in (["replay", str(p)], ["log", "-o", str(tmp_path / "x.mcap"), "--duration", "0"]):
        caplog.clear()
        rc = main([*argv, "--interface", "socketcan", "--channel", "dvnosuch0"])
        assert rc == 2
        msg = caplog.records[-1].getMessage()
        assert "socketcan:dvnosuch0" in msg and "--interface virtual" in msg
        assert "dynval run" in msg and "\n" not in msg


# ---- log files ---------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".blf", ".asc", ".trc", ".log"])
def test_python_can_log_round_trip(tmp_path: Path, suffix: str) -> None:
    """Frames written with python-can's writer come back from canlog.frames unchanged: ids,
    extended flag, payload, and timestamps (relative for ASC, to the format's precision)."""
    sent = _frames()
    p = tmp_path / f"x{suffix}"
    w = can.Logger(p)
    for m in sent:
        w.on_message_received(m)
    w.stop()
    assert canlog.is_can_log(p)
    got = list(canlog.frames(p))
    assert len(got) == len(sent)
    assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got] == \
           [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in sent]
    dt_sent = np.diff([m.timestamp for m in sent])
    dt_got = np.diff([m.timestamp for m in got])
    assert np.max(np.abs(dt_got - dt_sent)) < 2e-6  # BLF: ns, ASC/TRC/candump: us


def test_vector_asc_is_not_read_as_numbers(tmp_path: Path) -> None:
    p = tmp_path / "run.asc"
    w = can.Logger(p)
    for m in _frames(5):
        w.on_message_received(m)
    w.stop()
    with pytest.raises(InputFileError, match="Vector ASC CAN log") as e:
        read_test(p, fs_hz=640.0)
    assert str(p) in str(e.value)
    num = tmp_path / "num.asc"  # a whitespace-numeric test with the .asc suffix still reads
    num.write_text("1.0 2.0\n3.0 4.0\n")
    assert not canlog.is_can_log(num)
    assert read_test(num, fs_hz=10.0).n_samples == 2


def test_a_damaged_log_is_one_error_naming_the_file(tmp_path: Path) -> None:
    p = tmp_path / "bad.blf"
    p.write_bytes(b"LOGG" + bytes(40))
    with pytest.raises(InputFileError) as e:
        list(canlog.frames(p))
    assert str(p) in str(e.value)


# ---- the bus -----------------------------------------------------------------------------------
def test_replay_of_a_test_and_of_its_candump_log_send_the_same_frames(
        tmp_path: Path) -> None:
    """`dynval replay t.csv` on the virtual bus, recorded by `dynval log -o x.log` (candump
    -L through python-can), then `dynval replay x.log`: the second replay sends the frames of
    the first, in order, at the recorded intervals."""
    ch = _chan()
    test = _csv(tmp_path)
    out = tmp_path / "x.log"
    rc: list[int] = []

    def send() -> None:
        time.sleep(0.3)
        rc.append(main(["replay", str(test), "-i", "virtual", "-c", ch, "--speed", "4"]))

    t = threading.Thread(target=send)
    t.start()
    assert main(["log", "-o", str(out), "-i", "virtual", "-c", ch, "--idle-timeout", "1.0"]) == 0
    t.join(10)
    assert rc == [0]
    first = [(m.arbitration_id, bytes(m.data)) for m in canlog.frames(out)]
    plan = bus.make_plan(read_test(test))
    assert first == [f for _, fr in plan.batches() for f in fr]
    rx = can.Bus(interface="virtual", channel=ch)
    try:
        res = canlog.replay_log(can.Bus(interface="virtual", channel=ch), out, speed=4.0)
        got = []
        while (m := rx.recv(timeout=0.2)) is not None:
            got.append(m)
    finally:
        rx.shutdown()
    assert res.frames_sent == len(first) and res.send_errors == 0
    assert [(m.arbitration_id, bytes(m.data)) for m in got] == first
    # the log holds the first replay at 4x (96 samples at 640 Hz: 150 ms -> ~37 ms); the
    # second replay is paced at 4x the log's own timestamps again (~9 ms), not asap
    stamps = [m.timestamp for m in canlog.frames(out)]
    span_log = stamps[-1] - stamps[0]
    # no frame leaves before its deadline: the run lasts at least the log's span / 4
    assert 0.030 < span_log and span_log / 4 <= res.wall_s < span_log / 4 + 1.0
    assert got[-1].timestamp - got[0].timestamp < span_log  # faster than the log
    assert res.timing["frames"] == len(first)


def test_mcap_to_candump_and_back_keeps_the_samples(tmp_path: Path) -> None:
    """A dynval MCAP's raw frames as candump -L (read back by python-can's CanutilsLogReader),
    then decoded into an MCAP again: the same values, and the frames at their log times."""
    rng = np.random.default_rng(5)
    rec = Recording("r", 640.0, [Channel("a", rng.standard_normal(60)),
                                 Channel("b", rng.standard_normal(60) * 3)])
    plan = bus.make_plan(rec)
    src = tmp_path / "src.mcap"
    t0 = 1_700_000_000_000_000_000
    with McapLog(src, meta={"fs_hz": "640", "n_samples": "60"}, channel_names=["a", "b"]) as mc:
        for off, frames in plan.batches():
            for cid, data in frames:
                mc.on_frame(t0 + off, cid, data)
    dump = tmp_path / "x.log"
    assert main(["convert", str(src), "-o", str(dump)]) == 0
    lines = dump.read_text().splitlines()
    cid0, data0 = plan.setup[0]
    assert len(lines) == plan.n_frames
    assert lines[0].startswith(f"(1700000000.000000) can0 {cid0:03X}#{data0.hex().upper()}")
    got = list(can.CanutilsLogReader(dump))
    assert [(m.arbitration_id, bytes(m.data)) for m in got] == \
           [f for _, fr in plan.batches() for f in fr]
    back = tmp_path / "back.mcap"
    assert main(["convert", str(dump), "-o", str(back)]) == 0
    a, b = read_mcap(src), read_mcap(back, lenient=True)
    for c in range(2):
        assert np.array_equal(a.channels[c].data, plan.values(c))
        assert np.array_equal(b.channels[c].data[:60], plan.values(c))


def test_log_to_blf_records_the_bus(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ch = _chan()
    out = tmp_path / "x.blf"
    sent = _frames(20)

    def send() -> None:
        time.sleep(0.3)
        tx = can.Bus(interface="virtual", channel=ch)
        for m in sent:
            tx.send(m)
        tx.shutdown()

    t = threading.Thread(target=send)
    t.start()
    assert main(["log", "-o", str(out), "--interface", "virtual", "--channel", ch,
                 "--idle-timeout", "0.8"]) == 0
    t.join(10)
    assert f"{out}: 20 frames from virtual:{ch}" in capsys.readouterr().out
    got = list(can.BLFReader(out))
    assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got] == \
           [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in sent]
