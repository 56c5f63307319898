"""CSV tests with a header: `time_s,force_N,acc1_mps2,...` (units in the names), after an
optional `#` preamble; `,` `;` or tab separated, quoted or not, decimal point or comma."""
from __future__ import annotations

import csv
import importlib
import io
import logging
import warnings as warnings_module
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from dynval.errors import InputFileError
from dynval.io.arrays import regular_period
from dynval.io.recording import (
    Channel,
    Recording,
    default_role,
    file_sha256,
    parse_row,
    split_unit,
)

log = logging.getLogger(__name__)

_pd: Any  # pandas' C parser where installed (the `formats` extra): about twice numpy's speed
try:
    _pd = importlib.import_module("pandas")
except ImportError:  # pragma: no cover - numpy's block parser then
    _pd = None

_BLOCK_BYTES = 1 << 20  # text parsed at once: 1 MB of lines, whatever the file's size
_QUOTE = '"'


@dataclass(frozen=True)
class _Dialect:
    """How the file writes its table: the cell separator and the decimal mark (a ';' file
    with decimal commas, as spreadsheets write them in much of Europe)."""

    sep: str = ","
    decimal: str = "."


def read_csv(path: Path | str, *, lenient: bool = False) -> Recording:
    """Read a CSV test. Before the header, lines starting with '#' (a logger's preamble) and
    blank lines are skipped. Cells are separated by ',' (or ';' or a tab, as the header
    shows), may be quoted ("1.5"), and use a decimal point, or a decimal comma in a
    ';'-separated file. Errors name file, line and column: missing header or columns,
    non-numeric cells, NaN, time that is not increasing or not regular, truncated rows, bytes
    that are not UTF-8. lenient=True turns recoverable row problems (NaN cells, short last row)
    into counted warnings; the affected cells become NaN, which the core drops and counts.
    the fast parser reads blocks of 1 MB; a block it refuses is read row by row, which names
    the problem's line. Memory is about twice the samples kept."""
    p = Path(path)
    warnings: list[str] = []
    try:
        with open(p, "rb") as f:
            header_ln, header, dialect, pending = _header(p, f)
            data, lines = _rows(p, f, pending, header_ln + 1, header, dialect, lenient, warnings)
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    return _recording(p, header, data, lines, lenient, warnings)


def _split(line: str, sep: str) -> list[str]:
    """The cells of one line, quotes removed ("a,b" is one cell)."""
    if _QUOTE not in line:
        return line.split(sep)
    return next(csv.reader([line], delimiter=sep, quotechar=_QUOTE))


def _header(p: Path, f: BinaryIO) -> tuple[int, list[str], _Dialect, bytes]:
    """(line number, column names, dialect, the first data line) after the preamble."""
    ln = 0
    while True:
        raw = f.readline()
        ln += 1
        if not raw:
            raise InputFileError(p, "empty file: expected a header such as "
                                 "time_s,force_N,acc1_mps2", ln)
        try:
            line = raw.decode("utf-8-sig" if ln == 1 else "utf-8").rstrip("\r\n")
        except UnicodeDecodeError as exc:
            raise InputFileError(p, f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                                 f"{exc.start} of the line)", ln) from None
        if line.strip() and not line.lstrip().startswith("#"):
            break
    unquoted = line.replace(_QUOTE, "")
    sep = next((s for s in (";", "\t") if s in unquoted and "," not in unquoted), ",")
    header = [h.strip() for h in _split(line, sep)]
    if any(not h for h in header):
        raise InputFileError(p, "empty column name in the header", ln)
    if len(set(header)) != len(header):
        raise InputFileError(p, "duplicate column names in the header", ln)
    try:
        float(header[0].replace(",", "."))
        raise InputFileError(p, "the first line is numeric: a header row is required", ln)
    except ValueError:
        pass
    if not (header[0].lower().startswith("time") or header[0].lower() == "t"):
        found = _shown(header[0])
        hint = "" if found == header[0] else " (not a CSV text file?)"
        raise InputFileError(p, f"the first column must be the time (e.g. time_s), found "
                             f"'{found}'{hint}", ln, None if hint else found)
    if len(header) < 2:
        raise InputFileError(p, "no channel columns besides the time", ln)
    first = f.readline()
    decimal = "," if sep != "," and b"," in first else "."
    return ln, header, _Dialect(sep, decimal), first


def _shown(name: str, most: int = 40) -> str:
    """A column name as an error message can show it on one line: control and other
    unprintable characters escaped, at most ``most`` characters (a binary file read as text
    has a 'header' of any length and bytes)."""
    out = "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in name)
    return out if len(out) <= most else out[:most] + "..."


