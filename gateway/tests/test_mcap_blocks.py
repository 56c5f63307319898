"""The logger's block path: fixed-layout protobuf bytes equal the protobuf library's own
encoding, the block writer's files read by mcap's indexed reader (message indexes per channel,
statistics), sequence events of interleaved channels counted as frame by frame, and a writer
that cannot keep up drops whole blocks, counted, logged and written as an event."""
from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval import bus
from dynval.io.mcapfile import iter_messages, read_mcap
from dynval.mcap_log import AsyncLog, McapLog
from dynval.mcap_schema import descriptor_set, fill_tags, payload_fields
from dynval.mcap_writer import HEADER_BYTES, record_dtype


def _pb_class(name: str) -> Any:
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    pool = descriptor_pool.DescriptorPool()
    for f in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set()).file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def test_fixed_layout_bytes_are_protobuf_with_every_field() -> None:
    """Every field written at its fixed width, in number order, is what protobuf itself
    writes for non-default values; parsing gives the values back (NaN included)."""
    b = np.zeros(2, record_dtype(payload_fields("Sample")))
    fill_tags(b, "Sample")
    b["channel"], b["index"], b["value"], b["verdict"] = [3, 7], [2**40 + 5, 9], [-1.25, 2.5], \
        [1, 4]
    cls = _pb_class("dynval.Sample")
    first = b[0].tobytes()[HEADER_BYTES:]
    assert first == cls(channel=3, index=2**40 + 5, value=-1.25, verdict=1).SerializeToString()
    assert len(first) == 5 + 9 + 9 + 2  # fixed32, fixed64, double, one-byte enum
    b["value"][1] = np.nan
    m = cls.FromString(b[1].tobytes()[HEADER_BYTES:])
    assert (m.channel, m.index, m.verdict) == (7, 9, 4) and math.isnan(m.value)
    f = np.zeros(1, record_dtype(payload_fields("CanFrame", 5)))
    fill_tags(f, "CanFrame", 5)
    f["id"], f["extended"], f["dlc"], f["data"] = 0x1ABCDEF, 1, 5, [[1, 2, 3, 4, 255]]
    want = _pb_class("dynval.CanFrame")(id=0x1ABCDEF, extended=True, dlc=5,
                                        data=bytes([1, 2, 3, 4, 255]))
    assert f[0].tobytes()[HEADER_BYTES:] == want.SerializeToString()


def _log(p: Path, nch: int, n_frames: int, skip: set[tuple[int, int]] = frozenset(),
         dup: set[tuple[int, int]] = frozenset(), block: int = 97) -> dict[str, Any]:
    """nch channels at 1000 Hz through on_frames in blocks of `block` frames (channels
    interleaved), frames (channel, k) in skip not sent, those in dup sent twice."""
    ids, datas = [], []
    for cid, data in [(bus.ID_CTRL, bus.encode_ctrl(bus.CTRL_CLEAR)[1]),
                      *(bus.encode_chcfg(c, 1000, 2.0 ** -4) for c in range(nch)),
                      bus.encode_ctrl(bus.CTRL_START, 1)]:
        ids.append(cid)
        datas.append(data)
    for k in range(n_frames):
        for c in range(nch):
            if (c, k) in skip:
                continue
            for _ in range(2 if (c, k) in dup else 1):
                cid, data = bus.encode_samples(c, k, [k, -k, c])
                ids.append(cid)
                datas.append(data)
    t = np.arange(len(ids), dtype=np.int64) * 1000 + 10**18
    with McapLog(p, channel_names=[f"c{c}" for c in range(nch)], chunk_size=8192) as lg:
        for a in range(0, len(ids), block):
            d = np.frombuffer(b"".join(datas[a:a + block]), np.uint8).reshape(-1, 8)
            lg.on_frames(t[a:a + block], np.array(ids[a:a + block], np.uint32),
                         np.full(d.shape[0], 8, np.uint8), d)
    return lg.summary()


