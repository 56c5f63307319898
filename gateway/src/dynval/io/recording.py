"""A recorded test in memory: equally sampled channels with units and roles."""
from __future__ import annotations

import hashlib
import logging
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynval.errors import InputFileError

MAX_RATE_HZ = 1e9  # no DAQ samples faster: a larger rate (a time step near 0) is a damaged file
MIN_RATE_HZ = 2.0 ** -32  # the core's longest sample period (DV_TEMPORAL_MAX_DT_S), 136 years
_UNIT_SUFFIX = re.compile(r"^(?P<name>.+?)_(?P<unit>mps2|m_s2|N|m|mm|s|V|g|ms2|um|ue|lbf|in)$")
_UNITS = {"mps2": "m/s^2", "m_s2": "m/s^2", "ms2": "m/s^2", "N": "N", "m": "m", "mm": "mm",
          "s": "s", "V": "V", "g": "g", "um": "um", "ue": "microstrain", "lbf": "lbf", "in": "in"}


@dataclass
class Channel:
    """One measured channel. role is 'input' (a force or prescribed motion) or 'output'."""

    name: str
    data: np.ndarray
    unit: str = ""
    role: str = "output"
    dof: int | None = None
    scale: float = 1.0


@dataclass
class Recording:
    """Channels sampled at fs_hz, in file order, plus where they came from."""

    name: str
    fs_hz: float
    channels: list[Channel]
    source: Path | None = None
    sha256: str = ""
    warnings: list[str] = field(default_factory=list)
    t0_s: float = 0.0

    @property
    def n_samples(self) -> int:
        return int(self.channels[0].data.size) if self.channels else 0

    def channel(self, name: str) -> Channel:
        for c in self.channels:
            if c.name == name:
                return c
        raise KeyError(f"{self.name}: no channel '{name}' (have {', '.join(self.names)})")

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.channels]


def split_unit(column: str) -> tuple[str, str]:
    """'acc1_mps2' -> ('acc1', 'm/s^2'); a name without a known unit suffix keeps unit ''."""
    m = _UNIT_SUFFIX.match(column)
    if m is None:
        return column, ""
    return column, _UNITS[m.group("unit")]


def base_name(column: str) -> str:
    """'acc1_mps2' -> 'acc1': the column without a known unit suffix."""
    m = _UNIT_SUFFIX.match(column)
    return column if m is None else m.group("name")


def default_role(column: str) -> str:
    """Forces and prescribed motions are inputs by default; everything else an output."""
    low = column.lower()
    return "input" if low.startswith(("force", "f_", "stroke", "disp_in", "input")) else "output"


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def parse_row(path: Path, ln: int, cells: Sequence[str], names: Sequence[str], *, last: bool,
              lenient: bool, warnings: list[str], required: int = -1) -> list[float] | None:
    """One data row of a text table (the CSV and the whitespace readers): its cells as floats.
    Errors name the file, line and column: a wrong number of cells, a non-number, NaN/Inf.
    lenient=True drops a short last row (a truncated file: returns None) and keeps NaN/Inf and
    empty cells as NaN (the core drops and counts it), each counted in warnings; column
    `required` (the time) must be finite even then."""
    ncol = len(names)
    if len(cells) != ncol:
        msg = f"expected {ncol} cells, found {len(cells)}"
        if lenient and last and len(cells) < ncol:
            warnings.append(f"{path}:{ln}: truncated last row dropped ({msg})")
            logging.getLogger(__name__).warning(warnings[-1])
            return None
        raise InputFileError(path, msg + (" (truncated file?)" if last else ""), ln)
    row = []
    for j, cell in enumerate(cells):
        # lenient: an empty cell is a missing sample (a spreadsheet's), as NaN is
        empty = lenient and j != required and not cell.strip()
        try:
            v = math.nan if empty else float(cell)
        except ValueError:
            raise InputFileError(path, f"not a number: {cell.strip()!r}", ln, names[j]) from None
        if not math.isfinite(v):
            if not lenient or j == required:
                raise InputFileError(path, f"non-finite value {cell.strip()!r}", ln, names[j])
            what = f"empty {names[j]} cell" if empty else f"non-finite {names[j]}"
            warnings.append(f"{path}:{ln}: {what} kept as NaN (dropped and counted by the "
                            "core)")
            logging.getLogger(__name__).warning(warnings[-1])
            v = math.nan
        row.append(v)
    return row
