"""The LabVIEW text layout of the DROPBEAR data set 8 (../shared/data/real/dropbear-dataset8,
SOURCE.md): 9 header lines (path, programmer, striker velocity, 'Sampling Frequency - N', date,
channel names, units, two filler lines), then tab-separated rows ending with a Time column.

The DAQ artefact SOURCE.md describes (the 'Accel' column dropping to about -1.4 V on every ~5th
sample) is detected and reported as a counted warning; mask_artefact=True turns those samples
into NaN (the core drops and counts them). Nothing is changed silently."""
from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from dynval.errors import InputFileError
from dynval.io.recording import Channel, Recording, file_sha256, parse_row

log = logging.getLogger(__name__)

HEADER_LINES = 9
_FS = re.compile(r"^\s*Sampling Frequency\s*-\s*([0-9.eE+-]+)\s*$")
ARTEFACT_COLUMN = "Accel"
ARTEFACT_LEVEL_V = -1.0  # the spikes sit near -1.4 V; the signal stays within +-0.5 V


def looks_like_dropbear(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            head = [f.readline() for _ in range(4)]
    except OSError:
        return False
    return any(_FS.match(h) for h in head)


def _name(col: str) -> str:
    return re.sub(r"[^0-9A-Za-z]+", "_", col.strip()).strip("_").lower()


def _time_tol(t: np.ndarray) -> np.ndarray:
    """Half a unit in the 6th significant digit (the file prints 1.19996E+1)."""
    mag = np.floor(np.log10(np.maximum(np.abs(t), 1e-30)))
    return np.asarray(0.5 * 10.0 ** (mag - 5) + 1e-12)


def read_dropbear(path: Path | str, *, lenient: bool = False,
                  mask_artefact: bool = False) -> Recording:
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8", errors="strict").splitlines()
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise InputFileError(p, f"not a text file ({exc.reason})") from exc
    if len(lines) < HEADER_LINES + 2:
        raise InputFileError(p, f"a DROPBEAR file has {HEADER_LINES} header lines and data; "
                             f"found {len(lines)} lines (truncated?)", len(lines))
    fs = None
    for head in lines[:5]:
        m = _FS.match(head)
        if m:
            fs = float(m.group(1))
    if fs is None or not fs > 0:
        raise InputFileError(p, "no 'Sampling Frequency - N' line in the header", 4)
    cols = [c.strip() for c in lines[5].split("\t") if c.strip()]
    units = [c.strip() for c in lines[6].split("\t") if c.strip()]
    if not cols or cols[-1].lower() != "time":
        raise InputFileError(p, "line 6 must name the columns, the last being 'Time'", 6)
    ncol = len(cols)
    warnings: list[str] = []
    data = np.empty((len(lines) - HEADER_LINES, ncol))
    n = 0
    last = len(lines)
    for ln in range(HEADER_LINES + 1, last + 1):
        text = lines[ln - 1]
        if not text.strip():
            continue
        row = parse_row(p, ln, text.split("\t"), cols, last=ln == last, lenient=lenient,
                        warnings=warnings, required=ncol - 1)
        if row is None:
            continue
        data[n] = row
        n += 1
    data = data[:n]
    if n < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {n}")
    t = data[:, -1]
    want = t[0] + np.arange(n) / fs
    off = np.flatnonzero(np.abs(t - want) > _time_tol(want) + 1e-9)
    if off.size:
        i = int(off[0])
        msg = (f"time {t[i]:.9g} s where the {fs:g} Hz clock gives {want[i]:.9g} s "
               f"({off.size} rows off the clock)")
        if not lenient:
            raise InputFileError(p, msg, HEADER_LINES + 1 + i, cols[-1])
        warnings.append(f"{p}:{HEADER_LINES + 1 + i}: {msg}")
        log.warning(warnings[-1])
    chans = []
    for j, col in enumerate(cols[:-1]):
        x = data[:, j].copy()
        unit = "V" if j < len(units) and units[j].lower().startswith("voltage") else ""
        if col == ARTEFACT_COLUMN:
            spikes = np.flatnonzero(x < ARTEFACT_LEVEL_V)
            if spikes.size:
                what = "masked as NaN" if mask_artefact else "kept"
                warnings.append(f"{p}: column {col}: {spikes.size} samples below "
                                f"{ARTEFACT_LEVEL_V} V (the DAQ spike artefact of SOURCE.md, "
                                f"first at line {HEADER_LINES + 1 + int(spikes[0])}); {what}")
                log.warning(warnings[-1])
                if mask_artefact:
                    x[spikes] = np.nan
        role = "output"
        chans.append(Channel(name=_name(col), data=x, unit=unit, role=role))
    return Recording(name=p.stem, fs_hz=float(fs), channels=chans, source=p,
                     sha256=file_sha256(p), warnings=warnings, t0_s=float(t[0]))
