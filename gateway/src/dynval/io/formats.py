"""Readers of the test engineers' data formats, each through that format's own library:
UFF 58 (pyuff), MDF 4 (asammdf), HDF5 (h5py), MATLAB .mat (scipy.io; v7.3 files are HDF5) and a
pandas DataFrame (the Python API). Units come from the file's metadata where it has them (UFF
axis labels, MDF channel units, HDF5 `unit`/`units` attributes, DataFrame.attrs['units']),
else from a unit suffix of the name; a channel map (io.channelmap) renames, scales and adds
units otherwise. The libraries are the optional extra `formats` (pip install 'dynval[formats]').

Layouts where the format leaves them open (HDF5, MATLAB): equal-length 1-D numeric arrays at
the top level (HDF5: or in the one group that holds them), one of them the time
(time, time_s, t, ...) or a scalar rate (fs_hz, fs, Fs, sampling_rate, ...; HDF5: also an
attribute of the file or the group)."""
from __future__ import annotations

import importlib
import logging
import mmap
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import ConfigError, InputFileError
from dynval.io.arrays import (
    RATE_NAMES,
    TIME_JITTER,
    find_time,
    guarded,
    one_line,
    recording_from_arrays,
    usable_rate,
)
from dynval.io.recording import Recording

log = logging.getLogger(__name__)

UFF_SUFFIXES = (".uff", ".unv")
MDF_SUFFIXES = (".mf4", ".mdf")
HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf")
MAT_SUFFIXES = (".mat",)
SUFFIXES = UFF_SUFFIXES + MDF_SUFFIXES + HDF5_SUFFIXES + MAT_SUFFIXES
_MAX_SAMPLES = 1 << 31  # a header claiming more is damaged (16 GiB of float64 per channel)

# UFF 58 record 8 "specific data type" of the ordinate: 13 excitation force is an input
_UFF_INPUT_TYPES = {13}
_UFF_DIRS = {1: "x", 2: "y", 3: "z", -1: "-x", -2: "-y", -3: "-z", 4: "rx", 5: "ry", 6: "rz"}


def _need(p: Path, module: str, package: str) -> Any:
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputFileError(p, f"reading this format needs the {package} package: pip install "
                             f"'dynval[formats]'") from None


def _label(v: Any) -> str:
    s = str(v).strip()
    return "" if s.upper() == "NONE" else s


