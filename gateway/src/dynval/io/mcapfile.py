"""Reading MCAP files written by dynval, including files a killed logger left behind.

iter_messages() reads records sequentially with mcap's non-seeking StreamReader. A file
without its footer (the logger was killed) is read up to the last complete record: the
records are first walked by their length prefixes, and the reader only sees the complete ones;
a chunk whose CRC does not match ends the read. read_mcap() turns the /dv/samples/<channel>
topics back into a Recording (the values the firmware saw), of either layout: one sample per
message ("index", "value", absent when missing: mcap_log's) or three per message ("index",
"values" with null for missing: logs written before it)."""
from __future__ import annotations

import importlib
import io
import logging
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import InputFileError
from dynval.io.arrays import checked_unit, one_line
from dynval.io.jsonfile import parse_json
from dynval.io.recording import MAX_RATE_HZ, MIN_RATE_HZ, Channel, Recording, file_sha256
from dynval.topics import CHANNEL_NAMES_KEY, T_CONTROL, T_SAMPLES

log = logging.getLogger(__name__)

MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER = 0x02
OP_CHUNK = 0x06
SAMPLES_PER_MESSAGE = 3  # at most, in the old layout: a DV_SAMPLES frame's 3 samples
MAX_SAMPLES = 1 << 40  # beyond any test: a larger index or count is a damaged file
GAP_LIMIT = 64  # without n_samples, indices may spread this many samples per message at most


@dataclass
class Scan:
    """What a sequential read found: complete=False means no footer (a killed writer)."""

    complete: bool = False
    size: int = 0
    good_bytes: int = 0
    records: int = 0
    chunks: int = 0
    truncated_bytes: int = 0
    error: str = ""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)


def scan(path: Path | str) -> Scan:
    """Walk the records by their length prefixes (no decoding)."""
    p = Path(path)
    s = Scan()
    try:
        f = open(p, "rb")  # noqa: SIM115
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    with f:
        s.size = f.seek(0, io.SEEK_END)
        f.seek(0)
        if f.read(8) != MAGIC:
            raise InputFileError(p, "not an MCAP file (bad magic)", None, "byte 0")
        off = 8
        while True:
            head = f.read(9)
            if len(head) < 9:
                break
            op, length = struct.unpack("<BQ", head)
            if off + 9 + length > s.size:
                break
            f.seek(length, io.SEEK_CUR)
            off += 9 + length
            s.records += 1
            s.chunks += op == OP_CHUNK
            if op == OP_FOOTER:
                s.complete = f.read(8) == MAGIC
                if s.complete:
                    off += 8
                break
        s.good_bytes = off
        s.truncated_bytes = s.size - off
    return s


class _Limited(io.RawIOBase):
    def __init__(self, f: Any, limit: int) -> None:
        self.f = f
        self.left = limit

    def readable(self) -> bool:
        return True

    def readinto(self, b: Any) -> int:
        n = min(len(b), self.left)
        if n <= 0:
            return 0
        data = self.f.read(n)
        b[: len(data)] = data
        self.left -= len(data)
        return len(data)


@dataclass
class Message:
    topic: str
    log_time: int
    data: dict[str, Any]
    sequence: int = 0
    publish_time: int = 0


def _decode_errors() -> tuple[type[BaseException], ...]:
    """What the mcap library and its decompressors raise on damaged bytes."""
    from mcap.exceptions import McapError

    errs: list[type[BaseException]] = [McapError, struct.error, ValueError, EOFError,
                                       RuntimeError, KeyError, IndexError, OverflowError]
    try:
        errs.append(importlib.import_module("zstandard").ZstdError)
    except ImportError:  # the package reads zstd chunks only when zstandard is there
        pass
    return tuple(errs)


def _payload(p: Path, raw: bytes, topic: str, k: int) -> dict[str, Any]:
    """A message's JSON payload: an object, else InputFileError naming the record."""
    try:
        d = parse_json(p, raw.decode("utf-8"))
    except (UnicodeDecodeError, InputFileError):
        d = None
    if not isinstance(d, dict):
        raise InputFileError(p, f"message {k} on {topic}: the payload is not a JSON object "
                             "(not written by dynval)", None, f"record {k}")
    return d


