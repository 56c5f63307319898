"""The CAN side of the gateway: the dynval protocol through the C codec (dv_codec, via the
binding: nothing is encoded or decoded by a second implementation), its constants from the C
header and the DBC (dynval.contract), sequence tracking (dv_seq_t), the frame plan of a recorded
test and a drift-free replay scheduler.

Frame plan of one test (one record): DV_CTRL CLEAR, one DV_CHCFG per channel (rate and lsb),
DV_CTRL START (record_id), the DV_SAMPLES frames (channels interleaved, 3 samples per frame,
sent at the time of the frame's last sample), DV_CTRL STOP.
"""
from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import Any

import numpy as np

from dynval import _core
from dynval.contract import DBC_VALUES, MACROS, const, named
from dynval.errors import ConfigError, DynvalError
from dynval.io.recording import Recording
from dynval.pacing import RT_MARGIN_NS, SLEEP_MARGIN_NS, tight_timing, wait_until

log = logging.getLogger(__name__)

SAMPLES_PER_FRAME = const("DV_CODEC_SAMPLES_PER_FRAME")
RAW_MISSING = const("DV_CODEC_RAW_MISSING")
DEFAULT_LSB = float(MACROS["DV_CODEC_DEFAULT_LSB"])  # until DV_CHCFG arrives
CTRL_START, CTRL_STOP = const("DV_CTRL_START"), const("DV_CTRL_STOP")
CTRL_CLEAR, CTRL_STATUS = const("DV_CTRL_CLEAR"), const("DV_CTRL_STATUS")
MAX_CHAN = const("SIM_MAX_CHAN")  # channels a node serves

#: the protocol's identifiers (DV_CAN_ID_* of dv_codec.h)
IDS = named("DV_CAN_ID_")
ID_STATUS, ID_CTRL, ID_CHCFG = IDS["status"], IDS["ctrl"], IDS["chcfg"]
ID_SAMPLES, ID_FEATURE, ID_RESID = IDS["samples"], IDS["feature"], IDS["resid"]
EFF_FLAG = const("DV_CAN_EFF_FLAG")
#: DV_FEATURE.feat_id -> name, the DBC's value table
FEATURE_NAMES = DBC_VALUES[(ID_FEATURE, "feat_id")]

#: dv_seq_update's verdicts by value (dv_seq_verdict_t: DV_SEQ_OK -> "ok", ...)
SEQ_VERDICTS = tuple(str(n).removeprefix("DV_SEQ_").lower() for _, n in
                     sorted(_core.ffi.typeof("dv_seq_verdict_t").elements.items()))


class BusError(DynvalError):
    """The CAN bus cannot be opened or refuses frames."""


# ---- the codec (C) ---------------------------------------------------------------------------
@cache
def _buf(ctype: str, user: str = "encode") -> Any:
    """A scratch instance of a C type for each user: the replay encodes while the logger's
    thread decodes, each in one thread."""
    return _core.ffi.new(ctype)


def _encode(kind: str) -> tuple[int, bytes]:
    """Encode the message _buf("dv_msg_t *") holds, as kind (the DV_MSG_<KIND> member)."""
    msg, frame = _buf("dv_msg_t *"), _buf("dv_can_frame_t *")
    msg.kind = getattr(_core.lib, f"DV_MSG_{kind.upper()}")
    st = _core.lib.dv_codec_encode(msg, frame)
    if st != 0:
        raise ConfigError(f"dv_codec_encode refused a message (status {st})")
    return int(frame.id), bytes(_core.ffi.buffer(frame.data, 8))


def encode_ctrl(cmd: int, record_id: int = 0) -> tuple[int, bytes]:
    """(id, 8 bytes) of a DV_CTRL frame."""
    c = _buf("dv_msg_t *").u.ctrl
    c.cmd = cmd
    c.record_id = record_id & 0xFFFFFFFF
    return _encode("ctrl")