def test_block_files_read_by_the_official_indexed_reader(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    p = tmp_path / "b.mcap"
    s = _log(p, nch=12, n_frames=400)  # 300 wraps the 8-bit counter
    with open(p, "rb") as f:
        r = make_reader(f)
        st = r.get_summary().statistics  # type: ignore[union-attr]
        by_topic = {c.id: c.topic for c in r.get_summary().channels.values()}  # type: ignore
        got = [(ch.topic, m.log_time) for _, ch, m in r.iter_messages(topics=["/dv/samples/c7"])]
    assert st.message_count == sum(s["messages"].values())
    assert {by_topic[c]: n for c, n in st.channel_message_counts.items()}["/dv/samples/c7"] \
        == 3 * 400
    # the topic filter goes through the per-channel message indexes; 3 samples per frame at
    # 1000 Hz from the START frame's receive time (after CLEAR and 12 DV_CHCFG, 1 us apart)
    t_start = 10**18 + 13 * 1000
    assert got == [("/dv/samples/c7", t_start + i * 1_000_000) for i in range(1200)]
    rec = read_mcap(p)
    k = np.arange(400)
    want = np.column_stack([k, -k, np.full(400, 7)]).ravel() * 2.0 ** -4
    assert np.array_equal(rec.channels[7].data, want) and rec.fs_hz == 1000.0


def test_sequence_events_of_interleaved_channels(tmp_path: Path) -> None:
    """Gaps and duplicates spread over channels and over block edges are counted as the
    frame-by-frame tracker counts them, each on its own channel."""
    skip = {(2, 10), (2, 11), (5, 96), (5, 97), (5, 98), (0, 300)}
    dup = {(3, 50), (7, 200)}
    s = _log(tmp_path / "g.mcap", nch=8, n_frames=320, skip=skip, dup=dup, block=64)
    assert s["events"] == {"seq_gap": 6, "seq_dup": 2}
    assert {c: v["lost"] for c, v in s["sequence"].items() if v["lost"]} == \
        {"c0": 1, "c2": 2, "c5": 3}
    assert {c: v["dup"] for c, v in s["sequence"].items() if v["dup"]} == {"c3": 1, "c7": 1}
    ev = [m.data for m in iter_messages(tmp_path / "g.mcap", topics={"/dv/events"})]
    gaps = sorted((e["channel"], e["count"]) for e in ev if e["event"] == "seq_gap")
    assert gaps == [(0, 1), (2, 2), (5, 3)]
    rec = read_mcap(tmp_path / "g.mcap")
    assert np.isnan(rec.channels[5].data).sum() == 9  # the 3 lost frames' samples


class _Msg:
    def __init__(self, t: float, cid: int, data: bytes) -> None:
        self.timestamp, self.arbitration_id, self.data = t, cid, data
        self.is_extended_id = self.is_error_frame = False


def test_a_writer_behind_the_bus_drops_whole_blocks_counted(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch,
                                                            caplog: pytest.LogCaptureFixture
                                                            ) -> None:
    """The reader never waits: with the writer held, blocks beyond the queue are dropped,
    counted, logged and written to the file as logger_overflow events with their count."""
    monkeypatch.setattr(AsyncLog, "MAX_BLOCKS", 2)
    monkeypatch.setattr(AsyncLog, "BLOCK_FRAMES", 10)
    p = tmp_path / "o.mcap"
    lg = McapLog(p, channel_names=["a"])
    gate, taken = threading.Event(), threading.Event()
    real = lg.on_frames

    def held(*a: Any) -> None:
        taken.set()
        gate.wait(10)
        real(*a)

    monkeypatch.setattr(lg, "on_frames", held)
    w = AsyncLog(lg)
    msgs = [_Msg(1.7e9 + k * 1e-3, *bus.encode_samples(0, k, [k, k, k])) for k in range(100)]
    for m in msgs[:10]:
        w.put(m)
    assert taken.wait(5)  # the writer holds the first block
    t0 = time.monotonic()
    for m in msgs[10:]:  # 9 more blocks: two queued, seven dropped
        w.put(m)
    assert time.monotonic() - t0 < 1.0  # the reader did not wait
    time.sleep(0.2)
    gate.set()
    w.close()
    s = lg.close()
    assert w.dropped == 70 and s["events"]["logger_overflow"] == 70
    assert s["messages"]["/dv/samples/a"] == 3 * 30
    warned = [r.getMessage() for r in caplog.records if "behind the bus" in r.getMessage()]
    assert warned == ["the MCAP writer is behind the bus: 10 frames dropped so far"]
    ev = [m.data for m in iter_messages(p, topics={"/dv/events"})]
    assert sum(e["count"] for e in ev if e["event"] == "logger_overflow") == 70
