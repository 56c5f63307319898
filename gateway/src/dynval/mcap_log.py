"""MCAP logging of the dynval bus: every frame raw on /can/raw, decoded samples per channel on
/dv/samples/<channel>, features on /dv/features, residuals on /dv/residuals, DV_STATUS on
/dv/status, control frames on /dv/control, counted anomalies (unknown ids, bad frames,
sequence gaps) on /dv/events and the same with the run control as text on /dv/log
(foxglove.Log); JSON messages with a JSON Schema each, so the mcap CLI and Foxglove read them.
A "dynval" metadata record (test, channel map, rate, units, model, software version, source
hash) is written first, a "dynval.summary" record at the end.

For Foxglove's plot panel (its JSON-schema parser takes "number"/"integer" fields, not type
unions such as ["number", "null"]) every sample is its own message: {"index", "t_s", "value",
"raw", "seq", "verdict", "channel"}, "value" absent for a missing sample. Times come from the
test's own clock: from DV_CTRL START on, a sample's log_time and publish_time are the START
frame's receive time + index / fs, so a replay faster than real time (--asap) keeps the test's
time base; the other messages are logged at the time of the latest sample received (after
STOP: that plus the wall time since), with their receive time as publish_time. Files of the
previous layout (three samples per message in "values") are still read (io.mcapfile).

Written incrementally: chunks of at most chunk_size bytes (or max_chunk_age_s of wall time),
compressed (zstd, else lz4, else none), with CRCs, each flushed to the OS as it is finished,
so a killed logger leaves a file readable up to its last complete chunk
(dynval.io.mcapfile.iter_messages recovers it)."""
from __future__ import annotations

import json
import logging
import time
from collections import Counter
from pathlib import Path
from typing import IO, Any

from mcap.writer import CompressionType, Writer

