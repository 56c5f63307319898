"""MCAP logging of the dynval bus: every frame raw on /can/raw, decoded samples per channel on
/dv/samples/<channel>, features on /dv/features, residuals on /dv/residuals, DV_STATUS on
/dv/status, control frames on /dv/control, counted anomalies (unknown ids, bad frames,
sequence gaps, frames the logger dropped) on /dv/events and the same with the run control as
text on /dv/log (foxglove.Log). A "dynval" metadata record (test, channel map, rate, units,
model, software version, source hash) is written first, a "dynval.summary" record at the end.

At bus rate: frames are decoded in blocks by the C codec (dv_codec_decode_n, dv_seq_update_n,
dv_codec_sample_values) and the high-rate topics (samples, raw frames, features, residuals)
are protobuf messages of a fixed layout (mcap_schema) built a block at a time as numpy record
arrays (mcap_writer); the low-rate ones (status, control, events, log) stay JSON with a JSON
Schema. AsyncLog runs all of it in a writer thread behind a bounded queue, so the bus reader
never waits for the file.

For Foxglove's plot panel every sample is its own message: {channel, index, value, verdict},
value NaN for a missing sample (its raw counts and frame counter are on /can/raw). Times come
from the test's own clock: from DV_CTRL START on, a sample's log_time and publish_time are
the START frame's receive time + index / fs, so a replay faster than real time (--asap) keeps
the test's time base; the other messages are logged at the time of the latest sample
received (after STOP: that plus the wall time since), with their receive time as
publish_time. Files of the previous layouts (JSON
samples, one or three per message) are still read (io.mcapfile).

Written incrementally: chunks of at most chunk_size bytes (or max_chunk_age_s of wall time),
compressed (lz4, else zstd, else none), with CRCs, each flushed to the OS as it is finished,
so a killed logger leaves a file readable up to its last complete chunk
(dynval.io.mcapfile.iter_messages recovers it)."""
from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections import Counter
from functools import cache
from operator import attrgetter
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.writer import CompressionType

from dynval import __version__, _core, bus
from dynval.contract import IR_COUNTERS
from dynval.errors import DynvalError
from dynval.mcap_schema import MESSAGES, descriptor_set, fill_tags, full_name, payload_fields
from dynval.mcap_writer import BlockWriter, record_dtype
from dynval.topics import (
    CHANNEL_NAMES_KEY,
    T_CONTROL,
    T_EVENTS,
    T_FEATURES,
    T_LOG,
    T_RAW,
    T_RESID,
    T_SAMPLES,
    T_STATUS,
)

log = logging.getLogger(__name__)

PROFILE = ""  # JSON and protobuf messages

_INT = {"type": "integer"}
_NUM = {"type": "number"}
_STR = {"type": "string"}
SCHEMAS: dict[str, dict[str, Any]] = {  # the low-rate topics' JSON messages
    "dynval.Status": {"state": _INT, "beat": _INT, "lost": _INT, "dup": _INT, "late": _INT,
                      "bad_dlc": _INT, "unknown": _INT},
    "dynval.Control": {"kind": _STR, "cmd": _INT, "record_id": _INT, "channel": _INT,
                       "flags": _INT, "fs_hz": _INT, "lsb": _NUM},
    "dynval.Event": {"event": _STR, "id": _INT, "channel": _INT, "count": _INT,
                     "detail": _STR},
}
#: the high-rate topics' protobuf messages (mcap_schema), by schema name
BINARY = {full_name(m): m for m in MESSAGES}
#: Foxglove's well-known log message (the foxglove.Log JSON schema of the Foxglove SDK's
#: schemas: its log panel lists these); level: 1 DEBUG, 2 INFO, 3 WARNING, 4 ERROR
LOG_LEVELS = ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL")
FOXGLOVE_LOG: dict[str, Any] = {
    "title": "foxglove.Log", "description": "A log message", "type": "object",
    "properties": {
        "timestamp": {"type": "object", "title": "time",
                      "properties": {"sec": {"type": "integer", "minimum": 0},
                                     "nsec": {"type": "integer", "minimum": 0,
                                              "maximum": 999999999}},
                      "description": "Timestamp of log message"},
        "level": {"title": "foxglove.LogLevel", "description": "Log level",
                  "oneOf": [{"title": n, "const": i} for i, n in enumerate(LOG_LEVELS)]},
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"}},
    "required": ["timestamp", "level", "message", "name", "file", "line"]}
TOPIC_SCHEMA = {T_RAW: "dynval.CanFrame", T_FEATURES: "dynval.Feature",
                T_RESID: "dynval.Residual", T_STATUS: "dynval.Status",
                T_CONTROL: "dynval.Control", T_EVENTS: "dynval.Event", T_LOG: "foxglove.Log"}


def schema_json(name: str) -> dict[str, Any]:
    """The JSON Schema registered for a schema name."""
    if name == "foxglove.Log":
        return FOXGLOVE_LOG
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": name,
            "type": "object", "properties": SCHEMAS[name]}


