"""firmware_sim's Modbus server under hostile clients, on 127.0.0.1 only, every loop bounded.

A well-behaved client polls input registers every POLL_S while a hostile one: trickles a request
one byte every 0.45 s (slow loris), holds every client slot open and idle, floods requests and
never reads the replies, or sends garbage framing. The well-behaved client must be served
within the normal poll period each time (latency < MAX_LATENCY_S), and the hostile connection
is closed. Also: mask write (0x16) is validated like a write, writes to unmapped holding
registers get exception 2. Runs without CAN (-i none). Needs build/e2e or DV_E2E_BUILD.

Each test prints the worst latency the good client saw (pytest -s to see it), the figure the
issue asks for.
"""

from __future__ import annotations

import socket
import struct
import sys
import threading
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "e2e"))
import dv_e2e as E  # noqa: E402

pytestmark = pytest.mark.skipif(not E.SIM_BIN.exists(),
                                reason=f"{E.SIM_BIN} not built (tests/e2e/run_e2e.sh)")

POLL_S = 0.1  # the good client's poll period
MAX_LATENCY_S = 0.1  # served within the normal poll period
MAX_CLIENTS = 8  # SIM_MB_MAX_CLIENTS


@pytest.fixture
def sim(tmp_path):
    s = E.Sim(["-i", "none", "-H", "0"], tmp_path)
    yield s
    assert s.stop() == 0, s.stderr()


def mbap(pdu: bytes, tid: int = 1) -> bytes:
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu


def recv_reply(s: socket.socket) -> bytes:
    """One whole response ADU's PDU; b"" when the server closed the connection."""
    buf = b""
    while len(buf) < 7:
        chunk = s.recv(7 - len(buf))
        if not chunk:
            return b""
        buf += chunk
    need = struct.unpack(">H", buf[4:6])[0] - 1
    pdu = b""
    while len(pdu) < need:
        chunk = s.recv(need - len(pdu))
        if not chunk:
            return b""
        pdu += chunk
    return pdu


def request(s: socket.socket, pdu: bytes, tid: int = 1) -> bytes:
    s.sendall(mbap(pdu, tid))
    return recv_reply(s)


class GoodClient(threading.Thread):
    """Reads 10 input registers every POLL_S for `duration` s; keeps the worst latency."""

    def __init__(self, port: int, duration: float):
        super().__init__(daemon=True)
        self.port, self.duration = port, duration
        self.latencies: list[float] = []
        self.errors: list[str] = []

    def run(self) -> None:
        end = time.monotonic() + self.duration
        tid = 0
        while time.monotonic() < end:
            tid = (tid + 1) & 0xFFFF
            t0 = time.monotonic()
            try:
                # a fresh connection each time: connecting must not be locked out either
                with socket.create_connection(("127.0.0.1", self.port), timeout=15) as s:
                    rsp = request(s, struct.pack(">BHH", 4, 0, 10), tid)
                if len(rsp) != 22 or rsp[0] != 4:
                    self.errors.append(f"bad reply {rsp.hex()}")
            except OSError as e:
                self.errors.append(repr(e))
            self.latencies.append(time.monotonic() - t0)
            time.sleep(max(0.0, POLL_S - (time.monotonic() - t0)))

    def worst(self) -> float:
        return max(self.latencies) if self.latencies else float("inf")


def closed_by_server(s: socket.socket, timeout: float) -> bool:
    """True once the server closes (EOF or reset) within `timeout` s; any reply bytes are
    read and ignored."""
    s.settimeout(0.05)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if s.recv(4096) == b"":
                return True
        except TimeoutError:
            continue
        except OSError:
            return True
    return False


def test_hostile_slow_loris_does_not_stall_others(sim):
    good = GoodClient(sim.port, 4.0)
    req = mbap(struct.pack(">BHH", 4, 0, 10))
    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as bad:
        good.start()
        dropped_after = None
        t0 = time.monotonic()
        for b in req[:-1]:  # never completes the request: 11 bytes, 0.45 s apart (< 5 s)
            try:
                bad.sendall(bytes([b]))
            except OSError:
                dropped_after = time.monotonic() - t0
                break
            time.sleep(0.45)
        if dropped_after is None and closed_by_server(bad, 1.0):
            dropped_after = time.monotonic() - t0
        good.join(timeout=20)
    print(f"\nslow loris: good client worst latency {good.worst() * 1e3:.1f} ms over "
          f"{len(good.latencies)} polls; hostile dropped after "
          f"{'never' if dropped_after is None else f'{dropped_after:.2f} s'}")
    assert not good.errors, good.errors[:3]
    assert good.worst() < MAX_LATENCY_S
    assert dropped_after is not None and dropped_after < 2.0


