"""Named arrays to a Recording: the one place the binary readers (UFF 58, MDF4, HDF5, MATLAB,
a pandas DataFrame) check what the text readers check row by row: equal lengths, numbers,
finite values, a time that increases regularly (or a given rate). Errors name the file and the
channel (and the sample, counted from 0, where there is one)."""
from __future__ import annotations

import gc
import logging
import mmap
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from dynval.errors import DynvalError, InputFileError
from dynval.io.recording import (
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    Channel,
    Recording,
    default_role,
    file_sha256,
    split_unit,
)

log = logging.getLogger(__name__)

TIME_JITTER = 1e-3  # sample clocks jitter by less than this fraction of a period in any DAQ file
TIME_NAMES = ("time", "time_s", "t", "timestamps", "timestamp")
RATE_NAMES = ("fs_hz", "fs", "Fs", "sampling_rate", "sample_rate", "sampling_rate_hz",
              "samplingrate")

T = TypeVar("T")


def one_line(exc: BaseException) -> str:
    """An exception of a third-party reader as one line (type and first line of the text)."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0][:200]}" if text else type(exc).__name__


def guarded(p: Path, what: str, read: Callable[[], T], quiet: tuple[str, ...] = ()) -> T:
    """Run a third-party reader; anything it raises on a damaged file (its own exceptions,
    ValueError, struct errors, ...) becomes one InputFileError naming the file. The loggers
    in `quiet` (the library's own, which logs its errors with a traceback before raising)
    are silenced meanwhile, and so are the errors of its half-built objects' destructors
    (asammdf's MDF4.__del__ on a damaged file): the one line is ours."""
    loggers = [logging.getLogger(n) for n in quiet]
    was = [lg.disabled for lg in loggers]
    hook = sys.unraisablehook
    sys.unraisablehook = _unraisable
    for lg in loggers:
        lg.disabled = True
    try:
        try:
            return read()
        except DynvalError:
            raise
        except MemoryError:
            failure = f"not a readable {what} file (it claims more data than fits in memory)"
        except OSError as exc:
            failure = ("no such file" if not p.is_file() else
                       f"not a readable {what} file ({one_line(exc)})")
        except Exception as exc:  # noqa: BLE001 - the boundary of a third-party parser
            failure = f"not a readable {what} file ({one_line(exc)})"
        gc.collect()  # the failed reader's objects go now, under the quiet hooks
    finally:
        sys.unraisablehook = hook
        for lg, w in zip(loggers, was, strict=True):
            lg.disabled = w
    raise InputFileError(p, failure)


def _unraisable(u: Any) -> None:
    log.debug("ignored in a reader's clean-up: %s: %s", type(u.exc_value).__name__, u.exc_value)


def regular_period(p: Path | str, t: np.ndarray, *, lenient: bool, warnings: list[str],
                   locate: Callable[[int], tuple[int | None, str]],
                   column: str | None = None) -> float:
    """The sample period of the time stamps t: increasing, a usable rate and regular within
    TIME_JITTER of a period (lenient=True counts irregular steps as a warning instead).
    locate(i) gives (line or None, where) of the i-th time stamp for the error message; column
    names the time's column in it. Every reader with time stamps checks them here."""
    if t.size < 2:
        raise InputFileError(p, f"needs at least 2 samples, found {t.size}")
    if not np.isfinite(t).all():
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        ln, where = locate(i)
        raise InputFileError(p, f"non-finite time {float(t[i])}{where}", ln, column)
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0])
        ln, where = locate(i + 1)
        raise InputFileError(p, f"time does not increase ({float(t[i])!r} then "
                             f"{float(t[i + 1])!r}){where}", ln, column)
    period = float(np.median(dt))
    if not MIN_RATE_HZ <= 1.0 / period <= MAX_RATE_HZ:
        ln, where = locate(0)
        raise InputFileError(p, f"time step {period:.9g} s is not a usable sample "
                             f"period{where}", ln, column)
    off = np.flatnonzero(np.abs(dt - period) > TIME_JITTER * period + 1e-12)
    if off.size:
        i = int(off[0])
        ln, where = locate(i + 1)
        msg = (f"irregular sampling: step {dt[i]:.9g} s where the period is {period:.9g} s "
               f"({off.size} irregular steps){where}")
        if not lenient:
            raise InputFileError(p, msg, ln, column)
        warnings.append(f"{p}{'' if ln is None else f':{ln}'}: {msg}")
        log.warning(warnings[-1])
    return period


def _sample(i: int) -> tuple[int | None, str]:
    return None, f" at sample {i}"


def usable_rate(p: Path | str, fs_hz: Any, where: str) -> float:
    """fs_hz as a rate in [MIN_RATE_HZ, MAX_RATE_HZ]: one real number (or its text); an array
    of several, a boolean or a complex number is no rate (its first value or real part would
    be a guess)."""
    a = np.asarray(fs_hz)
    v = a.reshape(-1)[0] if a.size == 1 else None
    try:
        if v is None or a.dtype.kind in "bcV" or isinstance(v, bool | np.bool_):
            raise TypeError
        fs = float(v.decode() if isinstance(v, bytes) else v)
    except (TypeError, ValueError, UnicodeDecodeError):
        raise InputFileError(p, f"{where}: the sampling rate is not one number "
                             f"({str(fs_hz)[:40]})") from None
    if not MIN_RATE_HZ <= fs <= MAX_RATE_HZ:
        raise InputFileError(p, f"{where}: {fs!r} Hz is not a usable sampling rate")
    return fs


