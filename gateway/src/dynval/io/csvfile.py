"""CSV tests with a header: `time_s,force_N,acc1_mps2,...` (units in the names)."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from dynval.errors import InputFileError
from dynval.io.recording import Channel, Recording, default_role, file_sha256, parse_row, split_unit

log = logging.getLogger(__name__)

# Sample clocks jitter by less than this fraction of a period in any real DAQ file.
_TIME_JITTER = 1e-3


def read_csv(path: Path | str, *, lenient: bool = False) -> Recording:
    """Read a CSV test. Errors name file, line and column: missing header or columns,
    non-numeric cells, NaN, time that is not increasing or not regular, truncated rows.
    lenient=True turns recoverable row problems (NaN cells, short last row) into counted
    warnings; the affected cells become NaN, which the core drops and counts."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise InputFileError(p, f"not a text file ({exc.reason})") from exc
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise InputFileError(p, "empty file: expected a header such as time_s,force_N,acc1_mps2", 1)
    header = [h.strip() for h in lines[0].split(",")]
    if any(not h for h in header):
        raise InputFileError(p, "empty column name in the header", 1)
    if len(set(header)) != len(header):
        raise InputFileError(p, "duplicate column names in the header", 1)
    try:
        float(header[0])
        raise InputFileError(p, "the first line is numeric: a header row is required", 1)
    except ValueError:
        pass
    rows: list[list[float]] = []
    warnings: list[str] = []
    for ln, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        row = parse_row(p, ln, line.split(","), header, last=ln == len(lines), lenient=lenient,
                        warnings=warnings, required=0)
        if row is not None:
            rows.append(row)
    if len(rows) < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {len(rows)}")
    data = np.array(rows, dtype=np.float64)
    has_time = header[0].lower().startswith("time") or header[0].lower() == "t"
    if not has_time:
        raise InputFileError(p, f"the first column must be the time (e.g. time_s), found "
                             f"'{header[0]}'", 1, header[0])
    t = data[:, 0]
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0])
        raise InputFileError(p, f"time does not increase ({t[i]!r} then {t[i + 1]!r})", i + 3,
                             header[0])
    period = float(np.median(dt))
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