_COUNTER_AT = {a: name for name, a in IR_COUNTERS.items()}


def refused_event(status: int) -> str:
    """The event of a frame the codec refused with status: the name of the firmware counter
    that counts it (sim_refused_counter, the one table firmware and log share)."""
    return _COUNTER_AT[int(_core.sim_lib.sim_refused_counter(status))]


class LogError(DynvalError):
    """The MCAP file cannot be written."""


def payload_names(msg: str) -> list[str]:
    return [f for f, _, _ in MESSAGES[msg]]


def compression() -> CompressionType:
    """lz4 if installed, else zstd, else none. lz4 compresses the logger's chunks about twice
    as fast as zstd at its fastest level (about 250 vs 130 MB/s here), for files about 1.4x
    larger (bench/RESULTS.gateway.md): CPU headroom at bus rate comes first."""
    from importlib.util import find_spec

    if find_spec("lz4") is not None:
        return CompressionType.LZ4
    if find_spec("zstandard") is not None:
        return CompressionType.ZSTD
    return CompressionType.NONE


_KIND = {CompressionType.ZSTD: "zstd", CompressionType.LZ4: "lz4", CompressionType.NONE: ""}


class _Flushing:
    """A write stream that hands every write (a finished chunk, metadata) to the OS at once;
    a failed write (a full disk) is a LogError naming the file."""

    def __init__(self, f: IO[bytes], path: Path) -> None:
        self.f = f
        self.path = path

    def write(self, b: bytes) -> int:
        try:
            n = self.f.write(b)
            self.f.flush()
        except OSError as exc:
            raise LogError(f"{self.path}: cannot write the log: {exc.strerror or exc}") from exc
        return n

    def tell(self) -> int:
        return self.f.tell()

    def flush(self) -> None:
        self.f.flush()


def _dumps(d: dict[str, Any]) -> bytes:
    return json.dumps(d, separators=(",", ":"), allow_nan=False).encode()