def encode_chcfg(channel: int, fs_hz: int, lsb: float, flags: int = 1) -> tuple[int, bytes]:
    """(id, 8 bytes) of a DV_CHCFG frame."""
    c = _buf("dv_msg_t *").u.chcfg
    c.channel = channel
    c.flags = flags
    c.fs_hz = fs_hz
    c.lsb = lsb
    return _encode("chcfg")


def encode_samples(channel: int, seq: int, raw: Sequence[int] | np.ndarray) -> tuple[int, bytes]:
    """(id, 8 bytes) of a DV_SAMPLES frame with three raw counts."""
    s = _buf("dv_msg_t *").u.samples
    s.channel = channel
    s.seq = seq & 0xFF
    s.raw[0], s.raw[1], s.raw[2] = int(raw[0]), int(raw[1]), int(raw[2])
    return _encode("samples")


@dataclass
class Decoded:
    """A decoded frame: kind is the message (status, ctrl, chcfg, samples, feature, resid),
    fields its members."""

    kind: str
    fields: dict[str, Any]


def decode(can_id: int, data: bytes, extended: bool = False) -> Decoded | int:
    """Decode a frame with the C codec. Returns Decoded, or the codec's negative status
    (unknown id / bad DLC / bad config value) for a frame it refuses."""
    lib = _core.lib
    frame, msg = _buf("dv_can_frame_t *", "decode"), _buf("dv_msg_t *", "decode")
    frame.id = (can_id | EFF_FLAG) if extended else can_id
    n = len(data)
    frame.dlc = n if n <= 8 else 9
    _core.ffi.memmove(frame.data, data[:8], min(n, 8))
    st = int(lib.dv_codec_decode(frame, msg))
    if st != 0:
        return st
    k = int(msg.kind)
    u = msg.u
    if k == lib.DV_MSG_SAMPLES:
        s = u.samples
        return Decoded("samples", {"channel": s.channel, "seq": s.seq,
                                   "raw": [s.raw[0], s.raw[1], s.raw[2]]})
    if k == lib.DV_MSG_FEATURE:
        f = u.feature
        return Decoded("feature", {"feat_id": f.feat_id, "channel": f.channel,
                                   "index": f.index, "value": float(f.value)})
    if k == lib.DV_MSG_RESID:
        r = u.resid
        return Decoded("resid", {"channel": r.channel, "flags": r.flags, "step": r.step,
                                 "value": float(r.value)})
    if k == lib.DV_MSG_STATUS:
        s = u.status
        return Decoded("status", {"state": s.state, "beat": s.beat, "lost": s.lost,
                                  "dup": s.dup, "late": s.late, "bad_dlc": s.bad_dlc,
                                  "unknown": s.unknown})
    if k == lib.DV_MSG_CTRL:
        return Decoded("ctrl", {"cmd": u.ctrl.cmd, "record_id": u.ctrl.record_id})
    c = u.chcfg
    return Decoded("chcfg", {"channel": c.channel, "flags": c.flags, "fs_hz": c.fs_hz,
                             "lsb": float(c.lsb)})


_NP = {"uint8_t": "u1", "int16_t": "<i2", "uint16_t": "<u2", "uint32_t": "<u4",
       "float": "<f4"}


@cache
def frame_dtype() -> np.dtype:
    """numpy's view of dv_can_frame_t (offsets from the C declaration)."""
    names, formats, offsets = _struct_fields("dv_can_frame_t", 0)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": _core.ffi.sizeof("dv_can_frame_t")})


@cache
def msg_dtype(member: str) -> np.dtype:
    """numpy's view of a dv_msg_t whose union holds `member` (samples, feature, resid, status,
    ctrl, chcfg): "kind" and that member's fields, at the C offsets."""
    ffi = _core.ffi
    names, formats, offsets = _struct_fields(f"dv_msg_{member}_t", ffi.offsetof("dv_msg_t", "u"))
    return np.dtype({"names": ["kind", *names], "formats": ["<i4", *formats],
                     "offsets": [ffi.offsetof("dv_msg_t", "kind"), *offsets],
                     "itemsize": ffi.sizeof("dv_msg_t")})


