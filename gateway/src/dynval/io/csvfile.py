"""CSV tests with a header: `time_s,force_N,acc1_mps2,...` (units in the names)."""
from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from dynval.errors import InputFileError
from dynval.io.jsonfile import decode_utf8
from dynval.io.recording import (
    MAX_RATE_HZ,
    Channel,
    Recording,
    default_role,
    file_sha256,
    parse_row,
    split_unit,
)

log = logging.getLogger(__name__)

# Sample clocks jitter by less than this fraction of a period in any real DAQ file.
_TIME_JITTER = 1e-3


_BLOCK_ROWS = 1 << 15  # rows parsed at once: a few MB of text, whatever the file's size


def read_csv(path: Path | str, *, lenient: bool = False) -> Recording:
    """Read a CSV test. Errors name file, line and column: missing header or columns,
    non-numeric cells, NaN, time that is not increasing or not regular, truncated rows, bytes
    that are not UTF-8. lenient=True turns recoverable row problems (NaN cells, short last row)
    into counted warnings; the affected cells become NaN, which the core drops and counts.
    The file is read in blocks of rows: memory is about twice the samples kept."""
    p = Path(path)
    warnings: list[str] = []
    try:
        with open(p, "rb") as f:
            header = _header(p, f.readline())
            data = _rows(p, f, header, lenient, warnings)
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    return _recording(p, header, data, lenient, warnings)


def _header(p: Path, first: bytes) -> list[str]:
    line = decode_utf8(p, first).rstrip("\r\n")
    if not line.strip():
        raise InputFileError(p, "empty file: expected a header such as time_s,force_N,acc1_mps2", 1)
    header = [h.strip() for h in line.split(",")]
    if any(not h for h in header):
        raise InputFileError(p, "empty column name in the header", 1)
    if len(set(header)) != len(header):
        raise InputFileError(p, "duplicate column names in the header", 1)
    try:
        float(header[0])
        raise InputFileError(p, "the first line is numeric: a header row is required", 1)
    except ValueError:
        pass
    if not (header[0].lower().startswith("time") or header[0].lower() == "t"):
        raise InputFileError(p, f"the first column must be the time (e.g. time_s), found "
                             f"'{header[0]}'", 1, header[0])
    if len(header) < 2:
        raise InputFileError(p, "no channel columns besides the time", 1)
    return header


def _lines(p: Path, f: BinaryIO) -> Iterator[tuple[int, str, bool]]:
    """(line number, text, is the file's last line) of the non-blank data lines."""
    prev: tuple[int, str] | None = None
    for ln, raw in enumerate(f, start=2):
        if prev is not None:
            yield (*prev, False)
            prev = None
        try:
            text = raw.decode("utf-8").rstrip("\r\n")
        except UnicodeDecodeError as exc:
            raise InputFileError(p, f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at column "
                                 f"{exc.start + 1} of the line)", ln) from None
        if text.strip():
            prev = (ln, text)
        else:
            prev = None
    if prev is not None:
        yield (*prev, True)


def _rows(p: Path, f: BinaryIO, header: list[str], lenient: bool,
          warnings: list[str]) -> np.ndarray:
    """The data rows as an (n, columns) array, parsed block by block."""
    blocks: list[np.ndarray] = []
    block: list[tuple[int, str, bool]] = []
    for item in _lines(p, f):
        block.append(item)
        if len(block) == _BLOCK_ROWS:
            blocks.append(_parse_block(p, block, header, lenient, warnings))
            block = []
    if block:
        blocks.append(_parse_block(p, block, header, lenient, warnings))
    n = sum(len(b) for b in blocks)
    if n < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {n}")
    data = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    return data


def _parse_block(p: Path, block: list[tuple[int, str, bool]], header: list[str], lenient: bool,
                 warnings: list[str]) -> np.ndarray:
    """numpy's parser for a block of clean rows; a block it refuses (or with NaN/Inf) is parsed
    row by row, which names the line and column of the problem or counts it (lenient)."""
    try:
        a = np.loadtxt([t for _, t, _ in block], delimiter=",", comments=None, ndmin=2,
                       dtype=np.float64)
        if a.shape == (len(block), len(header)) and np.isfinite(a).all():
            return a
    except ValueError:
        pass
    rows = [parse_row(p, ln, text.split(","), header, last=last, lenient=lenient,
                      warnings=warnings, required=0) for ln, text, last in block]
    kept = [r for r in rows if r is not None]
    return np.array(kept, dtype=np.float64).reshape(len(kept), len(header))


def _recording(p: Path, header: list[str], data: np.ndarray, lenient: bool,
               warnings: list[str]) -> Recording:
    t = data[:, 0]
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0])
        raise InputFileError(p, f"time does not increase ({t[i]!r} then {t[i + 1]!r})", i + 3,
                             header[0])
    period = float(np.median(dt))
    if not 0 < 1.0 / period <= MAX_RATE_HZ:
        raise InputFileError(p, f"time step {period!r} s is not a usable sample period", 2,
                             header[0])
    off = np.flatnonzero(np.abs(dt - period) > _TIME_JITTER * period + 1e-12)
    if off.size:
        i = int(off[0])
        msg = (f"irregular sampling: step {dt[i]!r} s where the period is {period!r} s "
               f"({off.size} irregular steps)")
        if not lenient:
            raise InputFileError(p, msg, i + 3, header[0])
        warnings.append(f"{p}:{i + 3}: {msg}")
        log.warning(warnings[-1])
    channels = []
    for j, col in enumerate(header[1:], start=1):
        name, unit = split_unit(col)
        channels.append(Channel(name=name, data=data[:, j].copy(), unit=unit,
                                role=default_role(col)))
    return Recording(name=p.stem, fs_hz=1.0 / period, channels=channels, source=p,
                     sha256=file_sha256(p), warnings=warnings, t0_s=float(t[0]))