from dynval import __version__, _core, bus
from dynval.contract import IR_COUNTERS
from dynval.errors import DynvalError
from dynval.topics import (
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

PROFILE = ""  # plain JSON messages

_INT = {"type": "integer"}
_NUM = {"type": "number"}
_STR = {"type": "string"}
SCHEMAS: dict[str, dict[str, Any]] = {
    "dynval.CanFrame": {"id": _INT, "extended": {"type": "boolean"}, "dlc": _INT,
                        "data": {"type": "string", "description": "payload, hex"}},
    "dynval.Sample": {"channel": _INT,
                      "index": {"type": "integer", "description": "sample number since START"},
                      "t_s": {"type": "number", "description": "index / fs: the test's clock"},
                      "value": {"type": "number", "description": "raw * lsb in the channel's "
                                "unit; absent for a missing sample"},
                      "raw": _INT, "seq": _INT,
                      "verdict": {"type": "string", "enum": list(bus.SEQ_VERDICTS)}},
    "dynval.Feature": {"channel": _INT, "name": _STR, "feat_id": _INT, "feature": _STR,
                       "index": _INT, "value": _NUM,
                       "bits": {"type": "integer", "description": "IEEE-754 binary32 bits"}},
    "dynval.Residual": {"channel": _INT, "name": _STR, "flags": _INT, "step": _INT,
                        "value": _NUM, "bits": _INT},
    "dynval.Status": {"state": _INT, "beat": _INT, "lost": _INT, "dup": _INT, "late": _INT,
                      "bad_dlc": _INT, "unknown": _INT},
    "dynval.Control": {"kind": _STR, "cmd": _INT, "record_id": _INT, "channel": _INT,
                       "flags": _INT, "fs_hz": _INT, "lsb": _NUM},
    "dynval.Event": {"event": _STR, "id": _INT, "channel": _INT, "count": _INT,
                     "detail": _STR},
}
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


def compression() -> CompressionType:
    """zstd if zstandard is installed, else lz4, else none."""
    from importlib.util import find_spec

    if find_spec("zstandard") is not None:
        return CompressionType.ZSTD
    if find_spec("lz4") is not None:
        return CompressionType.LZ4
    return CompressionType.NONE


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


def _f32_bits(v: float) -> int:
    import struct

    return int(struct.unpack("<I", struct.pack("<f", v))[0])


def _dumps(d: dict[str, Any]) -> bytes:
    return json.dumps(d, separators=(",", ":"), allow_nan=False).encode()


class McapLog:
    """Decode and log frames to one MCAP file. on_frame() per received frame; close() (or the
    context manager) writes the summary and finishes the file."""

    def __init__(self, path: Path | str, *, meta: dict[str, Any] | None = None,
                 channel_names: list[str] | None = None, chunk_size: int = 512 * 1024,
                 max_chunk_age_s: float = 0.5, compress: CompressionType | None = None,
                 log_raw: bool = True) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._f = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as exc:
            raise LogError(f"{self.path}: cannot write: {exc.strerror or exc}") from exc
        stream: Any = _Flushing(self._f, self.path)
        self._w: Any = Writer(stream, chunk_size=chunk_size,
                         compression=compress if compress is not None else compression())
        self._w.start(profile=PROFILE, library=f"dynval {__version__}")
        self._schema: dict[str, int] = {}
        self._chan: dict[str, int] = {}
        self.names = list(channel_names or [])
        self.lsb: dict[int, float] = {}
        self.seq: dict[int, bus.SeqTracker] = {}
        self._frame_no: dict[int, int] = {}
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
        sid = self._schema.get(schema)
        if sid is None:
            sid = int(self._w.register_schema(schema, "jsonschema",
                                              json.dumps(schema_json(schema)).encode()))
            self._schema[schema] = sid
        cid = int(self._w.register_channel(topic, "json", sid))
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
        if self._stopped is not None:
            return self._stopped[1] + (t_ns - self._stopped[0])
        last = self.sample_ns(max(0, self.frames_logged * bus.SAMPLES_PER_FRAME - 1))
        return t_ns if last is None else last

    def _put(self, topic: str, t_ns: int, d: dict[str, Any], schema: str | None = None,
             seq: int = 0, log_ns: int | None = None) -> None:
        """One message received at t_ns (publish_time), logged at log_ns (default
        clock_ns(t_ns))."""
        cid = self._chan.get(topic)
        if cid is None:
            cid = self._channel(topic, schema or TOPIC_SCHEMA[topic])
        self._w.add_message(cid, log_time=self.clock_ns(t_ns) if log_ns is None else log_ns,
                            data=_dumps(d), publish_time=t_ns, sequence=seq)
        self.counts[topic] += 1

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
        """Log one frame received at t_ns (integer ns, epoch)."""
        if self._closed:
            return
        if self.t_first is None:
            self.t_first = t_ns
        self.t_last = t_ns
        d = bus.decode(can_id, data, extended)
        raw = {"id": can_id, "extended": extended, "dlc": len(data), "data": data.hex()}
        is_samples = isinstance(d, bus.Decoded) and d.kind == "samples"
        if self.log_raw and not is_samples:
            self._put(T_RAW, t_ns, raw)
        if isinstance(d, int):
            self.event(t_ns, refused_event(d), can_id=can_id,
                       detail=f"{_core.status_name(d)}, dlc {len(data)}")
        elif d.kind == "samples":
            self._samples(t_ns, d.fields)
            if self.log_raw:  # after the samples: at the test time of its last sample
                self._put(T_RAW, t_ns, raw)
        elif d.kind == "feature":
            f = d.fields
            self._put(T_FEATURES, t_ns, {**f, "name": self.channel_name(f["channel"]),
                                         "feature": bus.FEATURE_NAMES.get(f["feat_id"], "?"),
                                         "bits": _f32_bits(f["value"])})
        elif d.kind == "resid":
            f = d.fields
            self._put(T_RESID, t_ns, {**f, "name": self.channel_name(f["channel"]),
                                      "bits": _f32_bits(f["value"])})
        elif d.kind == "status":
            self.last_status = d.fields
            self._put(T_STATUS, t_ns, d.fields)
        else:
            f = d.fields
            if d.kind == "chcfg":
                self.lsb[f["channel"]] = f["lsb"]
                self.fs_hz = int(f["fs_hz"])
            elif f["cmd"] == bus.CTRL_START:
                self.seq.clear()
                self.frames_logged = self._frames_flushed = 0
                self._frame_no.clear()
                self.t0_ns, self._stopped = t_ns, None
            elif f["cmd"] == bus.CTRL_STOP and self.t0_ns is not None:
                self._stopped = (t_ns, self.clock_ns(t_ns))
            self._put(T_CONTROL, t_ns, {"kind": d.kind, **f})
            if d.kind == "ctrl" and f["cmd"] in (bus.CTRL_START, bus.CTRL_STOP):
                what = "START" if f["cmd"] == bus.CTRL_START else "STOP"
                self.text(t_ns, "INFO", f"{what} record {f['record_id']}: "
                          f"{len(self.lsb)} channel(s) at {self.fs_hz} Hz")
        self.tick()

    @property
    def logged_s(self) -> float:
        """Data time (s since START) of the sample frames logged so far."""
        return self.frames_logged * bus.SAMPLES_PER_FRAME / self.fs_hz if self.fs_hz else 0.0

    def tick(self) -> None:
        """Finish the chunk in progress when it is older than max_chunk_age_s of wall time or
        holds more than that of data time (a replay faster than real time): bounds what a
        crash can lose at any speed. on_frame calls it; a receive loop calls it on every
        timeout too, so a burst followed by silence reaches the disk as well."""
        if self._closed:
            return
        now = time.monotonic_ns()
        new_frames = self.frames_logged - self._frames_flushed
        data_ns = new_frames * bus.SAMPLES_PER_FRAME * 1e9 / self.fs_hz if self.fs_hz else 0
        if now - self._last_flush > self.max_age_ns or data_ns > self.max_age_ns:
            self._w.flush()
            self._last_flush = now
            self._frames_flushed = self.frames_logged

    def _samples(self, t_ns: int, f: dict[str, Any]) -> None:
        ch = int(f["channel"])
        tr = self.seq.get(ch)
        if tr is None:
            tr = self.seq[ch] = bus.SeqTracker()
        before = tr.counts()
        verdict = tr.update(f["seq"])
        if verdict == "gap":
            lost = tr.counts()["lost"] - before["lost"]
            self.event(t_ns, "seq_gap", channel=ch, count=lost,
                       detail=f"{lost} frame(s) missing before seq {f['seq']}")
        elif verdict != "ok":
            self.event(t_ns, f"seq_{verdict}", channel=ch, detail=f"seq {f['seq']}")
        # unwrapped frame number since START (first frame 0)
        prev = self._frame_no.get(ch)
        if prev is None:
            k = 0
        elif verdict in ("ok", "gap"):
            k = prev + ((f["seq"] - (prev & 0xFF)) & 0xFF)
        else:
            k = prev - ((prev - f["seq"]) & 0xFF)
        if verdict in ("ok", "gap") or prev is None:
            self._frame_no[ch] = k
            self.frames_logged = max(self.frames_logged, k + 1)
        lsb = self.lsb.get(ch, bus.DEFAULT_LSB)
        topic = T_SAMPLES + self.channel_name(ch)
        for j, raw in enumerate(f["raw"]):
            i = k * bus.SAMPLES_PER_FRAME + j
            ts = self.sample_ns(i)
            d: dict[str, Any] = {"channel": ch, "index": i}
            if ts is not None:
                d["t_s"] = i / self.fs_hz
            v = bus.sample_value(raw, lsb)
            if v == v:  # NaN: a missing sample has no value (JSON has no NaN)
                d["value"] = v
            d.update(raw=raw, seq=f["seq"], verdict=verdict)
            # log and publish time on the test's clock: sample i was taken at t0 + i / fs
            self._put(topic, t_ns if ts is None else ts, d, schema="dynval.Sample", seq=i,
                      log_ns=t_ns if ts is None else ts)

    # -- end ---------------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        seq = {self.channel_name(c): t.counts() for c, t in sorted(self.seq.items())}
        return {"messages": dict(self.counts), "events": dict(self.events), "sequence": seq,
                "last_status": self.last_status,
                "duration_s": ((self.t_last - self.t_first) / 1e9) if self.t_first else 0.0}

    def close(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Write the summary metadata and finish the file (footer, indexes). Idempotent."""
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


def log_bus(bus_obj: Any, out: McapLog, *, stop: Any = None, idle_timeout_s: float | None = None,
            on_progress: Any = None) -> int:
    """Receive frames from a python-can bus into the log until stop() is true, a
    KeyboardInterrupt, or idle_timeout_s without a frame. Returns frames logged."""
    n = 0
    idle_since = time.monotonic()
    while stop is None or not stop():
        m = bus_obj.recv(timeout=0.05)
        if m is None:
            out.tick()
            if idle_timeout_s is not None and time.monotonic() - idle_since > idle_timeout_s:
                break
            continue
        idle_since = time.monotonic()
        t_ns = int(m.timestamp * 1e9) if m.timestamp else time.time_ns()
        if m.is_error_frame:
            out.event(t_ns, "error_frame", can_id=m.arbitration_id)
            continue
        out.on_frame(t_ns, m.arbitration_id, bytes(m.data), m.is_extended_id)
        n += 1
        if on_progress is not None and n % 1024 == 0:
            on_progress(1024)
    return n