def _struct_fields(ctype: str, base: int) -> tuple[list[str], list[Any], list[int]]:
    names: list[str] = []
    formats: list[Any] = []
    offsets: list[int] = []
    for name, f in _core.ffi.typeof(ctype).fields:
        t = f.type
        formats.append((_NP[t.item.cname], (t.length,)) if t.kind == "array" else _NP[t.cname])
        names.append(name)
        offsets.append(base + f.offset)
    return names, formats, offsets


def decode_block(ids: np.ndarray, dlc: np.ndarray, data: np.ndarray) -> tuple[np.ndarray,
                                                                                np.ndarray]:
    """dv_codec_decode_n over n frames (ids with EFF_FLAG for extended ones, dlc, data n x 8
    bytes): (status, messages as raw dv_msg_t records; view them with msg_dtype)."""
    n = ids.size
    frames = np.zeros(n, frame_dtype())
    frames["id"], frames["dlc"], frames["data"] = ids, dlc, data
    msgs = np.zeros(n, np.dtype((np.void, _core.ffi.sizeof("dv_msg_t"))))
    status = np.empty(n, np.int32)
    ffi = _core.ffi
    _core.lib.dv_codec_decode_n(ffi.from_buffer("dv_can_frame_t[]", frames), n,
                                ffi.from_buffer("dv_msg_t[]", msgs, require_writable=True),
                                ffi.from_buffer("dv_status_t[]", status,
                                                require_writable=True))
    return status, msgs


def sample_values(raw: np.ndarray, lsb: np.ndarray) -> np.ndarray:
    """dv_codec_sample_values: raw * lsb of int16 counts, each with its lsb; NaN for missing."""
    r = np.ascontiguousarray(raw, dtype=np.int16)
    q = np.ascontiguousarray(lsb, dtype=np.float32)
    out = np.empty(r.size, np.float64)
    ffi = _core.ffi
    _core.lib.dv_codec_sample_values(ffi.from_buffer("int16_t[]", r),
                                     ffi.from_buffer("float[]", q), r.size,
                                     ffi.from_buffer("double[]", out, require_writable=True))
    return out


def sample_value(raw: int, lsb: float) -> float:
    """raw * lsb in channel units, NaN for a missing sample (dv_codec_sample_value)."""
    return float(_core.lib.dv_codec_sample_value(raw, lsb))


def quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    """int16 counts of x by dv_codec_sample_raw (rounded, clamped, NaN -> missing)."""
    f = _core.lib.dv_codec_sample_raw
    return np.fromiter((f(v, lsb) for v in x.tolist()), dtype=np.int16, count=x.size)


def dequantise(raw: np.ndarray, lsb: float) -> np.ndarray:
    """Channel values of raw counts, exactly as the firmware converts them."""
    f = _core.lib.dv_codec_sample_value
    return np.fromiter((f(int(v), lsb) for v in raw.tolist()), dtype=np.float64,
                       count=raw.size)


# DV_CHCFG carries the lsb as an IEEE-754 binary32 and the firmware computes raw * lsb in it:
# a power of two from the smallest normal binary32 (smaller ones lose bits) up to 2^112, so
# that |raw| < 2^15 times it stays below 2^127, finite (beyond, the channel arrives as Inf)
LSB_MIN, LSB_MAX = 2.0 ** -126, 2.0 ** 112


def lsb_for(x: np.ndarray, headroom: float = 30000.0) -> float:
    """Power-of-two lsb (exact in binary32) putting the channel's peak near 30000 counts; may
    lie outside [LSB_MIN, LSB_MAX] for a channel the bus cannot carry (make_plan says so)."""
    finite = x[np.isfinite(x)]
    peak = float(np.max(np.abs(finite))) if finite.size else 0.0
    if peak == 0.0:
        return DEFAULT_LSB
    return float(2.0 ** max(-1074, math.ceil(math.log2(peak) - math.log2(headroom))))