def _rows(p: Path, f: BinaryIO, pending: bytes, ln0: int, header: list[str], dialect: _Dialect,
          lenient: bool, warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The data rows as an (n, columns) array and each row's line number, parsed in blocks of
    whole lines (the block with the file's last line knows it: a short last row may be a
    truncation)."""
    blocks: list[np.ndarray] = []
    lines: list[np.ndarray] = []
    buf = pending + f.read(_BLOCK_BYTES)
    ln = ln0
    while buf:
        more = f.read(_BLOCK_BYTES)
        if more:
            cut = buf.rfind(b"\n") + 1
            if cut == 0:  # one line longer than a block: take it whole
                buf += more
                continue
            block, buf = buf[:cut], buf[cut:] + more
        else:
            block, buf = buf, b""
        a, lns = _parse_block(p, block, ln, header, dialect, not buf, lenient, warnings)
        blocks.append(a)
        lines.append(lns)
        ln += block.count(b"\n")
    n = sum(len(b) for b in blocks)
    if n < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {n}")
    if len(blocks) == 1:
        return blocks[0], lines[0]
    return np.concatenate(blocks), np.concatenate(lines)


def _fast(block: bytes, dialect: _Dialect, ncol: int) -> np.ndarray | None:
    """The block parsed by pandas' C parser (numpy's where pandas is not installed), or None
    where it refuses the text; blank lines are skipped, as the row-by-row path skips them."""
    try:
        if _pd is not None:
            return np.asarray(_pd.read_csv(
                io.BytesIO(block), header=None, sep=dialect.sep, decimal=dialect.decimal,
                quotechar=_QUOTE, dtype=np.float64, engine="c", skip_blank_lines=True,
                encoding="utf-8", encoding_errors="strict").to_numpy(), dtype=np.float64)
        text = block.decode("utf-8")
        if dialect.decimal == ",":
            text = text.replace(",", ".")
        with warnings_module.catch_warnings():
            warnings_module.simplefilter("error")  # "empty input": the row-by-row path says it
            return np.loadtxt(io.StringIO(text), delimiter=dialect.sep, quotechar=_QUOTE,
                              comments=None, ndmin=2, dtype=np.float64)
    except (ValueError, UnicodeDecodeError, UserWarning, OverflowError):
        return None
    except Exception as exc:  # noqa: BLE001 - pandas' EmptyDataError and kin: parse by rows
        log.debug("fast CSV path refused a block: %s", exc)
        return None


def _parse_block(p: Path, block: bytes, ln0: int, header: list[str], dialect: _Dialect,
                 last: bool, lenient: bool, warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The fast parser for a block of clean rows (line numbers ln0...); a block it refuses (or
    with NaN/Inf, or not UTF-8) is parsed row by row, which names the line and column of the
    problem or counts it (lenient)."""
    n_lines = block.count(b"\n") + (not block.endswith(b"\n"))
    a = _fast(block, dialect, len(header))
    if a is not None and a.ndim == 2 and a.shape[1] == len(header) and np.isfinite(a).all():
        if a.shape[0] == n_lines:
            return a, np.arange(ln0, ln0 + n_lines, dtype=np.int64)
        kept = [ln0 + i for i, raw in enumerate(block.split(b"\n")) if raw.strip()]
        if len(kept) == a.shape[0]:  # the parser skipped the blank lines, as the rows do
            return a, np.asarray(kept, dtype=np.int64)
    raws = block.split(b"\n")
    if raws and raws[-1] == b"":
        raws.pop()
    rows: list[list[float]] = []
    keep: list[int] = []
    for i, raw in enumerate(raws):
        ln = ln0 + i
        try:
            line = raw.decode("utf-8").rstrip("\r")
        except UnicodeDecodeError as exc:
            raise InputFileError(p, f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at column "
                                 f"{exc.start + 1} of the line)", ln) from None
        if not line.strip():
            continue
        try:
            cells = _split(line, dialect.sep)
        except csv.Error as exc:
            raise InputFileError(p, f"bad quoting ({exc})", ln) from None
        if dialect.decimal == ",":
            cells = [c.replace(",", ".") for c in cells]
        is_last = last and not any(r.strip() for r in raws[i + 1:])
        row = parse_row(p, ln, cells, header, last=is_last, lenient=lenient,
                        warnings=warnings, required=0)
        if row is not None:
            rows.append(row)
            keep.append(ln)
    return (np.array(rows, dtype=np.float64).reshape(len(rows), len(header)),
            np.asarray(keep, dtype=np.int64))


def _recording(p: Path, header: list[str], data: np.ndarray, lines: np.ndarray, lenient: bool,
               warnings: list[str]) -> Recording:
    t = data[:, 0]
    period = regular_period(p, t, lenient=lenient, warnings=warnings,
                            locate=lambda i: (int(lines[i]), ""), column=header[0])
    channels = []
    for j, col in enumerate(header[1:], start=1):
        name, unit = split_unit(col)
        channels.append(Channel(name=name, data=data[:, j].copy(), unit=unit,
                                role=default_role(col)))
    return Recording(name=p.stem, fs_hz=1.0 / period, channels=channels, source=p,
                     sha256=file_sha256(p), warnings=warnings, t0_s=float(t[0]))
