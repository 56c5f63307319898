"""Reading MCAP files written by dynval, including files a killed logger left behind.

iter_messages() reads records sequentially with mcap's non-seeking StreamReader. A file
without its footer (the logger was killed) is read up to the last complete record: the
records are first walked by their length prefixes, and the reader only sees the complete ones;
a chunk whose CRC does not match ends the read. read_mcap() turns the /dv/samples/<channel>
topics back into a Recording (the values the firmware saw)."""
from __future__ import annotations

import io
import json
import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import InputFileError
from dynval.io.recording import Channel, Recording, file_sha256
from dynval.topics import T_SAMPLES

log = logging.getLogger(__name__)

MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER = 0x02
OP_CHUNK = 0x06


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


def iter_messages(path: Path | str, *, topics: set[str] | None = None,
                  prefix: str | None = None, scan_out: Scan | None = None) -> Iterator[Message]:
    """Messages in file order (decoded JSON), metadata into scan_out.metadata. Recovers the
    complete part of a file without footer; a bad chunk CRC stops the read (scan_out.error)."""
    from mcap.exceptions import EndOfFile, McapError
    from mcap.records import Channel as McapChannel
    from mcap.records import Message as McapMessage
    from mcap.records import Metadata
    from mcap.stream_reader import CRCValidationError, StreamReader

    p = Path(path)
    s = scan(p)
    if scan_out is not None:
        for k, v in vars(s).items():
            setattr(scan_out, k, v)
    s = scan_out if scan_out is not None else s
    chans: dict[int, str] = {}
    with open(p, "rb") as f:
        f.seek(8)
        body = io.BufferedReader(_Limited(f, s.good_bytes - 8))
        reader = StreamReader(body, skip_magic=True, validate_crcs=True)
        try:
            for r in reader.records:
                if isinstance(r, McapChannel):
                    chans[r.id] = r.topic
                elif isinstance(r, McapMessage):
                    t = chans.get(r.channel_id, "?")
                    if (topics is None or t in topics) and (prefix is None or
                                                           t.startswith(prefix)):
                        yield Message(t, r.log_time, json.loads(r.data), r.sequence)
                elif isinstance(r, Metadata):
                    s.metadata[r.name] = dict(r.metadata)
        except EndOfFile:
            pass  # the complete records are read; a footer-less file ends here
        except CRCValidationError as exc:
            s.error = f"chunk CRC mismatch: {exc}"
            log.warning("%s: %s; read stops there", p, s.error)
        except (McapError, struct.error, ValueError) as exc:
            s.error = str(exc)
            log.warning("%s: %s; read stops there", p, exc)


def read_mcap(path: Path | str, *, lenient: bool = False) -> Recording:
    """The samples a dynval MCAP logged, as a Recording (channel order by channel number;
    gaps and missing samples are NaN, each counted in warnings)."""
    p = Path(path)
    sc = Scan()
    per: dict[int, dict[int, list[float | None]]] = {}
    names: dict[int, str] = {}
    for m in iter_messages(p, prefix=T_SAMPLES, scan_out=sc):
        if m.data.get("verdict") not in ("ok", "gap"):
            continue
        ch = int(m.data["channel"])
        names[ch] = m.topic.rsplit("/", 1)[1]
        per.setdefault(ch, {})[int(m.data["index"])] = m.data["values"]
    warnings: list[str] = []
    if not sc.complete:
        msg = f"{p}: no footer (logger stopped abnormally); read up to byte {sc.good_bytes}"
        if not lenient:
            raise InputFileError(p, msg + " (use --lenient to read what remains)")
        warnings.append(msg)
        log.warning(msg)
    meta = sc.metadata.get("dynval", {})
    if not per:
        raise InputFileError(p, "no /dv/samples/* messages in this MCAP")
    try:
        fs = float(meta.get("fs_hz", "nan"))
    except ValueError:
        fs = float("nan")
    if not fs > 0:
        raise InputFileError(p, "the 'dynval' metadata record has no fs_hz")
    units = json.loads(meta.get("units", "{}")) if meta.get("units") else {}
    roles = json.loads(meta.get("roles", "{}")) if meta.get("roles") else {}
    n = max(max(d) + 3 for d in per.values())
    chans = []
    for ch in sorted(per):
        x = np.full(n, np.nan)
        for i, vals in per[ch].items():
            x[i:i + 3] = [np.nan if v is None else v for v in vals]
        miss = int(np.isnan(x).sum())
        if miss:
            warnings.append(f"{p}: channel {names[ch]}: {miss} missing samples (NaN)")
        chans.append(Channel(names[ch], x, units.get(names[ch], ""),
                             roles.get(names[ch], "output")))
    n_rec = int(meta.get("n_samples", n))
    for c in chans:
        c.data = c.data[:n_rec]
    return Recording(name=meta.get("test", p.stem), fs_hz=fs, channels=chans, source=p,
                     sha256=file_sha256(p), warnings=warnings)