def check_lsb(rec: Recording, channel: str, lsb: float) -> None:
    """ConfigError unless lsb is one DV_CHCFG carries as it is (binary32, normal, finite)."""
    if not LSB_MIN <= lsb <= LSB_MAX:
        peak = float(np.nanmax(np.abs(rec.channel(channel).data), initial=0.0))
        raise ConfigError(f"{rec.source or rec.name}: channel {channel} peaks at {peak:.3g}: "
                          f"its lsb {lsb:.3g} is outside the binary32 range DV_CHCFG carries "
                          f"({LSB_MIN:.3g} .. {LSB_MAX:.3g}); rescale it (channel map "
                          "'scale')")


class SeqTracker:
    """dv_seq_t of one channel (the firmware's own sequence rules)."""

    def __init__(self) -> None:
        self._s = _core.ffi.new("dv_seq_t *")
        _core.lib.dv_seq_init(self._s)
        self._c = _core.ffi.new("dv_seq_counts_t *")

    def update(self, seq: int) -> str:
        return SEQ_VERDICTS[int(_core.lib.dv_seq_update(self._s, seq & 0xFF))]

    def counts(self) -> dict[str, int]:
        _core.lib.dv_seq_get(self._s, self._c)
        c = self._c
        return {"ok": c.ok, "lost": c.lost, "dup": c.dup, "late": c.late, "stale": c.stale}