# ---- UFF 58 ------------------------------------------------------------------------------------
def read_uff(path: Path | str, *, lenient: bool = False) -> Recording:
    """Time histories of a universal file (dataset 58, function type 1 'time response'), one
    channel per dataset: named by id1 (else node and direction), unit from the ordinate's axis
    label, an excitation force (specific data type 13) as the input. All datasets must share
    the abscissa (start, increment, length)."""
    p = Path(path)
    pyuff = _need(p, "pyuff", "pyuff")

    def sets() -> list[dict[str, Any]]:
        u = pyuff.UFF(str(p))
        types = [int(x) for x in np.atleast_1d(u.get_set_types())]
        idx = [i for i, t in enumerate(types) if t == 58]
        if not idx:
            raise InputFileError(p, "no dataset 58 (function at nodal DOF) in the universal "
                                 f"file (datasets: {sorted(set(types)) or 'none'})")
        lines = _check_uff_blocks(p)
        return [_uff_set(p, u, i, lines[i]) for i in idx]

    dsets = guarded(p, "universal (UFF 58)", sets, quiet=("pyuff",))
    cols: dict[str, Any] = {}
    units: dict[str, str] = {}
    roles: dict[str, str] = {}
    notes: list[str] = []
    skipped: list[str] = []
    ref: tuple[float, float, int] | None = None
    for k, d in enumerate(dsets):
        try:
            func, x0, dx = int(d["func_type"]), float(d["abscissa_min"]), float(d["abscissa_inc"])
            data, npts = d["data"], int(d["num_pts"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputFileError(p, f"dataset 58 #{k + 1} is incomplete ({one_line(exc)})") \
                from None
        if func != 1:  # (a spectrum or FRF beside the time histories)
            skipped.append(f"dataset 58 #{k + 1} (function type {func}, not a time response)")
            continue
        if np.iscomplexobj(data):
            raise InputFileError(p, f"dataset 58 #{k + 1}: complex ordinates in a time response")
        name = _label(d.get("id1", "")) or \
            f"node{d.get('rsp_node', k + 1)}{_UFF_DIRS.get(int(d.get('rsp_dir', 0)), '')}"
        if npts != np.size(data):  # pyuff reads the values there are, whatever the header says
            raise InputFileError(p, f"dataset 58 #{k + 1} ({name}): the header gives {npts} "
                                 f"points, the data {np.size(data)} (truncated or damaged)")
        _check_uneven(p, d, k, name)
        if name in cols:
            notes.append(_renamed(p, name, f"{name}_{k + 1}", f"dataset 58 #{k + 1}"))
            name = f"{name}_{k + 1}"
        this = (x0, dx, int(np.size(data)))
        if ref is None:
            ref = this
        elif not np.allclose(this[:2], ref[:2], rtol=1e-9, atol=0) or this[2] != ref[2]:
            raise InputFileError(p, f"dataset 58 #{k + 1} ({name}): abscissa start {x0!r} s, "
                                 f"step {dx!r} s, {this[2]} points differ from the first "
                                 f"dataset's {ref[0]!r} s, {ref[1]!r} s, {ref[2]}")
        cols[name] = data
        units[name] = _label(d.get("ordinate_axis_units_lab", ""))
        if int(d.get("ordinate_spec_data_type", 0)) in _UFF_INPUT_TYPES:
            roles[name] = "input"
    if ref is None:
        raise InputFileError(p, "no time response (dataset 58 with function type 1) in the file")
    if not ref[1] > 0:
        raise InputFileError(p, f"abscissa increment {ref[1]!r} s is not a sample period")
    rec = recording_from_arrays(p, p.stem, cols, units=units, roles=roles, fs_hz=1.0 / ref[1],
                                t0_s=ref[0], lenient=lenient)
    rec.warnings[:0] = notes
    return _notes(p, rec, skipped, None)


def _renamed(p: Path, name: str, new: str, where: str) -> str:
    """A channel whose name another one has already: kept as `new`, a counted warning (the
    first of the name is the one a model's channel of that name gets)."""
    msg = f"{p}: {where}: a second channel named {name!r}, read as {new!r}"
    log.warning(msg)
    return msg


def _uff_tags(data: bytes) -> list[int]:
    """The offsets of the '    -1' delimiter lines as pyuff finds them (followed by a line end,
    the file's end or blanks to column 80); pyuff pairs them into datasets."""
    out, i = [], data.find(b"    -1")
    while i != -1:
        end = data[i + 6:i + 7]
        if not end or end in (b"\n", b"\r") or (
                i + 80 < len(data) and data[i + 6:i + 80] == b" " * 74):
            out.append(i)
        i = data.find(b"    -1", i + 1)
    return out


def _check_uff_blocks(p: Path) -> list[int]:
    """The first line of each dataset. pyuff pairs the '    -1' lines and passes over a pair
    without a dataset number and an unpaired last line: a truncated file, or one whose
    delimiter was damaged, would lose channels without a word."""
    data = p.read_bytes()
    tags = _uff_tags(data)
    lines, ln = [], 1
    for a, b in zip([0, *tags], tags, strict=False):  # counted tag to tag: a long file's once
        ln += data.count(b"\n", a, b)
        lines.append(ln)
    for a, b, ln in zip(tags[::2], tags[1::2], lines[::2], strict=False):
        head = data[a:b].splitlines()
        if len(head) < 2 or not head[1][:6].strip().lstrip(b"-").isdigit():
            raise InputFileError(p, f"line {ln + 1}: no dataset number after the '    -1' line "
                                 "(a dataset not closed, or a damaged file)")
    if len(tags) % 2 or (tags and data[tags[-1] + 6:].strip()):
        raise InputFileError(p, f"line {lines[-1] + 1}: a dataset that is not closed by a "
                             "'    -1' line (the file is truncated or damaged)")
    return lines[::2]


def _uff_set(p: Path, u: Any, i: int, line: int) -> dict[str, Any]:
    """Dataset i of the file, an error naming it and its line where pyuff cannot read it."""
    try:
        d = u.read_sets(i)
    except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exceptions, its cause inside
        cause: BaseException = exc
        while cause.__context__ is not None:
            cause = cause.__context__
        raise InputFileError(p, f"line {line}: dataset #{i + 1} is not a readable dataset 58 "
                             f"({one_line(cause)})") from None
    return d if isinstance(d, dict) else {}


def _check_uneven(p: Path, d: dict[str, Any], k: int, name: str) -> None:
    """An uneven abscissa (spacing 0) gives a time per point: with an increment in the header
    (which the channel is read at) they must agree, within the jitter and the 6 digits of
    the file's abscissa values. Without one the increment's check refuses the dataset."""
    dx = float(d["abscissa_inc"])
    if int(d.get("abscissa_spacing", 1)) != 0 or not dx > 0:
        return
    x = np.asarray(d.get("x"), dtype=np.float64)
    grid = float(d["abscissa_min"]) + dx * np.arange(x.size)
    off = np.flatnonzero(~(np.abs(x - grid) <= TIME_JITTER * dx + 5e-6 * np.abs(grid)))
    if off.size:
        i = int(off[0])
        raise InputFileError(p, f"dataset 58 #{k + 1} ({name}): uneven abscissa: point {i} "
                             f"at {float(x[i])!r} s, not at {float(grid[i])!r} s (the "
                             "header's start + increment)")


# ---- MDF 4 -------------------------------------------------------------------------------------
def read_mdf(path: Path | str, *, lenient: bool = False) -> Recording:
    """The channels of an MDF file (asammdf) that share the time base of the first data
    channel, with the units the file gives them; channels on another time base (another
    rate or a bus log) or not numeric are left out and a counted warning. Samples the file
    marks invalid (invalidation bits) are an error, or with lenient=True missing (NaN)."""
    p = Path(path)
    asammdf = _need(p, "asammdf", "asammdf")

    def signals() -> list[Any]:
        with asammdf.MDF(str(p)) as mdf:
            out = []
            for gi, group in enumerate(mdf.groups):
                master = mdf.masters_db.get(gi)
                for ci in range(len(group.channels)):
                    if ci == master:
                        continue
                    out.append(mdf.get(group=gi, index=ci, raw=False,
                                       ignore_invalidation_bits=True))
            return out

    sigs = guarded(p, "MDF", signals, quiet=("asammdf",))
    nums = [s for s in sigs if np.asarray(s.samples).dtype.kind in "biuf"
            and np.asarray(s.samples).ndim == 1]
    left = [f"{s.name} ({_kind(np.asarray(s.samples).dtype)})" for s in sigs
            if not any(s is k for k in nums)]
    if not nums:
        raise InputFileError(p, "no numeric channels in the MDF file")
    t = np.asarray(nums[0].timestamps, dtype=np.float64)
    same = [s for s in nums if np.asarray(s.timestamps).shape == t.shape  # NaN: time's error
            and np.array_equal(np.asarray(s.timestamps, dtype=np.float64), t, equal_nan=True)]
    left += [f"{s.name} (on another time base than {nums[0].name})" for s in nums
             if not any(s is k for k in same)]
    cols: dict[str, Any] = {}
    units: dict[str, str] = {}
    notes: list[str] = []
    for s in same:
        name = s.name
        if name in cols:
            where = f"group {getattr(s, 'group_index', '?')}"
            notes.append(_renamed(p, name, f"{name}_{len(cols)}", where))
            name = f"{name}_{len(cols)}"
        cols[name] = _mdf_valid(p, s, name, lenient)
        units[name] = str(s.unit or "")
    rec = recording_from_arrays(p, p.stem, cols, units=units, time=t, lenient=lenient)
    rec.warnings[:0] = notes
    return _notes(p, rec, left, None)


def _mdf_valid(p: Path, s: Any, name: str, lenient: bool) -> np.ndarray:
    """A channel's samples; those its invalidation bits mark are an error, or with lenient
    NaN (missing, counted as the other readers' non-finite samples are)."""
    a = np.asarray(s.samples)
    inv = getattr(s, "invalidation_bits", None)
    bad = np.zeros(a.shape, dtype=bool) if inv is None else np.asarray(inv, dtype=bool)
    if not bad.any():
        return a
    if not lenient:
        raise InputFileError(p, f"sample {int(np.flatnonzero(bad)[0])} is marked invalid "
                             f"({int(bad.sum())} in the channel; --lenient reads them as "
                             "missing)", column=name)
    return np.where(bad, np.nan, a.astype(np.float64))


# ---- HDF5 --------------------------------------------------------------------------------------
def _attr_text(v: Any) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.size == 1:
        return _attr_text(v.reshape(-1)[0])
    return str(v)


def _mapped(p: Path, d: Any) -> np.ndarray:
    """A dataset stored contiguously and uncompressed, memory-mapped copy-on-write (its pages are
    read as they are used, so a long record is not loaded: arrays.release_pages); any other
    read into memory."""
    off = d.id.get_offset()
    if d.chunks is None and off is not None and d.dtype.kind == "f" and not d.external:
        start = off - off % mmap.ALLOCATIONGRANULARITY
        with open(p, "rb") as fh:
            mm = mmap.mmap(fh.fileno(), off - start + d.size * d.dtype.itemsize,
                           access=mmap.ACCESS_COPY, offset=start)
        return np.frombuffer(mm, dtype=d.dtype, count=d.size, offset=off - start
                             ).reshape(d.shape)
    return np.asarray(d[()])


def read_hdf5(path: Path | str, *, lenient: bool = False) -> Recording:
    """Equal-length 1-D datasets of an HDF5 file (the root's, or else of the one group that
    holds such datasets), timed by a time dataset or a rate (a scalar dataset or an attribute
    of the file or group, RATE_NAMES). Units from each dataset's `unit` or `units` attribute.
Contiguous float datasets are memory-mapped (_mapped). What is not read as a channel (another
group's datasets, a complex, text or empty dataset, a broken link) is a counted warning."""
    p = Path(path)
    h5py = _need(p, "h5py", "h5py")

    def load() -> tuple[dict[str, Any], dict[str, str], Any, Any, list[str]]:
        with h5py.File(p, "r") as f:
            g, dsets, left = _h5_group(p, h5py, f)
            for k, v in dsets.items():
                if v.size > _MAX_SAMPLES:
                    raise InputFileError(p, f"{v.size} samples in one dataset", column=k)
                _h5_written(p, v, k)
            rate = None
            for src in (g.attrs, f.attrs):
                rate = next((src[k] for k in RATE_NAMES if k in src), None)
                if rate is not None:
                    break
            if rate is None:
                rate = next((g[k][()] for k in RATE_NAMES if k in g and
                             isinstance(g[k], h5py.Dataset) and g[k].size == 1), None)
            tname = find_time(list(dsets))
            time = dsets.pop(tname)[()] if tname is not None else None
            cols = {k: _mapped(p, v) for k, v in dsets.items()}
            units = {k: _attr_text(v.attrs.get("unit", v.attrs.get("units", "")))
                     for k, v in dsets.items()}
            return cols, units, time, rate, left

    cols, units, time, rate, left = guarded(p, "HDF5", load)
    fs = None if time is not None or rate is None else usable_rate(p, rate, "rate attribute")
    rec = recording_from_arrays(p, p.stem, cols, units=units, time=time, fs_hz=fs,
                                lenient=lenient)
    return _notes(p, rec, left, rate if time is not None else None)


def _h5_group(p: Path, h5py: Any, f: Any) -> tuple[Any, dict[str, Any], list[str]]:
    """The group read (the root, else the first top-level group with channel datasets), its
    channel datasets, and what is left out: its other arrays and the other groups' channels."""
    found = [(g, *_h5_split(h5py, g)) for g in
             [f] + [g for g in f.values() if isinstance(g, h5py.Group)]]
    with_data = [x for x in found if x[1]]
    if not with_data:
        raise InputFileError(p, "no numeric 1-D datasets in the HDF5 file (at the root or in "
                             "a group)")
    g, dsets, left = with_data[0]
    left = left + [f"group {o.name} ({len(d)} datasets)" for o, d, _ in with_data[1:]]
    return g, dsets, left


def _h5_split(h5py: Any, g: Any) -> tuple[dict[str, Any], list[str]]:
    """The numeric datasets of more than one sample in g, and its other arrays with why they
    are not read; a scalar or one-value dataset (a rate, a gain) is no channel."""
    dsets: dict[str, Any] = {}
    left: list[str] = []
    for k in g:
        v = g.get(k)
        if v is None:
            left.append(f"{k} (a broken link)")
        elif not isinstance(v, h5py.Dataset) or v.shape is None \
                or _attr_text(v.attrs.get("MATLAB_class", "")) == "char":  # v7.3 text: uint16
            continue
        elif v.size == 1 or not v.shape:  # a rate, a gain: or a channel cut to one sample
            if k not in RATE_NAMES and v.dtype.kind in "biuf":
                left.append(f"{k} (one value)")
        elif v.attrs.get("MATLAB_empty", 0):  # a v7.3 empty variable: its dimensions stored
            left.append(f"{k} (no samples)")
        elif v.dtype.kind in "biuf" and v.size > 1:
            dsets[k] = v
        else:
            left.append(f"{k} ({'no samples' if v.size == 0 else _kind(v.dtype)})")
    return dsets, left


def _kind(dtype: Any) -> str:
    return {"c": "complex", "S": "text", "U": "text", "O": "text or objects",
            "V": "compound"}.get(dtype.kind, f"type {dtype}")


def _h5_written(p: Path, v: Any, name: str) -> None:
    """A dataset created but never (or only partly) written, by a writer that stopped: its
    unwritten samples read as the fill value (zeros), numbers that were never measured."""
    if v.is_virtual or v.external:
        return
    status = v.id.get_space_status()
    if status != 2:  # h5d.SPACE_STATUS_ALLOCATED (1: partly, 0: not at all)
        raise InputFileError(p, f"the dataset was {'only partly' if status else 'never'} "
                             "written (a stopped writer?): its unwritten samples read as the "
                             "fill value", column=name)


def _notes(p: Path, rec: Recording, left: list[str], rate: Any) -> Recording:
    """Counted warnings: the file's arrays that are not read as channels (a channel of a type
    the reader passes over must not go without a word), and a rate that the time channel,
    which is used, contradicts."""
    notes = [f"{p}: not read as channels: {', '.join(left)}"] if left else []
    if rate is not None:
        try:
            fs: float | None = usable_rate(p, rate, "rate")
        except InputFileError:
            fs = None
        if fs is None or abs(fs - rec.fs_hz) > TIME_JITTER * rec.fs_hz:
            notes.append(f"{p}: the file's rate {str(rate)[:40]} is not its time channel's "
                         f"{rec.fs_hz:.9g} Hz: the time channel is used")
    for n in notes:
        log.warning(n)
    rec.warnings.extend(notes)
    return rec


# ---- MATLAB ------------------------------------------------------------------------------------
def read_mat(path: Path | str, *, lenient: bool = False) -> Recording:
    """The equal-length numeric vectors of a MATLAB .mat file (v4 to v7; a v7.3 file is HDF5
    and read as such), timed by a time vector or a scalar rate variable (RATE_NAMES). A
    MATLAB file holds no units: a `units` struct (field per variable) gives them, else a
    channel map. Variables not read as channels (complex, text, cells, structs, sparse, empty)
    are a counted warning."""
    p = Path(path)
    sio = _need(p, "scipy.io", "scipy")
    try:
        with open(p, "rb") as fh:
            head = fh.read(128)
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from None
    if head[:8] == b"\x89HDF\r\n\x1a\n" or b"MATLAB 7.3" in head:
        return read_hdf5(p, lenient=lenient)

    def load() -> dict[str, Any]:
        d: dict[str, Any] = sio.loadmat(str(p), squeeze_me=True, struct_as_record=False)
        # loadmat gives a logical as uint8 (true: 1), and a rate variable `fs = true` would
        # read as 1 Hz: its class is in the file's directory (read again: only with a rate)
        rates = [k for k in RATE_NAMES if k in d]
        for name, _, cls in sio.whosmat(str(p)) if rates else ():
            if cls == "logical" and name in rates:  # (squeezed, one value is a Python int)
                d[name] = np.asarray(d[name]).astype(bool)
        return d

    d = guarded(p, "MATLAB", load)
    units: dict[str, str] = {}
    u = d.get("units")
    if u is not None and hasattr(u, "_fieldnames"):
        units = {k: str(getattr(u, k)) for k in u._fieldnames}
    vecs = {k: v for k, v in d.items() if not k.startswith("__") and isinstance(v, np.ndarray)
            and v.dtype.kind in "biuf" and v.ndim >= 1 and v.size > 1}
    left = [f"{k} ({_mat_kind(v)})" for k, v in d.items() if k not in vecs and
            not k.startswith("__") and k not in ("units", *RATE_NAMES) and _mat_kind(v)]
    rate = next((d[k] for k in RATE_NAMES if k in d and np.size(d[k]) == 1), None)
    if not vecs:
        raise InputFileError(p, "no numeric vectors in the MATLAB file")
    tname = find_time(list(vecs))
    time = vecs.pop(tname) if tname is not None else None
    fs = None if time is not None or rate is None else usable_rate(p, rate, "rate variable")
    rec = recording_from_arrays(p, p.stem, vecs, units=units, time=time, fs_hz=fs,
                                lenient=lenient)
    return _notes(p, rec, left, rate if time is not None else None)


def _mat_kind(v: Any) -> str:
    """Why a MATLAB variable is not a channel ('' for a string: no channel). One number (a
    gain, or a channel cut to one sample: loadmat gives it as a scalar) is named, as every
    variable not read; a rate variable is left out by the caller."""
    if isinstance(v, int | float | complex | np.number):
        return "one value"
    if isinstance(v, np.ndarray):
        if v.size == 0:
            return "no samples"
        if v.size == 1:  # a rate, a gain: or a channel cut to one sample
            return "one value" if v.dtype.kind in "biuf" else ""
        return "a cell array" if v.dtype.kind == "O" else _kind(v.dtype)
    if hasattr(v, "_fieldnames"):
        return "a struct"
    return "a sparse matrix" if hasattr(v, "tocsr") else ""


# ---- pandas ------------------------------------------------------------------------------------
def read_dataframe(df: Any, *, name: str = "dataframe", fs_hz: float | None = None,
                   time_column: str | None = None, units: dict[str, str] | None = None,
                   lenient: bool = False) -> Recording:
    """A pandas DataFrame as a Recording (the Python API): one column per channel, timed by
    time_column, else a time column (time, time_s, t, ...), else a numeric, timedelta or
    datetime index (not a plain 0..n-1 RangeIndex), else fs_hz (which, when given, sets the
    rate even with a time column: that column then gives the start time only). Units from
    `units`, else df.attrs['units'] (a dict), else a unit suffix of the column name."""
    try:
        pd = importlib.import_module("pandas")
    except ImportError:
        raise ConfigError("read_dataframe needs pandas: pip install 'dynval[formats]'") from None
    if not isinstance(df, pd.DataFrame):
        raise ConfigError(f"read_dataframe needs a pandas DataFrame, got {type(df).__name__}")
    cols = {str(c): df[c].to_numpy() for c in df.columns}
    if len(cols) != len(df.columns):
        raise ConfigError(f"{name}: duplicate column names")
    time = None
    t0 = 0.0
    tname = time_column if time_column is not None else find_time(list(cols))
    if tname is not None:
        if tname not in cols:
            raise ConfigError(f"{name}: no column '{tname}' (have {', '.join(cols)})")
        time = cols.pop(tname)
        if fs_hz is not None:  # the given rate wins; the time column gives the start only
            t0 = float(np.asarray(time, dtype=np.float64)[0]) if len(time) else 0.0
            time = None
    elif fs_hz is None and not isinstance(df.index, pd.RangeIndex):
        idx = df.index
        if isinstance(idx, pd.DatetimeIndex | pd.TimedeltaIndex):
            time = (idx - idx[0]).total_seconds().to_numpy()
        elif idx.dtype.kind in "iuf":
            time = idx.to_numpy()
    attrs_units = df.attrs.get("units") if isinstance(df.attrs.get("units"), dict) else {}
    merged = {**{str(k): str(v) for k, v in attrs_units.items()}, **(units or {})}
    return recording_from_arrays(name, name, cols, units=merged, time=time, fs_hz=fs_hz,
                                 t0_s=t0, lenient=lenient)