class McapLog:
    """Decode and log frames to one MCAP file: on_frames() per block of received frames
    (on_frame() buffers single frames into blocks); close() (or the context manager) writes
    the summary and finishes the file."""

    def __init__(self, path: Path | str, *, meta: dict[str, Any] | None = None,
                 channel_names: list[str] | None = None, chunk_size: int = 4 << 20,
                 max_chunk_age_s: float = 0.5, compress: CompressionType | None = None,
                 log_raw: bool = True) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._f = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as exc:
            raise LogError(f"{self.path}: cannot write: {exc.strerror or exc}") from exc
        kind = compress if compress is not None else compression()
        self._w = BlockWriter(_Flushing(self._f, self.path), chunk_size=chunk_size,
                              compression=_KIND[kind], profile=PROFILE,
                              library=f"dynval {__version__}")
        self._schema: dict[str, int] = {}
        self._chan: dict[str, int] = {}
        self.names = list(channel_names or [])
        self.lsb: dict[int, float] = {}
        self._lsb = np.full(bus.SeqBank.N, bus.DEFAULT_LSB, np.float32)  # by channel number
        self._seq = bus.SeqBank()
        self._seen: set[int] = set()  # channels with sample frames since START
        self._sample_cid = np.zeros(bus.SeqBank.N, np.uint16)  # MCAP channel of each
        self.counts: Counter[str] = Counter()
        self.events: Counter[str] = Counter()
        self.last_status: dict[str, int] | None = None
        self.log_raw = log_raw
        self.max_age_ns = int(max_chunk_age_s * 1e9)
        self._last_flush = time.monotonic_ns()
        self.fs_hz = 0  # the rate of the DV_CHCFG frames (data time of the sample frames)
        self.frames_logged = 0  # sample frames per channel since START (the highest + 1)
        self._frames_flushed = 0  # frames_logged when the last chunk was finished
        self._closed = False
        self._pending: list[tuple[int, int, bytes]] = []  # on_frame's, not yet in a block
        self.t_first: int | None = None
        self.t_last = 0
        self.t0_ns: int | None = None  # receive time of DV_CTRL START: sample 0 of the test
        self._stopped: tuple[int, int] | None = None  # (receive, test clock) at STOP
        md = {k: v if isinstance(v, str) else json.dumps(v) for k, v in (meta or {}).items()}
        md.setdefault("software", f"dynval {__version__}")
        self._w.add_metadata("dynval", md)
        for topic in (T_RAW, T_FEATURES, T_RESID, T_STATUS, T_CONTROL, T_EVENTS, T_LOG):
            self._channel(topic, TOPIC_SCHEMA[topic])

    # -- channels ----------------------------------------------------------------------------
    def _channel(self, topic: str, schema: str) -> int:
        cid = self._chan.get(topic)
        if cid is not None:
            return cid
        binary = schema in BINARY
        sid = self._schema.get(schema)
        if sid is None:
            sid = (self._w.register_schema(full_name(BINARY[schema]), "protobuf",
                                           descriptor_set()) if binary else
                   self._w.register_schema(schema, "jsonschema",
                                           json.dumps(schema_json(schema)).encode()))
            self._schema[schema] = sid
        md = {CHANNEL_NAMES_KEY: json.dumps(self.names)} if self.names and binary else {}
        cid = self._w.register_channel(topic, "protobuf" if binary else "json", sid, md)
        self._chan[topic] = cid
        return cid

    def channel_name(self, ch: int) -> str:
        return self.names[ch] if ch < len(self.names) else f"ch{ch}"

    def sample_ns(self, index: int) -> int | None:
        """log_time of sample `index` on the test's clock (None before START and DV_CHCFG)."""
        if self.t0_ns is None or not self.fs_hz:
            return None
        return self.t0_ns + round(index * 1e9 / self.fs_hz)

    def clock_ns(self, t_ns: int) -> int:
        """log_time of a message received at t_ns that is not a sample: the test clock of the
        latest sample received; after STOP, that plus the wall time since; host time before
        START."""
        return int(self._clock(np.array([t_ns], np.int64),
                               np.array([self.frames_logged], np.int64))[0])

    def _clock(self, t_ns: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """clock_ns of messages received at t_ns when `frames` sample frames were logged."""
        if self._stopped is not None:
            return self._stopped[1] + (t_ns - self._stopped[0])
        if self.t0_ns is None or not self.fs_hz:
            return t_ns
        last = np.maximum(0, frames * bus.SAMPLES_PER_FRAME - 1)
        return np.asarray(self.t0_ns + np.rint(last * 1e9 / self.fs_hz).astype(np.int64))

    def _put(self, topic: str, t_ns: int, d: dict[str, Any], schema: str | None = None,
             seq: int = 0, log_ns: int | None = None) -> None:
        """One JSON message received at t_ns (publish_time), logged at log_ns (default
        clock_ns(t_ns))."""
        cid = self._chan.get(topic)
        if cid is None:
            cid = self._channel(topic, schema or TOPIC_SCHEMA[topic])
        self._w.add(cid, self.clock_ns(t_ns) if log_ns is None else log_ns, t_ns, _dumps(d),
                    seq)
        self.counts[topic] += 1

    def _block(self, topic: str, msg: str, n: int, log: np.ndarray, pub: np.ndarray,
               seq: np.ndarray | int = 0, bytes_len: int = 8,
               cid: np.ndarray | None = None) -> np.ndarray:
        """A block of n binary messages on topic (or on the channels cid, one per message),
        times and sequence set, tags written; the caller fills the payload and hands it to
        self._w.add_block."""
        if cid is None:
            self.counts[topic] += n
        b = self._w.new_block(self._channel(topic, full_name(msg)) if cid is None else cid,
                              _template(msg, bytes_len), n)
        b["_log"], b["_pub"], b["_seq"] = log, pub, seq
        return b

    def text(self, t_ns: int, level: str, message: str) -> None:
        """A foxglove.Log message on /dv/log."""
        ts = self.clock_ns(t_ns)
        self._put(T_LOG, t_ns, {"timestamp": {"sec": ts // 1_000_000_000,
                                              "nsec": ts % 1_000_000_000},
                                "level": LOG_LEVELS.index(level), "message": message,
                                "name": "dynval", "file": "", "line": 0}, log_ns=ts)

    def event(self, t_ns: int, event: str, *, can_id: int = -1, channel: int = -1,
              count: int = 1, detail: str = "") -> None:
        self.events[event] += count
        log.debug("event %s id=0x%X ch=%d n=%d %s", event, can_id, channel, count, detail)
        self._put(T_EVENTS, t_ns, {"event": event, "id": can_id, "channel": channel,
                                   "count": count, "detail": detail})
        where = f" on {self.channel_name(channel)}" if channel >= 0 else ""
        frame = f" (id 0x{can_id:X})" if can_id >= 0 else ""
        self.text(t_ns, "WARNING", f"{event}{where}{frame}: {count}"
                  f"{', ' + detail if detail else ''}")

    # -- frames ------------------------------------------------------------------------------
    def on_frame(self, t_ns: int, can_id: int, data: bytes, extended: bool = False) -> None:
        """Log one frame received at t_ns (integer ns, epoch): buffered, logged with the next
        block (on_frames), tick() or close()."""
        self._pending.append((t_ns, (can_id | bus.EFF_FLAG) if extended else can_id,
                              bytes(data)))
        if len(self._pending) >= PENDING_FRAMES:
            self._drain()

    def _drain(self) -> None:
        if self._pending:
            p, self._pending = self._pending, []
            t, ids, datas = zip(*p, strict=True)
            self.on_frames(*frame_arrays(t, ids, datas))

    def on_frames(self, t_ns: np.ndarray, ids: np.ndarray, dlc: np.ndarray,
                  data: np.ndarray) -> None:
        """Log a block of frames received at t_ns (int64 ns, epoch): ids (uint32, EFF_FLAG
        for extended ones), their lengths dlc, data n x 8 bytes. Decoded by the C codec in
        one call; DV_CTRL/DV_CHCFG frames (which change the time base) split the block."""
        if self._closed or t_ns.size == 0:
            return
        self._drain()
        if self.t_first is None:
            self.t_first = int(t_ns[0])
        self.t_last = int(t_ns[-1])
        status, msgs = bus.decode_block(ids, np.minimum(dlc, 9), data)
        kind = msgs.view(bus.msg_dtype("samples"))["kind"]
        lib = _core.lib
        ctl = np.flatnonzero((status == 0) & ((kind == lib.DV_MSG_CTRL) |
                                              (kind == lib.DV_MSG_CHCFG)))
        f = _Frames(t_ns, ids, dlc, data, status, msgs, kind)
        start = 0
        for c in (*ctl.tolist(), t_ns.size):
            self._segment(f.part(start, c))
            if c < t_ns.size:
                self._control(f.part(c, c + 1))
            start = c + 1
        self.tick()

    def _segment(self, f: _Frames) -> None:
        """Frames without a change of time base: samples, results, status, refused ones."""
        if f.n == 0:
            return
        lib = _core.lib
        logged = self._samples(f, np.flatnonzero(f.kind == lib.DV_MSG_SAMPLES))
        clock = self._clock(f.t, logged)  # each frame at the test time of the latest sample
        if self.log_raw:
            self._raw(f, clock)
        for k in np.flatnonzero(f.status != 0).tolist():
            st = int(f.status[k])
            self.event(int(f.t[k]), refused_event(st), can_id=int(f.ids[k]) & ~bus.EFF_FLAG,
                       detail=f"{_core.status_name(st)}, dlc {int(f.dlc[k])}")
        for topic, member, msg in ((T_FEATURES, "feature", "Feature"),
                                   (T_RESID, "resid", "Residual")):
            sel = np.flatnonzero(f.kind == getattr(lib, f"DV_MSG_{member.upper()}"))
            if sel.size:
                self._result(topic, msg, f.msgs[sel].view(bus.msg_dtype(member)),
                             clock[sel], f.t[sel])
        for k in np.flatnonzero(f.kind == lib.DV_MSG_STATUS).tolist():
            d = f.msgs[k:k + 1].view(bus.msg_dtype("status"))[0]
            self.last_status = {n: int(d[n]) for n in STATUS_FIELDS}
            self._put(T_STATUS, int(f.t[k]), self.last_status, log_ns=int(clock[k]))

    def _raw(self, f: _Frames, clock: np.ndarray) -> None:
        """/can/raw: every frame as received (grouped by length: one layout per length)."""
        one = f.n > 0 and bool((f.dlc == f.dlc[0]).all())  # the usual block: views, no copies
        for n in ([int(f.dlc[0])] if one else np.unique(f.dlc).tolist()):
            sel: Any = slice(None) if one else np.flatnonzero(f.dlc == n)
            width = min(int(n), 8)
            b = self._block(T_RAW, "CanFrame", f.n if one else sel.size, clock[sel], f.t[sel],
                            bytes_len=width)
            b["id"] = f.ids[sel] & ~np.uint32(bus.EFF_FLAG)
            b["extended"] = (f.ids[sel] & np.uint32(bus.EFF_FLAG)) != 0
            b["dlc"] = f.dlc[sel]
            b["data"] = f.data[sel, :width]
            self._w.add_block(b)

    def _result(self, topic: str, msg: str, d: np.ndarray, clock: np.ndarray,
                t: np.ndarray) -> None:
        """DV_FEATURE / DV_RESID frames: value as double, bits its binary32 bits."""
        b = self._block(topic, msg, d.size, clock, t)
        for name in payload_names(msg):
            if name == "bits":
                b["bits"] = np.ascontiguousarray(d["value"]).view(np.uint32)
            else:
                b[name] = d[name]
        self._w.add_block(b)

    def _control(self, f: _Frames) -> None:
        """One DV_CTRL or DV_CHCFG frame: raw, then the change of time base, then logged."""
        t_ns = int(f.t[0])
        if self.log_raw:
            self._raw(f, self._clock(f.t, np.array([self.frames_logged])))
        kind = "chcfg" if int(f.kind[0]) == _core.lib.DV_MSG_CHCFG else "ctrl"
        rec = f.msgs.view(bus.msg_dtype(kind))[0]
        d: dict[str, Any] = {n: (float(rec[n]) if n == "lsb" else int(rec[n]))
                             for n in rec.dtype.names if n != "kind"}
        if kind == "chcfg":
            self.lsb[d["channel"]] = d["lsb"]
            self._lsb[d["channel"]] = d["lsb"]
            self.fs_hz = d["fs_hz"]
        elif d["cmd"] == bus.CTRL_START:
            self._seq.reset()
            self._seen.clear()
            self.frames_logged = self._frames_flushed = 0
            self.t0_ns, self._stopped = t_ns, None
        elif d["cmd"] == bus.CTRL_STOP and self.t0_ns is not None:
            self._stopped = (t_ns, self.clock_ns(t_ns))
        self._put(T_CONTROL, t_ns, {"kind": kind, **d})
        if kind == "ctrl" and d["cmd"] in (bus.CTRL_START, bus.CTRL_STOP):
            what = "START" if d["cmd"] == bus.CTRL_START else "STOP"
            self.text(t_ns, "INFO", f"{what} record {d['record_id']}: "
                      f"{len(self.lsb)} channel(s) at {self.fs_hz} Hz")

    @property
    def logged_s(self) -> float:
        """Data time (s since START) of the sample frames logged so far."""
        return self.frames_logged * bus.SAMPLES_PER_FRAME / self.fs_hz if self.fs_hz else 0.0

    def tick(self) -> None:
        """Finish the chunk in progress when it is older than max_chunk_age_s of wall time or
        holds more than that of data time (a replay faster than real time): bounds what a
        crash can lose at any speed. on_frames calls it; a receive loop calls it on every
        timeout too, so a burst followed by silence reaches the disk as well."""
        if self._closed:
            return
        self._drain()
        now = time.monotonic_ns()
        new_frames = self.frames_logged - self._frames_flushed
        data_ns = new_frames * bus.SAMPLES_PER_FRAME * 1e9 / self.fs_hz if self.fs_hz else 0
        if now - self._last_flush > self.max_age_ns:
            self._w.flush()
            self._w.sync()  # on disk now, not only queued: what a kill can lose is bounded
        elif data_ns > self.max_age_ns / 2:  # faster than real time: write behind by at
            self._w.flush()  # most one chunk (half the age), the next one built meanwhile
            self._w.sync(pending=1)
        else:
            return
        self._last_flush = now
        self._frames_flushed = self.frames_logged

    def _samples(self, f: _Frames, sel: np.ndarray) -> np.ndarray:
        """Log the DV_SAMPLES frames f[sel] of every channel at once: sequence verdicts and
        frame numbers since START (dv_seq_track_n), events, one message per sample. Returns
        for every frame of f the sample frames logged up to and including it (frames_logged
        as it grows)."""
        if sel.size == 0:
            return np.full(f.n, self.frames_logged, np.int64)
        s = f.msgs[sel].view(bus.msg_dtype("samples"))
        ch = s["channel"]
        last = self._seq.last.copy()
        verdict, k = self._seq.track(ch, s["seq"])
        accepted = verdict <= 1  # ok, gap
        counts = np.bincount(ch, minlength=bus.SeqBank.N)
        for c in np.flatnonzero(counts).tolist():
            n = int(counts[c])
            self._seen.add(c)
            topic = T_SAMPLES + self.channel_name(c)
            if not self._sample_cid[c]:
                self._sample_cid[c] = self._channel(topic, full_name("Sample"))
            self.counts[topic] += n * bus.SAMPLES_PER_FRAME
        for j in np.flatnonzero(verdict != 0).tolist():
            self._seq_event(f, sel, ch, k, accepted, last, j, int(verdict[j]))
        per = bus.SAMPLES_PER_FRAME
        idx = (np.maximum(k, 0)[:, None] * per + np.arange(per)).ravel()
        if self.t0_ns is not None and self.fs_hz:
            ts = self.t0_ns + np.rint(idx * 1e9 / self.fs_hz).astype(np.int64)
        else:
            ts = np.repeat(f.t[sel], per)
        b = self._block("", "Sample", idx.size, ts, ts, idx & 0xFFFFFFFF,
                        cid=np.repeat(self._sample_cid[ch], per))
        b["channel"], b["index"] = np.repeat(ch, per), idx
        b["value"] = bus.sample_values(s["raw"].ravel(), np.repeat(self._lsb[ch], per))
        b["verdict"] = np.repeat(verdict, per)
        self._w.add_block(b)
        grown = np.zeros(f.n, np.int64)
        grown[sel[accepted]] = k[accepted] + 1
        logged = np.maximum.accumulate(np.maximum(grown, self.frames_logged))
        self.frames_logged = int(logged[-1])
        return logged

    def _seq_event(self, f: _Frames, sel: np.ndarray, ch: np.ndarray, k: np.ndarray,
                   accepted: np.ndarray, last: np.ndarray, j: int, verdict: int) -> None:
        """The event of the j-th sample frame of a block, discarded or after a gap."""
        c, seq, t = int(ch[j]), int(k[j]) & 0xFF, int(f.t[sel[j]])
        v = bus.SEQ_VERDICTS[verdict]
        if v != "gap":
            self.event(t, f"seq_{v}", channel=c, detail=f"seq {seq}")
            return
        before = np.flatnonzero(accepted[:j] & (ch[:j] == c))
        prev = int(k[before[-1]]) if before.size else int(last[c])
        lost = int(k[j]) - prev - 1
        self.event(t, "seq_gap", channel=c, count=lost,
                   detail=f"{lost} frame(s) missing before seq {seq}")

    # -- end ---------------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        seq = {self.channel_name(c): self._seq.counts(c) for c in sorted(self._seen)}
        return {"messages": dict(self.counts), "events": dict(self.events), "sequence": seq,
                "last_status": self.last_status,
                "duration_s": ((self.t_last - self.t_first) / 1e9) if self.t_first else 0.0}

    def close(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Write the summary metadata and finish the file (footer, indexes). Idempotent."""
        if not self._closed:
            self._drain()
        s = self.summary()
        if self._closed:
            return s
        self._closed = True
        md = {k: json.dumps(v) for k, v in {**s, **(extra or {})}.items()}
        self._w.add_metadata("dynval.summary", md)
        self._w.finish()
        self._f.close()
        return s

    def __enter__(self) -> McapLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


PENDING_FRAMES = 256  # on_frame's frames per block


@cache
def _template(msg: str, bytes_len: int) -> np.ndarray:
    """A Message record of msg's fixed layout with its constant bytes (header, tags)."""
    t = BlockWriter.template(record_dtype(payload_fields(msg, bytes_len)))
    fill_tags(t, msg, bytes_len)
    return t
STATUS_FIELDS = ("state", "beat", "lost", "dup", "late", "bad_dlc", "unknown")


class _Frames:
    """A block of received frames and their decoding (views, no copies, for part())."""

    def __init__(self, t: np.ndarray, ids: np.ndarray, dlc: np.ndarray, data: np.ndarray,
                 status: np.ndarray, msgs: np.ndarray, kind: np.ndarray) -> None:
        self.t, self.ids, self.dlc, self.data = t, ids, dlc, data
        self.status, self.msgs, self.kind = status, msgs, kind
        self.n = int(t.size)

    def part(self, a: int, b: int) -> _Frames:
        return _Frames(self.t[a:b], self.ids[a:b], self.dlc[a:b], self.data[a:b],
                       self.status[a:b], self.msgs[a:b], self.kind[a:b])


def frame_arrays(t_ns: Any, ids: Any, datas: Any) -> tuple[np.ndarray, np.ndarray,
                                                           np.ndarray, np.ndarray]:
    """on_frames' arrays of received frames: times (ns), ids (EFF_FLAG for extended ones),
    payloads (bytes; the first 8 bytes are kept, the length as dlc)."""
    n = len(datas)
    joined = b"".join(datas)
    if len(joined) == 8 * n:
        data = np.frombuffer(joined, np.uint8).reshape(n, 8)
        dlc = np.full(n, 8, np.uint8)
    else:
        data = np.frombuffer(b"".join(d[:8].ljust(8, b"\0") for d in datas),
                             np.uint8).reshape(n, 8)
        dlc = np.fromiter((min(len(d), 255) for d in datas), np.uint8, n)
    return (np.asarray(t_ns, np.int64), np.asarray(ids, np.uint32), dlc, data)


# ---- the logger beside a bus reader ------------------------------------------------------------
_IS_ERROR, _TIMESTAMP = attrgetter("is_error_frame"), attrgetter("timestamp")
_ID, _EXTENDED, _DATA = attrgetter("arbitration_id"), attrgetter("is_extended_id"), \
    attrgetter("data")


class AsyncLog:
    """McapLog in a writer thread, fed by a bus reader that never waits for the file: the
    reader's put() appends a frame to a block; full blocks (BLOCK_FRAMES, or BLOCK_S old) go
    through a bounded queue (MAX_BLOCKS); a full queue drops the block, counted (dropped),
    logged as a warning and written to the file as a logger_overflow event. An error of the
    writer (a full disk) is raised by the reader's next put() or by close()."""

    BLOCK_FRAMES = 2048
    BLOCK_S = 0.02
    MAX_BLOCKS = 32  # with BLOCK_S: at most ~0.6 s of frames in memory at bus rate

    def __init__(self, out: McapLog) -> None:
        self.out = out
        self.q: queue.Queue[list[Any] | None] = queue.Queue(self.MAX_BLOCKS)
        self.dropped = 0
        self._unreported = 0
        self.error: BaseException | None = None
        self._block: list[Any] = []
        self._since = time.monotonic()
        self._warned = 0.0
        self.thread = threading.Thread(target=self._run, name="dv-log-writer", daemon=True)
        self.thread.start()

    def put(self, m: Any) -> None:
        """A python-can Message received: appended to the block in progress (all the reader
        does per frame; the writer thread reads the messages' fields)."""
        if self.error is not None:
            raise self.error
        b = self._block
        b.append(m)
        n = len(b)
        if n >= self.BLOCK_FRAMES or (n & 63 == 0 and time.monotonic() - self._since >
                                      self.BLOCK_S):
            self.hand_off()

    def hand_off(self) -> None:
        """Queue the block in progress (the reader calls it when idle too)."""
        if self._block:
            try:
                self.q.put_nowait(self._block)
            except queue.Full:
                self.dropped += len(self._block)
                self._unreported += len(self._block)
                if time.monotonic() - self._warned > 1.0:  # at most once a second
                    self._warned = time.monotonic()
                    log.warning("the MCAP writer is behind the bus: %d frames dropped so far",
                                self.dropped)
        self._block = []
        self._since = time.monotonic()

    def _run(self) -> None:
        try:
            while True:
                try:
                    block = self.q.get(timeout=0.05)
                except queue.Empty:
                    self._report()
                    self.out.tick()
                    continue
                if block is None:
                    break
                self._log(block)
                self._report()
        except BaseException as exc:  # noqa: BLE001 - raised in the reader by put()/close()
            self.error = exc

    def _log(self, block: list[Any]) -> None:
        """A block of python-can Messages into the log (each field read in one C-level pass);
        error frames become events."""
        errors = [m for m in block if m.is_error_frame] if any(map(_IS_ERROR, block)) else []
        if errors:
            block = [m for m in block if not m.is_error_frame]
        n = len(block)
        if n:
            t = np.fromiter(map(_TIMESTAMP, block), np.float64, n)
            t[t == 0] = time.time()  # an interface without timestamps: the receive time
            ids = np.fromiter(map(_ID, block), np.uint32, n)
            if any(map(_EXTENDED, block)):  # (one pass without an array: usually none)
                ids[np.fromiter(map(_EXTENDED, block), bool, n)] |= np.uint32(bus.EFF_FLAG)
            self.out.on_frames(*frame_arrays((t * 1e9).astype(np.int64), ids,
                                             list(map(_DATA, block))))
        for m in errors:
            self.out.event(int((m.timestamp or time.time()) * 1e9), "error_frame",
                           can_id=m.arbitration_id)

    def _report(self) -> None:
        if self._unreported:
            n, self._unreported = self._unreported, 0
            self.out.event(time.time_ns(), "logger_overflow", count=n,
                           detail="frames dropped: the writer fell behind the bus")

    def close(self) -> None:
        """Queue the last block, let the writer finish the queue; raise its error if any."""
        self.hand_off()
        while self.thread.is_alive():
            try:
                self.q.put(None, timeout=0.1)
                break
            except queue.Full:
                continue
        self.thread.join()
        if self.error is not None:
            raise self.error
        self._report()

    def close_quietly(self) -> None:
        """Stop the writer after an error elsewhere (its own error is already known)."""
        try:
            self.close()
        except Exception:  # noqa: BLE001 - the first error is the one reported
            log.debug("writer stopped after an error", exc_info=True)


def log_bus(bus_obj: Any, out: McapLog, *, stop: Any = None, idle_timeout_s: float | None = None,
            on_progress: Any = None) -> int:
    """Receive frames from a python-can bus into the log until stop() is true, a
    KeyboardInterrupt, or idle_timeout_s without a frame; the file is written by a writer
    thread (AsyncLog), so the reader never waits for it. Returns frames received."""
    n = 0
    idle_since = time.monotonic()
    w = AsyncLog(out)
    try:
        while stop is None or not stop():
            m = bus_obj.recv(timeout=0.05)
            if m is None:
                w.hand_off()
                if idle_timeout_s is not None and time.monotonic() - idle_since > idle_timeout_s:
                    break
                continue
            idle_since = time.monotonic()
            w.put(m)
            if not m.is_error_frame:
                n += 1
                if on_progress is not None and n % 1024 == 0:
                    on_progress(1024)
    finally:
        w.close()
    if w.dropped:
        log.warning("%s: %d frames dropped (the writer fell behind the bus)", out.path,
                    w.dropped)
    return n
