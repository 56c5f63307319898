"""Whitespace-separated text tests: one column per channel, no time column, a given sampling
rate. Default layout (the three-story structure data): force + 4 accelerations. An optional
first line of names (non-numeric) names the columns; '#' starts a comment."""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dynval.errors import InputFileError
from dynval.io.recording import Channel, Recording, default_role, file_sha256, parse_row, split_unit

#: the three-story structure layout: channel 1 force, channels 2..5 accelerations of DOF 1..4
DEFAULT_COLUMNS = ("force_N", "acc1_mps2", "acc2_mps2", "acc3_mps2", "acc4_mps2")


def default_names(ncol: int) -> list[str]:
    if ncol == len(DEFAULT_COLUMNS):
        return list(DEFAULT_COLUMNS)
    return [f"ch{i + 1}" for i in range(ncol)]


def read_text(path: Path | str, fs_hz: float, *, columns: Sequence[str] | None = None,
              lenient: bool = False) -> Recording:
    """Read a whitespace text test sampled at fs_hz. Errors name file, line and column: rows
    with a different number of cells, non-numeric cells, NaN/Inf. lenient=True keeps NaN/Inf
    cells as NaN and drops a short last row (truncated file), each counted in warnings."""
    p = Path(path)
    if not (fs_hz > 0 and math.isfinite(fs_hz)):
        raise InputFileError(p, f"a text test needs a sampling rate > 0 (--fs), got {fs_hz}")
    try:
        lines = p.read_text(encoding="utf-8-sig").splitlines()
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise InputFileError(p, f"not a text file ({exc.reason})") from exc
    header: list[str] | None = list(columns) if columns else None
    rows: list[list[float]] = []
    warnings: list[str] = []
    ncol = len(header) if header else 0
    numbered = [(i, ln.split("#", 1)[0].split()) for i, ln in enumerate(lines, 1)]
    numbered = [(i, c) for i, c in numbered if c]
    if not numbered:
        raise InputFileError(p, "no data rows", 1)
    first_ln, first = numbered[0]
    try:
        [float(c) for c in first]
    except ValueError:
        if header is None:
            header = first
        ncol = len(first)
        numbered = numbered[1:]
    if not ncol:
        ncol = len(numbered[0][1])
    names = header if header else default_names(ncol)
    if len(names) != ncol:
        raise InputFileError(p, f"{len(names)} column names for {ncol} columns", first_ln)
    last_ln = numbered[-1][0] if numbered else first_ln
    for ln, cells in numbered:
        row = parse_row(p, ln, cells, names, last=ln == last_ln, lenient=lenient,
                        warnings=warnings)
        if row is not None:
            rows.append(row)
    if len(rows) < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {len(rows)}")
    data = np.array(rows, dtype=np.float64)
    chans = []
    for j, col in enumerate(names):
        name, unit = split_unit(col)
        chans.append(Channel(name=name, data=data[:, j].copy(), unit=unit,
                             role=default_role(col)))
    return Recording(name=p.stem, fs_hz=float(fs_hz), channels=chans, source=p,
                     sha256=file_sha256(p), warnings=warnings)