def iter_records(path: Path | str, *, scan_out: Scan | None = None) -> Iterator[Any]:
    """The mcap records (Schema, Channel, Message, Metadata, ...) in file order, metadata also
    into scan_out.metadata. Recovers the complete part of a file without footer; a damaged
    chunk (CRC, compression, record layout) stops the read (scan_out.error)."""
    from mcap.exceptions import EndOfFile
    from mcap.records import Message as McapMessage
    from mcap.records import Metadata
    from mcap.stream_reader import CRCValidationError, StreamReader

    p = Path(path)
    s = scan(p)
    if scan_out is not None:
        for k, v in vars(s).items():
            setattr(scan_out, k, v)
    s = scan_out if scan_out is not None else s
    errors = _decode_errors()
    n = 0
    with open(p, "rb") as f:
        f.seek(8)
        body = io.BufferedReader(_Limited(f, s.good_bytes - 8))
        records = StreamReader(body, skip_magic=True, validate_crcs=True).records
        while True:
            try:
                r = next(records)
            except (StopIteration, EndOfFile):
                break  # the complete records are read; a footer-less file ends here
            except CRCValidationError as exc:
                s.error = f"chunk CRC mismatch: {exc}"
                log.warning("%s: %s; read stops there", p, s.error)
                break
            except errors as exc:
                s.error = f"damaged record after message {n}: {one_line(exc)}"
                log.warning("%s: %s; read stops there", p, s.error)
                break
            if isinstance(r, McapMessage):
                n += 1
            elif isinstance(r, Metadata):
                s.metadata[r.name] = dict(r.metadata)
            yield r


def iter_messages(path: Path | str, *, topics: set[str] | None = None,
                  prefix: str | None = None, scan_out: Scan | None = None) -> Iterator[Message]:
    """Messages in file order (decoded: JSON, or protobuf as dicts of every field) of
    iter_records, all or those on `topics` or under `prefix`; a payload that does not decode
    is an InputFileError naming the record."""
    from mcap.records import Channel as McapChannel
    from mcap.records import Message as McapMessage
    from mcap.records import Schema as McapSchema

    p = Path(path)
    schemas: dict[int, Any] = {}
    chans: dict[int, tuple[str, Any]] = {}
    n = 0
    for r in iter_records(p, scan_out=scan_out):
        if isinstance(r, McapSchema):
            schemas[r.id] = r
        elif isinstance(r, McapChannel):
            chans[r.id] = (r.topic, _decoder(p, r, schemas.get(r.schema_id)))
        elif isinstance(r, McapMessage):
            n += 1
            t, dec = chans.get(r.channel_id, ("?", None))
            if (topics is None and prefix is None) or (topics is not None and t in topics) or (
                    prefix is not None and t.startswith(prefix)):
                d = dec(r.data, n) if dec is not None else _payload(p, r.data, t, n)
                yield Message(t, r.log_time, d, r.sequence, r.publish_time)


def _decoder(p: Path, ch: Any, schema: Any) -> Any:
    """The payload decoder of a protobuf channel (None: JSON). dynval's features and
    residuals also get the channel's name (channel metadata) and the feature's name."""
    if ch.message_encoding != "protobuf":
        return None
    from google.protobuf.message import DecodeError

    from dynval.mcap_schema import ProtobufDecoder

    if schema is None or schema.encoding != "protobuf":
        raise InputFileError(p, f"channel {ch.topic}: protobuf messages without a protobuf "
                             "schema")
    try:
        dec = ProtobufDecoder(schema.name, bytes(schema.data))
    except Exception as exc:  # noqa: BLE001 - the protobuf library's many refusals
        raise InputFileError(p, f"channel {ch.topic}: its protobuf schema {schema.name!r} "
                             f"does not load: {one_line(exc)}") from None
    names = _channel_names(p, ch)
    named = schema.name in ("dynval.Feature", "dynval.Residual")

    def decode(data: bytes, k: int) -> dict[str, Any]:
        try:
            d = dec(data)
        except (DecodeError, ValueError) as exc:
            raise InputFileError(p, f"message {k} on {ch.topic}: not a {schema.name} "
                                 f"({one_line(exc)})", None, f"record {k}") from None
        if named:
            c = d.get("channel", -1)
            d["name"] = names[c] if isinstance(c, int) and 0 <= c < len(names) else f"ch{c}"
        if schema.name == "dynval.Feature":
            from dynval.bus import FEATURE_NAMES

            fid = d.get("feat_id")
            d["feature"] = FEATURE_NAMES.get(fid, "?") if isinstance(fid, int) else "?"
        return d

    return decode


def _channel_names(p: Path, ch: Any) -> list[str]:
    text = ch.metadata.get(CHANNEL_NAMES_KEY)
    if text is None:
        return []
    names = parse_json(p, text)
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise InputFileError(p, f"channel {ch.topic}: '{CHANNEL_NAMES_KEY}' is not a list of "
                             "names")
    return names


MAX_CHANNELS = 256  # DV_CHCFG's channel field is a byte