def test_hostile_idle_connections_do_not_lock_out(sim):
    idle = [socket.create_connection(("127.0.0.1", sim.port), timeout=10)
            for _ in range(MAX_CLIENTS)]
    try:
        time.sleep(0.3)  # all accepted and idle
        good = GoodClient(sim.port, 1.5)
        good.run()
        print(f"\n{MAX_CLIENTS} idle connections: good client worst latency "
              f"{good.worst() * 1e3:.1f} ms over {len(good.latencies)} polls")
        assert not good.errors, good.errors[:3]
        assert good.worst() < MAX_LATENCY_S
    finally:
        for s in idle:
            s.close()


def test_hostile_more_connections_than_slots(sim):
    """3 x MAX_CLIENTS connections held open: a new client still gets in at once."""
    hold = [socket.create_connection(("127.0.0.1", sim.port), timeout=10)
            for _ in range(3 * MAX_CLIENTS)]
    try:
        time.sleep(0.2)
        good = GoodClient(sim.port, 1.0)
        good.run()
        assert not good.errors, good.errors[:3]
        assert good.worst() < MAX_LATENCY_S
    finally:
        for s in hold:
            s.close()


def test_hostile_flood_without_reading_replies(sim):
    """A client pipelines requests and never reads: it is dropped once its replies back up,
    others are served meanwhile."""
    good = GoodClient(sim.port, 2.0)
    req = mbap(struct.pack(">BHH", 4, 0, 125))  # 250-byte replies
    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as bad:
        bad.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        bad.settimeout(0.2)
        good.start()
        sent = 0
        end = time.monotonic() + 2.0
        while time.monotonic() < end and sent < 200000:
            try:
                bad.send(req * 16)
                sent += 16
            except (TimeoutError, BlockingIOError):
                time.sleep(0.01)
            except OSError:
                break  # reset: dropped
        good.join(timeout=20)
    print(f"\nflood: {sent} requests sent; good client worst latency "
          f"{good.worst() * 1e3:.1f} ms")
    assert not good.errors, good.errors[:3]
    assert good.worst() < MAX_LATENCY_S


@pytest.mark.parametrize("adu", [
    struct.pack(">HHHB", 1, 5, 6, 1) + bytes([4, 0, 0, 0, 1]),  # protocol id 5
    struct.pack(">HHHB", 1, 0, 0, 1),  # length 0
    struct.pack(">HHHB", 1, 0, 1000, 1) + bytes(20),  # length beyond the ADU maximum
])
def test_hostile_bad_framing_is_closed(sim, adu):
    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as s:
        s.sendall(adu)
        assert closed_by_server(s, 2.0)
    # and the server still answers
    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as s:
        assert request(s, struct.pack(">BHH", 4, 0, 1))[0] == 4


def read_holding(s: socket.socket, addr: int, n: int = 1) -> list[int]:
    rsp = request(s, struct.pack(">BHH", 3, addr, n))
    assert rsp[0] == 3, rsp.hex()
    return list(struct.unpack(f">{n}H", rsp[2:]))


def test_mask_write_is_validated_like_a_write(sim):
    rm = E.regmap()
    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as s:
        n_chan = rm["SIM_HR_N_CHAN"]
        assert read_holding(s, n_chan) == [5]
        # (5 & 0) | 0 = 0 channels: out of range -> exception 3, nothing changes
        rsp = request(s, struct.pack(">BHHH", 0x16, n_chan, 0x0000, 0x0000))
        assert rsp == bytes([0x96, 3])
        assert read_holding(s, n_chan) == [5]
        # (5 & 0xFFF8) | 3 = 3 channels: accepted, echoed, applied
        pdu = struct.pack(">BHHH", 0x16, n_chan, 0xFFF8, 0x0003)
        assert request(s, pdu) == pdu
        assert read_holding(s, n_chan) == [3]
        in_use = request(s, struct.pack(">BHH", 4, rm["SIM_IR_N_CHAN"], 1))
        assert struct.unpack(">H", in_use[2:4])[0] == 3
        # an unmapped register: exception 2
        assert request(s, struct.pack(">BHHH", 0x16, 4, 0, 1)) == bytes([0x96, 2])


@pytest.mark.parametrize("addr,count", [(4, 1), (11, 1), (39, 1), (56, 1), (68, 2), (99, 1),
                                        (3, 3), (54, 4)])
def test_write_to_unmapped_holding_register_is_refused(sim, addr, count):
    def all_holding(s: socket.socket) -> list[int]:
        return read_holding(s, 0, 100) + read_holding(s, 100, 64)  # SIM_N_HOLDING = 164

    with socket.create_connection(("127.0.0.1", sim.port), timeout=10) as s:
        before = all_holding(s)
        if count == 1:
            rsp = request(s, struct.pack(">BHH", 6, addr, 7))
            assert rsp == bytes([0x86, 2])
        else:
            pdu = struct.pack(">BHHB", 0x10, addr, count, 2 * count) + bytes(2 * count)
            assert request(s, pdu) == bytes([0x90, 2])
        assert all_holding(s) == before