def channel_array(p: Path | str, name: str, value: Any, n: int | None) -> np.ndarray:
    """A channel's samples as 1-D float64 (a (n, 1) or (1, n) column is one channel)."""
    try:
        a = np.asarray(value)
    except Exception as exc:  # noqa: BLE001 - arbitrary objects from a file
        raise InputFileError(p, f"not an array ({one_line(exc)})", column=name) from None
    if a.dtype.kind not in "biuf":
        raise InputFileError(p, f"not numeric samples (type {a.dtype})", column=name)
    if a.ndim > 1 and sum(k > 1 for k in a.shape) <= 1:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise InputFileError(p, f"expected one channel (a 1-D array), found shape {a.shape}",
                             column=name)
    if n is not None and a.size != n:
        raise InputFileError(p, f"{a.size} samples where the other channels have {n}",
                             column=name)
    return a.astype(np.float64, copy=False)


def recording_from_arrays(p: Path | str, name: str, columns: Mapping[str, Any], *,
                          units: Mapping[str, str] | None = None,
                          roles: Mapping[str, str] | None = None,
                          time: Any = None, fs_hz: float | None = None, t0_s: float = 0.0,
                          lenient: bool = False, source: Path | None = None) -> Recording:
    """A Recording of named equal-length channels, timed by `time` (checked for a regular
    rate) or by fs_hz. Units: `units` where given, else a unit suffix of the name (acc1_mps2),
    else none (a channel map can add them). Non-finite samples are an error, or with
    lenient=True kept as NaN (the core drops and counts them), counted in warnings."""
    if not columns:
        raise InputFileError(p, "no channels (numeric 1-D arrays) found")
    warnings: list[str] = []
    n: int | None = None
    t = None
    if time is not None:
        t = channel_array(p, "time", time, None)
        n = t.size
        fs = 1.0 / regular_period(p, t, lenient=lenient, warnings=warnings, locate=_sample)
        t0_s = float(t[0])
    elif fs_hz is None:
        raise InputFileError(p, "no time channel and no sampling rate: name a time channel "
                             f"({', '.join(TIME_NAMES)}) or give the rate")
    else:
        fs = usable_rate(p, fs_hz, "sampling rate")
    chans: list[Channel] = []
    for col, value in columns.items():
        a = channel_array(p, col, value, n)
        n = a.size
        bad = ~np.isfinite(a)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            msg = f"non-finite value {float(a[i])} at sample {i} ({int(bad.sum())} in the channel)"
            if not lenient:
                raise InputFileError(p, msg, column=col)
            a = np.where(bad, np.nan, a)
            warnings.append(f"{p} (column {col}): {msg}, kept as NaN (dropped and counted by "
                            "the core)")
            log.warning(warnings[-1])
        unit = checked_unit(p, col, (units or {}).get(col), warnings)
        role = (roles or {}).get(col) or default_role(col)
        if mapped(a):  # a mapped file stays mapped, not loaded (its checked pages let go)
            release_pages(a)
        else:
            a = np.array(a, dtype=np.float64)
        chans.append(Channel(name=col, data=a, unit=unit, role=role))
    if n is None or n < 2:
        raise InputFileError(p, f"needs at least 2 samples, found {n or 0}")
    src = source if source is not None else (Path(p) if isinstance(p, Path) else None)
    sha = file_sha256(src) if src is not None and src.is_file() else ""
    return Recording(name=name, fs_hz=fs, channels=chans, source=src, sha256=sha,
                     warnings=warnings, t0_s=t0_s)


def _unit_key(unit: str) -> str:
    u = unit.strip().lower().replace(" ", "").replace("**", "").replace("^", "")
    u = u.replace("\u00b2", "2").replace("\u00b5", "u").replace("\u03bc", "u")
    return _SAME_UNIT.get(u, u)


_SAME_UNIT = {"ms-2": "m/s2", "m/s/s": "m/s2", "m.s-2": "m/s2", "ue": "microstrain",
              "u\u03b5": "microstrain", "ustrain": "microstrain", "micron": "um"}


def checked_unit(p: Path | str, col: str, given: str | None, warnings: list[str]) -> str:
    """The channel's unit: the file's where it gives one, else the name's suffix. A file's
    unit that the suffix contradicts (acc1_mps2 in g) is kept and a counted warning: the
    numbers are in one of them, and a model in SI units would take them for m/s^2."""
    suffix = split_unit(col)[1]
    if given and suffix and _unit_key(given) != _unit_key(suffix):
        warnings.append(f"{p} (column {col}): the file gives the unit {given!r}, the name's "
                        f"suffix says {suffix!r}: {given!r} kept")
        log.warning(warnings[-1])
    return given or suffix


def _mmap_of(a: np.ndarray) -> mmap.mmap | None:
    b: Any = a
    while isinstance(b, np.ndarray):
        b = b.base
    if isinstance(b, memoryview):  # np.frombuffer's base
        b = b.obj
    return b if isinstance(b, mmap.mmap) else None


def mapped(a: np.ndarray) -> bool:
    """Whether a is a view of a memory-mapped file (the HDF5 reader's long records)."""
    return _mmap_of(a) is not None


def release_pages(a: np.ndarray) -> None:
    """Let go of the pages of a's mapped file that this process holds (they stay in the page
    cache; a later read maps them again): memory in use stays a block, not the record. Only
    for an array nothing has written to (its copy-on-write changes would be lost)."""
    mm = _mmap_of(a)
    if mm is not None and hasattr(mmap, "MADV_DONTNEED"):
        mm.madvise(mmap.MADV_DONTNEED)


def find_time(names: list[str]) -> str | None:
    """The time channel among names: the first whose lower-case name is a TIME_NAMES entry or
    starts with 'time'."""
    for n in names:
        low = n.lower()
        if low in TIME_NAMES or low.startswith("time"):
            return n
    return None