def _int_field(p: Path, m: Message, key: str, lo: int, hi: int) -> int:
    v = m.data.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v < hi:
        raise InputFileError(p, f"{m.topic} message: '{key}' must be an integer in "
                             f"[{lo}, {hi}), got {str(v)[:40]}", None, f"sequence {m.sequence}")
    return v


def _number(p: Path, m: Message, x: Any, lenient: bool) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise InputFileError(p, f"{m.topic} message: a sample value must be a number, got "
                             f"{str(x)[:40]}", None, f"sequence {m.sequence}")
    try:
        v = float(x)
    except OverflowError:
        raise InputFileError(p, f"{m.topic} message: a value beyond the float range", None,
                             f"sequence {m.sequence}") from None
    if v in (np.inf, -np.inf):  # the logger's missing sample is NaN (or absent), never inf
        if not lenient:
            raise InputFileError(p, f"{m.topic} message: a sample value of {v} (--lenient "
                                 "reads it as missing)", None, f"sequence {m.sequence}")
        return np.nan
    return v


def _values(p: Path, m: Message, lenient: bool = False) -> list[float]:
    """The samples of a message: [value] (NaN when absent) of the one-sample layout, or the
    old layout's 'values' (null for missing)."""
    if "values" not in m.data:
        v = m.data.get("value")
        return [np.nan if v is None else _number(p, m, v, lenient)]
    v = m.data["values"]
    if not isinstance(v, list) or len(v) > SAMPLES_PER_MESSAGE:
        raise InputFileError(p, f"{m.topic} message: 'values' must be a list of at most "
                             f"{SAMPLES_PER_MESSAGE} numbers or null", None,
                             f"sequence {m.sequence}")
    return [np.nan if x is None else _number(p, m, x, lenient) for x in v]


def _meta_json(p: Path, meta: dict[str, str], key: str) -> dict[str, str]:
    text = meta.get(key)
    if not text:
        return {}
    d = parse_json(p, text) if isinstance(text, str) else None
    if not isinstance(d, dict) or not all(isinstance(v, str) for v in d.values()):
        raise InputFileError(p, f"the 'dynval' metadata's '{key}' is not a JSON object of "
                             "strings")
    bad = [k for k, v in d.items() if v not in ("input", "output")] if key == "roles" else []
    if bad:  # any other role would make the channel neither the model's input nor an output
        raise InputFileError(p, f"the 'dynval' metadata's roles: {d[bad[0]][:40]!r} for "
                             f"{bad[0][:40]} is not input or output")
    return d


def _meta_rate(p: Path, meta: dict[str, str], chcfg_hz: float | None = None) -> float:
    """fs_hz of the metadata, else the DV_CHCFG frames' (a log decoded from a CAN log)."""
    try:
        fs = float(meta.get("fs_hz", "nan"))
    except (TypeError, ValueError):
        fs = float("nan")
    if fs != fs and chcfg_hz is not None:
        fs = chcfg_hz
    if not MIN_RATE_HZ <= fs <= MAX_RATE_HZ:
        raise InputFileError(p, "the 'dynval' metadata record has no usable fs_hz (nor the "
                             "DV_CHCFG frames)")
    return fs


def _meta_count(p: Path, meta: dict[str, str]) -> int | None:
    """n_samples of the metadata (None when absent)."""
    text = meta.get("n_samples")
    if text is None:
        return None
    try:
        n = int(text)
    except (TypeError, ValueError):
        n = -1
    if not 0 <= n <= MAX_SAMPLES:
        raise InputFileError(p, f"the 'dynval' metadata's n_samples is not a count: "
                             f"{str(text)[:40]}")
    return n


def _sample_name(p: Path, m: Message, had: str | None) -> str:
    """The channel name of a sample topic; a channel number must keep one name (two topics
    of one channel would be merged into one channel, the other's name lost)."""
    name = m.topic[len(T_SAMPLES):]
    if not name:
        raise InputFileError(p, f"topic {m.topic}: no channel name", None,
                             f"sequence {m.sequence}")
    if had is not None and had != name:
        raise InputFileError(p, f"{m.topic} message: channel {m.data.get('channel')} is on "
                             f"{T_SAMPLES}{had} too", None, f"sequence {m.sequence}")
    return name


def _check_channels(p: Path, names: dict[int, str], n: int, n_msgs: int) -> None:
    """One channel per name (two would be one name twice in the recording), and the samples
    of the record within memory (a damaged n_samples would ask for terabytes)."""
    seen: dict[str, int] = {}
    for ch, name in sorted(names.items()):
        if name in seen:
            raise InputFileError(p, f"{T_SAMPLES}{name} carries channels {seen[name]} and {ch}")
        seen[name] = ch
    try:
        mem = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # not POSIX: 16 GiB
        mem = 1 << 34
    if 8 * n * len(names) > mem // 2:
        raise InputFileError(p, f"the record claims {n} samples per channel ({n_msgs} sample "
                             "messages logged): more than half this machine's memory "
                             "(damaged n_samples?)")


