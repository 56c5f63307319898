"""The JSON layout of the friction-damper (BRFD) data set (../shared/data/real/
friction-damper-brfd, SOURCE.md): {"data": [[t, disp, force, vel, ...], ...], "dt": ...,
"sampling freq": ..., "<quantity> units": ...}. 6 columns (dataset-2) or 8 (dataset-4).
Input: the measured displacement; output: the friction force."""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import InputFileError, short_repr
from dynval.io.jsonfile import read_json
from dynval.io.recording import MAX_RATE_HZ, Channel, Recording, file_sha256

log = logging.getLogger(__name__)

# (name, units key, role); the first column is the time
COLUMNS_6 = (("displacement", "displacement units", "input"),
             ("friction_force", "friction force units", "output"),
             ("velocity", "displacement units/s", "output"),
             ("actuator_force1", "actuator force units", "output"),
             ("actuator_force2", "actuator force units", "output"))
COLUMNS_8 = (COLUMNS_6[:3] + (("actuator_pos1", "displacement units", "output"),
                              ("actuator_pos2", "displacement units", "output"))
             + COLUMNS_6[3:])
_TIME_JITTER = 1e-3


def looks_like_brfd(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            head = f.read(64).lstrip()
    except OSError:
        return False
    return head.startswith(b"{") and b'"data"' in head


def _unit(meta: dict[str, Any], key: str) -> str:
    if key.endswith("/s"):
        base = meta.get(key[:-2])
        return f"{base}/s" if isinstance(base, str) else ""
    v = meta.get(key)
    return v if isinstance(v, str) else ""


def _rate(p: Path, meta: dict[str, Any]) -> float:
    """The sampling rate: 'sampling freq', else 1 / 'dt'; within MAX_RATE_HZ."""
    for key, invert in (("sampling freq", False), ("dt", True)):
        v = meta.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        try:
            fs = 1.0 / float(v) if invert else float(v)
        except (OverflowError, ZeroDivisionError):
            continue
        if 0 < fs <= MAX_RATE_HZ:
            return fs
    raise InputFileError(p, "neither 'sampling freq' nor 'dt' gives a rate in "
                         f"(0, {MAX_RATE_HZ:g}] Hz")


def read_brfd(path: Path | str, *, lenient: bool = False) -> Recording:
    """Read a BRFD JSON test. Errors name the file, the data row (as 'line', 1-based) and the
    column: missing keys, ragged rows, non-numeric/NaN values, time not matching dt."""
    p = Path(path)
    meta = read_json(p)
    if not isinstance(meta, dict) or not isinstance(meta.get("data"), list):
        raise InputFileError(p, "expected a JSON object with a 'data' list of rows")
    rows = meta["data"]
    if len(rows) < 2:
        raise InputFileError(p, f"needs at least 2 data rows, found {len(rows)}")
    ncol = len(rows[0]) if isinstance(rows[0], list) else 0
    if ncol not in (6, 8):
        raise InputFileError(p, f"rows have {ncol} values; the BRFD layout has 6 or 8", 1)
    cols = COLUMNS_6 if ncol == 6 else COLUMNS_8
    names = ["t", *(c[0] for c in cols)]
    warnings: list[str] = []
    data = np.empty((len(rows), ncol))
    for i, r in enumerate(rows):
        if not isinstance(r, list) or len(r) != ncol:
            raise InputFileError(p, f"data row has {len(r) if isinstance(r, list) else 'no'} "
                                 f"values, expected {ncol}", i + 1)
        for j, v in enumerate(r):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise InputFileError(p, f"not a number: {short_repr(v)}", i + 1, names[j])
            try:
                v = float(v)
            except OverflowError:
                raise InputFileError(p, f"number beyond the float range: {short_repr(v)}", i + 1,
                                     names[j]) from None
            if not math.isfinite(v):
                if not lenient or j == 0:
                    raise InputFileError(p, f"non-finite value {v!r}", i + 1, names[j])
                warnings.append(f"{p}: data row {i + 1}: non-finite {names[j]} kept as NaN")
                log.warning(warnings[-1])
            data[i, j] = v
    fs = _rate(p, meta)
    period = 1.0 / fs
    t = data[:, 0]
    step = np.diff(t)
    bad = np.flatnonzero(np.abs(step - period) > _TIME_JITTER * period)
    if bad.size:
        i = int(bad[0])
        msg = (f"time step {step[i]:.9g} s where 1/fs is {period:.9g} s ({bad.size} irregular "
               "steps)")
        if not lenient or np.any(step <= 0):
            raise InputFileError(p, msg, i + 2, "t")
        warnings.append(f"{p}: data row {i + 2}: {msg}")
        log.warning(warnings[-1])
    chans = [Channel(name=n, data=data[:, j + 1].copy(), unit=_unit(meta, k), role=role)
             for j, (n, k, role) in enumerate(cols)]
    return Recording(name=p.stem, fs_hz=float(fs), channels=chans, source=p,
                     sha256=file_sha256(p), warnings=warnings, t0_s=float(t[0]))