class SeqBank:
    """dv_seq_t of every channel number a frame can carry, and the number of each channel's
    last accepted frame: sequence tracking of blocks of frames (dv_seq_track_n)."""

    N = 256  # DV_SAMPLES.channel is a byte

    def __init__(self) -> None:
        self._s = _core.ffi.new("dv_seq_t[]", self.N)
        self._c = _core.ffi.new("dv_seq_counts_t *")
        self.last = np.empty(self.N, np.int64)
        self.reset()

    def reset(self) -> None:
        for i in range(self.N):
            _core.lib.dv_seq_init(self._s + i)
        self.last[:] = -1

    def track(self, chan: np.ndarray, seq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(verdicts, frame numbers since START) of frames of channels chan with counters
        seq, in the order received."""
        c = np.ascontiguousarray(chan, dtype=np.uint8)
        s = np.ascontiguousarray(seq, dtype=np.uint8)
        verdict = np.empty(c.size, np.uint8)
        k = np.empty(c.size, np.int64)
        ffi = _core.ffi
        _core.lib.dv_seq_track_n(self._s, ffi.from_buffer("int64_t[]", self.last,
                                                          require_writable=True),
                                 ffi.from_buffer("uint8_t[]", c), ffi.from_buffer("uint8_t[]", s),
                                 c.size, ffi.from_buffer("uint8_t[]", verdict,
                                                         require_writable=True),
                                 ffi.from_buffer("int64_t[]", k, require_writable=True))
        return verdict, k

    def counts(self, ch: int) -> dict[str, int]:
        _core.lib.dv_seq_get(self._s + ch, self._c)
        c = self._c
        return {"ok": c.ok, "lost": c.lost, "dup": c.dup, "late": c.late, "stale": c.stale}


# ---- the frame plan of a recorded test --------------------------------------------------------
@dataclass
class Plan:
    """What replay sends for one recording: setup frames, timed sample frames, stop frames.
    raw[c] holds channel c's counts (padded with RAW_MISSING to whole frames)."""

    rec: Recording
    lsb: list[float]
    raw: list[np.ndarray]
    fs_hz: int
    record_id: int = 1
    padded: int = 0
    setup: list[tuple[int, bytes]] = field(default_factory=list)
    stop: list[tuple[int, bytes]] = field(default_factory=list)

    @property
    def n_frames_per_channel(self) -> int:
        return int(self.raw[0].size // SAMPLES_PER_FRAME) if self.raw else 0

    @property
    def n_sample_frames(self) -> int:
        return self.n_frames_per_channel * len(self.raw)

    @property
    def n_frames(self) -> int:
        return len(self.setup) + self.n_sample_frames + len(self.stop)

    def values(self, c: int) -> np.ndarray:
        """The values the firmware sees on channel c (NaN for padding), before padding."""
        return dequantise(self.raw[c][: self.rec.n_samples], self.lsb[c])

    def batches(self) -> Iterator[tuple[int, list[tuple[int, bytes]]]]:
        """(offset_ns from the first sample, frames) in send order; every sample frame is due
        at the time of its last sample; setup at 0, stop one frame period after the last."""
        yield 0, list(self.setup)
        nch = len(self.raw)
        per = SAMPLES_PER_FRAME
        t_last = 0
        for k in range(self.n_frames_per_channel):
            due = round((k * per + per - 1) * 1e9 / self.fs_hz)
            frames = [encode_samples(c, k, self.raw[c][k * per:(k + 1) * per])
                      for c in range(nch)]
            t_last = due
            yield due, frames
        yield t_last + round(per * 1e9 / self.fs_hz), list(self.stop)


def make_plan(rec: Recording, record_id: int = 1, lsb: Sequence[float] | None = None) -> Plan:
    """Quantise a recording for the bus: per channel a power-of-two lsb (or the given ones),
    counts by the C codec, missing samples for NaN and for the padding of the last frame."""
    if not rec.channels:
        raise ConfigError(f"{rec.name}: no channels to send")
    if len(rec.channels) > MAX_CHAN:
        raise ConfigError(f"{rec.name}: {len(rec.channels)} channels; the protocol's node "
                          f"serves at most {MAX_CHAN} (use a channel map to choose)")
    fs = int(round(rec.fs_hz))
    if not 1 <= fs <= 65535 or abs(fs - rec.fs_hz) > 1e-6 * rec.fs_hz:
        raise ConfigError(f"{rec.name}: sample rate {rec.fs_hz:g} Hz is not an integer "
                          "1..65535 Hz (DV_CHCFG.fs_hz)")
    lsbs = list(lsb) if lsb is not None else [lsb_for(c.data) for c in rec.channels]
    for c, step in zip(rec.channels, lsbs, strict=True):
        check_lsb(rec, c.name, step)
    n = rec.n_samples
    pad = (-n) % SAMPLES_PER_FRAME
    raw = []
    for c, step in zip(rec.channels, lsbs, strict=True):
        q = quantise(np.asarray(c.data, dtype=np.float64), step)
        if pad:
            q = np.concatenate([q, np.full(pad, RAW_MISSING, dtype=np.int16)])
        raw.append(q)
    if pad:
        log.info("%s: last frame padded with %d missing sample(s) per channel", rec.name, pad)
    setup = [(ID_CTRL, encode_ctrl(CTRL_CLEAR)[1])]
    setup += [encode_chcfg(c, fs, lsbs[c]) for c in range(len(raw))]
    setup.append(encode_ctrl(CTRL_START, record_id))
    stop = [encode_ctrl(CTRL_STOP, record_id)]
    return Plan(rec, lsbs, raw, fs, record_id, pad, setup, stop)


# ---- timing ------------------------------------------------------------------------------------
class TimingStats:
    """Streaming statistics of send-time errors (bounded memory): count, mean, max, a 1-us
    histogram for the 95th percentile, and a least-squares drift slope of error vs time."""

    BINS = 200_000  # 1 us bins up to 200 ms; beyond goes to the last bin

    def __init__(self) -> None:
        self.n = 0
        self.sum = 0.0
        self.max = -math.inf
        self.min = math.inf
        self.hist = np.zeros(self.BINS, dtype=np.int64)
        self._sx = self._sy = self._sxx = self._sxy = 0.0
        self.first_err: float | None = None
        self.t_span_s = 0.0

    def add_batch(self, t_s: float, errs_ns: Sequence[int]) -> None:
        for e in errs_ns:
            ev = float(e)
            self.n += 1
            self.sum += ev
            self.max = max(self.max, ev)
            self.min = min(self.min, ev)
            self.hist[min(self.BINS - 1, max(0, int(ev // 1000)))] += 1
            self._sx += t_s
            self._sy += ev
            self._sxx += t_s * t_s
            self._sxy += t_s * ev
        self.t_span_s = max(self.t_span_s, t_s)

    def percentile_ns(self, q: float) -> float:
        if self.n == 0:
            return math.nan
        c = np.cumsum(self.hist)
        i = int(np.searchsorted(c, q / 100.0 * self.n))
        return (i + 1) * 1000.0

    def drift_ns_per_s(self) -> float:
        """Slope of the error over the run (0 = no accumulation)."""
        d = self.n * self._sxx - self._sx * self._sx
        if self.n < 2 or d <= 0:
            return 0.0
        return (self.n * self._sxy - self._sx * self._sy) / d

    def report(self) -> dict[str, float]:
        mean = self.sum / self.n if self.n else math.nan
        slope = self.drift_ns_per_s()
        return {"frames": float(self.n), "mean_us": mean / 1e3,
                "p95_us": self.percentile_ns(95.0) / 1e3,
                "max_us": (self.max if self.n else math.nan) / 1e3,
                "drift_us_per_s": slope / 1e3,
                "drift_us_over_run": slope * self.t_span_s / 1e3,
                "duration_s": self.t_span_s}


@dataclass
class ReplayResult:
    frames_sent: int
    sample_frames: int
    wall_s: float
    timing: dict[str, float]
    send_errors: int = 0

    @property
    def frames_per_s(self) -> float:
        return self.frames_sent / self.wall_s if self.wall_s > 0 else math.inf


def replay(bus: Any, plan: Plan, *, speed: float = 1.0, asap: bool = False,
           on_progress: Callable[[int], None] | None = None,
           send: Callable[[int, bytes], None] | None = None,
           hold: Callable[[int], None] | None = None, realtime: bool = False) -> ReplayResult:
    """Send a plan on a python-can bus. Paced: every batch is due at start + offset / speed
    (absolute deadlines: an early or late batch does not shift the later ones), and the
    send-time error (send return minus deadline) of every frame is recorded. asap: no pacing.
    on_progress(n) is called with the number of sample frames sent since the last call;
    hold(offset_ns), before each batch, may wait (a logger that must not fall behind).
    Pacing: dynval.pacing (wait_until; tight_timing, at SCHED_FIFO with realtime)."""
    with tight_timing(realtime and not asap):
        margin = RT_MARGIN_NS if realtime else SLEEP_MARGIN_NS
        return _replay(bus, plan, speed, asap, on_progress, send, hold, margin)


def _replay(bus: Any, plan: Plan, speed: float, asap: bool,
            on_progress: Callable[[int], None] | None,
            send: Callable[[int, bytes], None] | None,
            hold: Callable[[int], None] | None, margin_ns: int) -> ReplayResult:
    import can

    if not asap and not speed > 0:
        raise ConfigError(f"--speed must be > 0, got {speed}")

    def _send(can_id: int, data: bytes) -> None:
        bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

    tx = send or _send
    stats = TimingStats()
    sent = errors = 0
    sample_frames = 0
    t0 = time.perf_counter_ns() + (0 if asap else 2_000_000)  # 2 ms to settle
    last_prog = 0
    for off, frames in plan.batches():
        if hold is not None:
            hold(off)
        due = t0 + int(off / speed) if not asap else 0
        if not asap:
            wait_until(due, margin_ns)
        errs = []
        for can_id, data in frames:
            try:
                tx(can_id, data)
            except can.CanError as exc:
                errors += 1
                log.warning("send of 0x%03X failed: %s", can_id, exc)
                continue
            sent += 1
            if not asap:
                errs.append(time.perf_counter_ns() - due)
            if can_id == ID_SAMPLES:
                sample_frames += 1
        if errs:
            stats.add_batch(off / speed / 1e9, errs)
        if on_progress is not None and sample_frames - last_prog >= 512:
            on_progress(sample_frames - last_prog)
            last_prog = sample_frames
    wall = (time.perf_counter_ns() - t0) / 1e9
    if on_progress is not None and sample_frames > last_prog:
        on_progress(sample_frames - last_prog)
    rep = stats.report() if not asap else {"frames": float(sent)}
    return ReplayResult(sent, sample_frames, wall, rep, errors)


#: what a person without a CAN interface is told to use instead
NO_BUS_HINT = ("use --interface virtual (python-can's in-process bus, no hardware), a "
               "configured interface (--interface/--channel, CAN_INTERFACE, ~/.canrc), or "
               "`dynval run`, which replays through the firmware loop without any CAN "
               "interface")
DEFAULT_CONFIG = {"interface": "socketcan", "channel": "vcan0"}  # when nothing is configured


def bus_config(interface: str | None = None, channel: str | int | None = None,
               bitrate: int | None = None, options: dict[str, Any] | None = None,
               context: str | None = None) -> dict[str, Any]:
    """The python-can configuration of a bus, can.Bus(**config) semantics: the given values
    first, then python-can's own sources (can.rc, CAN_INTERFACE / CAN_CHANNEL / CAN_BITRATE /
    CAN_CONFIG, ~/.canrc, can.ini; context selects a section), then DEFAULT_CONFIG.
    ConfigError for an interface python-can does not know."""
    import can

    given = {k: v for k, v in (("interface", interface), ("channel", channel),
                               ("bitrate", bitrate)) if v is not None}
    given.update(options or {})
    try:
        try:
            cfg = dict(can.util.load_config(config=given, context=context))
        except can.CanInterfaceNotImplementedError as exc:
            if "interface" in given or '"None"' not in str(exc):
                raise  # an interface python-can does not know, from any source
            # no source names an interface (python-can: 'Unknown interface type "None"'): the
            # default interface, with the sources' other values
            cfg = dict(can.util.load_config(
                config={**given, "interface": DEFAULT_CONFIG["interface"]}, context=context))
            if cfg["interface"] == DEFAULT_CONFIG["interface"] and cfg.get("channel") is None:
                cfg["channel"] = DEFAULT_CONFIG["channel"]
    except can.CanInterfaceNotImplementedError as exc:
        raise ConfigError(f"{exc} (python-can interfaces: "
                          f"{', '.join(sorted(can.VALID_INTERFACES))})") from None
    return {k: v for k, v in cfg.items() if v is not None}


def describe(config: dict[str, Any]) -> str:
    """interface:channel of a bus configuration, for messages."""
    return f"{config.get('interface')}:{config.get('channel', '')}"


def open_bus(interface: str | dict[str, Any], channel: str | int | None = None,
             **kw: Any) -> Any:
    """A python-can bus of a configuration (bus_config(), or an interface name with channel
    and keyword arguments: can.Bus semantics), or BusError saying why it cannot be opened (a
    kernel without CAN, a missing driver) and what to use instead."""
    import can

    cfg = dict(interface) if isinstance(interface, dict) else {"interface": interface,
                                                                "channel": channel}
    cfg.update(kw)
    try:
        b = can.Bus(**cfg)
    except (OSError, can.CanError, ValueError, ImportError, NotImplementedError) as exc:
        raise BusError(f"cannot open the {describe(cfg)} bus: {exc}; {NO_BUS_HINT}") from exc
    if cfg.get("interface") == "socketcan":
        _enlarge_rx_buffer(b)
    return b


def _enlarge_rx_buffer(b: Any, size: int = 8 << 20) -> None:
    """A Python reader is paused by the GIL and the scheduler for milliseconds at a time; the
    kernel's default socket buffer (~200 kB, ~1500 CAN frames) then overflows on bursts. Ask for
    more (SO_RCVBUFFORCE as root, else SO_RCVBUF up to net.core.rmem_max)."""
    import socket

    sock = getattr(b, "socket", None)
    if sock is None:
        return
    force = getattr(socket, "SO_RCVBUFFORCE", 33)
    for opt in (force, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, opt, size)
            break
        except OSError:
            continue
    log.debug("socketcan receive buffer: %d bytes",
              sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))