def _samples(p: Path, name: str, got: dict[int, list[float]], n: int,
             n_rec: int | None) -> np.ndarray:
    """A channel's samples by index (NaN where missing), cut at n_samples; a sample logged
    beyond n_samples is an error, not cut without a word."""
    x = np.full(n, np.nan)
    for i, vals in got.items():
        x[i:i + len(vals)] = vals
    if n_rec is not None and n_rec < n:
        beyond = np.flatnonzero(~np.isnan(x[n_rec:]))
        if beyond.size:
            raise InputFileError(p, f"channel {name}: sample {n_rec + int(beyond[0])} is beyond "
                                 f"the record (n_samples {n_rec})")
        x = x[:n_rec]
    return x


def read_mcap(path: Path | str, *, lenient: bool = False) -> Recording:
    """The samples a dynval MCAP logged, as a Recording (channel order by channel number;
    gaps and missing samples are NaN, each counted in warnings). A message that is not a
    dynval sample message, or metadata that is not dynval's, is an InputFileError; so is a
    damaged chunk or a missing footer unless lenient."""
    p = Path(path)
    sc = Scan()
    per: dict[int, dict[int, list[float]]] = {}
    names: dict[int, str] = {}
    chcfg_hz: float | None = None
    twice: dict[int, int] = {}
    for m in iter_messages(p, topics={T_CONTROL}, prefix=T_SAMPLES, scan_out=sc):
        if m.topic == T_CONTROL:
            fs_cfg = m.data.get("fs_hz")
            if m.data.get("kind") == "chcfg" and isinstance(fs_cfg, int) and fs_cfg > 0:
                chcfg_hz = float(fs_cfg)
            continue
        if m.data.get("verdict") not in ("ok", "gap"):
            continue
        ch = _int_field(p, m, "channel", 0, MAX_CHANNELS)
        names[ch] = _sample_name(p, m, names.get(ch))
        idx = _int_field(p, m, "index", 0, MAX_SAMPLES)
        twice[ch] = twice.get(ch, 0) + (idx in per.setdefault(ch, {}))
        per[ch][idx] = _values(p, m, lenient)
    warnings: list[str] = []
    for bad, what in ((not sc.complete, f"no footer (logger stopped abnormally); read up to "
                       f"byte {sc.good_bytes}"), (bool(sc.error), sc.error)):
        if bad:
            if not lenient:
                raise InputFileError(p, f"{what} (use --lenient to read what remains)")
            warnings.append(f"{p}: {what}")
            log.warning(warnings[-1])
    meta = sc.metadata.get("dynval", {})
    if not per:
        raise InputFileError(p, "no /dv/samples/* messages in this MCAP")
    fs = _meta_rate(p, meta, chcfg_hz)
    units = _meta_json(p, meta, "units")
    roles = _meta_json(p, meta, "roles")
    n_rec = _meta_count(p, meta)
    n = max(i + len(v) for d in per.values() for i, v in d.items())
    n_msgs = sum(len(v) for d in per.values() for v in d.values())
    limit = n_rec + SAMPLES_PER_MESSAGE if n_rec is not None else GAP_LIMIT * n_msgs
    if n > limit:
        raise InputFileError(p, f"sample index {n - 1} is beyond the "
                             f"record ({'n_samples ' + str(n_rec) if n_rec is not None else ''}"
                             f"{'' if n_rec is not None else str(n_msgs) + ' sample messages'})")
    if n_rec is not None and n < n_rec:  # the log ends early (a recovered, killed logger)
        n = n_rec
    _check_channels(p, names, n, n_msgs)
    chans = []
    for ch in sorted(per):
        x = _samples(p, names[ch], per[ch], n, n_rec)
        miss, dup = int(np.isnan(x).sum()), twice.get(ch, 0)
        for what in ([f"{miss} missing samples (NaN)"] if miss else []) + (
                [f"{dup} samples logged twice (the later kept)"] if dup else []):
            warnings.append(f"{p}: channel {names[ch]}: {what}")
            log.warning(warnings[-1])
        unit = units.get(names[ch], "")
        chans.append(Channel(names[ch], x, unit and checked_unit(p, names[ch], unit, warnings),
                             roles.get(names[ch], "output")))
    return Recording(name=str(meta.get("test", p.stem)), fs_hz=fs, channels=chans, source=p,
                     sha256=file_sha256(p), warnings=warnings)
