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
import re
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import ConfigError, InputFileError
from dynval.io.arrays import (
    RATE_NAMES,
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
# a dataset's start and end delimiter: a line '    -1'
_UFF_TAG = re.compile(rb"^    -1[ \t]*\r?$", re.MULTILINE)


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
        _check_uff_closed(p)
        out = u.read_sets(idx)
        return out if isinstance(out, list) else [out]

    dsets = guarded(p, "universal (UFF 58)", sets, quiet=("pyuff",))
    cols: dict[str, Any] = {}
    units: dict[str, str] = {}
    roles: dict[str, str] = {}
    ref: tuple[float, float, int] | None = None
    for k, d in enumerate(dsets):
        try:
            func, x0, dx = int(d["func_type"]), float(d["abscissa_min"]), float(d["abscissa_inc"])
            data = d["data"]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputFileError(p, f"dataset 58 #{k + 1} is incomplete ({one_line(exc)})") \
                from None
        if func != 1:
            log.info("%s: dataset 58 #%d is function type %d, not a time response: skipped",
                     p, k + 1, func)
            continue
        if np.iscomplexobj(data):
            raise InputFileError(p, f"dataset 58 #{k + 1}: complex ordinates in a time response")
        name = _label(d.get("id1", "")) or \
            f"node{d.get('rsp_node', k + 1)}{_UFF_DIRS.get(int(d.get('rsp_dir', 0)), '')}"
        if name in cols:
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
    return recording_from_arrays(p, p.stem, cols, units=units, roles=roles, fs_hz=1.0 / ref[1],
                                 t0_s=ref[0], lenient=lenient)


def _check_uff_closed(p: Path) -> None:
    """pyuff reads what lies between pairs of '    -1' lines and ignores an unclosed last
    dataset: a truncated file would lose its last channels without a word."""
    data = p.read_bytes()
    last = None
    for tag in _UFF_TAG.finditer(data):
        last = tag
    if last is not None and data[last.end():].strip():
        line = data.count(b"\n", 0, last.end()) + 2
        raise InputFileError(p, f"line {line}: a dataset that is not closed by a '    -1' line "
                             "(the file is truncated or damaged)")


# ---- MDF 4 -------------------------------------------------------------------------------------
def read_mdf(path: Path | str, *, lenient: bool = False) -> Recording:
    """The channels of an MDF file (asammdf) that share the time base of the first data
    channel, with the units the file gives them; channels on another time base (another
    rate or a bus log) are left out and reported."""
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
                    out.append(mdf.get(group=gi, index=ci, raw=False))
            return out

    sigs = guarded(p, "MDF", signals, quiet=("asammdf",))
    sigs = [s for s in sigs if np.asarray(s.samples).dtype.kind in "biuf"
            and np.asarray(s.samples).ndim == 1]
    if not sigs:
        raise InputFileError(p, "no numeric channels in the MDF file")
    t = np.asarray(sigs[0].timestamps, dtype=np.float64)
    same = [s for s in sigs if np.asarray(s.timestamps).shape == t.shape
            and np.array_equal(np.asarray(s.timestamps, dtype=np.float64), t)]
    left = [s.name for s in sigs if not any(s is k for k in same)]
    if left:
        log.warning("%s: channels on another time base than %s left out: %s", p, sigs[0].name,
                    ", ".join(left))
    cols: dict[str, Any] = {}
    units: dict[str, str] = {}
    for s in same:
        name = s.name if s.name not in cols else f"{s.name}_{len(cols)}"
        cols[name] = np.asarray(s.samples)
        units[name] = str(s.unit or "")
    return recording_from_arrays(p, p.stem, cols, units=units, time=t, lenient=lenient)


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
Contiguous float datasets are memory-mapped (_mapped)."""
    p = Path(path)
    h5py = _need(p, "h5py", "h5py")

    def load() -> tuple[dict[str, Any], dict[str, str], Any, Any]:
        with h5py.File(p, "r") as f:
            groups = [f] + [g for g in f.values() if isinstance(g, h5py.Group)]
            for g in groups:
                dsets = {k: v for k, v in g.items() if isinstance(v, h5py.Dataset)
                         and v.dtype.kind in "biuf" and len(v.shape) >= 1 and v.size > 1}
                if dsets:
                    break
            else:
                raise InputFileError(p, "no numeric 1-D datasets in the HDF5 file (at the root "
                                     "or in a group)")
            for k, v in dsets.items():
                if v.size > _MAX_SAMPLES:
                    raise InputFileError(p, f"{v.size} samples in one dataset", column=k)
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
            return cols, units, time, rate

    cols, units, time, rate = guarded(p, "HDF5", load)
    fs = None if time is not None or rate is None else usable_rate(p, rate, "rate attribute")
    return recording_from_arrays(p, p.stem, cols, units=units, time=time, fs_hz=fs,
                                 lenient=lenient)


# ---- MATLAB ------------------------------------------------------------------------------------
def read_mat(path: Path | str, *, lenient: bool = False) -> Recording:
    """The equal-length numeric vectors of a MATLAB .mat file (v4 to v7; a v7.3 file is HDF5
    and read as such), timed by a time vector or a scalar rate variable (RATE_NAMES). A
    MATLAB file holds no units: a `units` struct (field per variable) gives them, else a
    channel map."""
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
        return d

    d = guarded(p, "MATLAB", load)
    units: dict[str, str] = {}
    u = d.get("units")
    if u is not None and hasattr(u, "_fieldnames"):
        units = {k: str(getattr(u, k)) for k in u._fieldnames}
    vecs = {k: v for k, v in d.items() if not k.startswith("__") and isinstance(v, np.ndarray)
            and v.dtype.kind in "biuf" and v.ndim >= 1 and v.size > 1}
    rate = next((d[k] for k in RATE_NAMES if k in d and np.size(d[k]) == 1), None)
    if not vecs:
        raise InputFileError(p, "no numeric vectors in the MATLAB file")
    tname = find_time(list(vecs))
    time = vecs.pop(tname) if tname is not None else None
    fs = None if time is not None or rate is None else usable_rate(p, rate, "rate variable")
    return recording_from_arrays(p, p.stem, vecs, units=units, time=time, fs_hz=fs,
                                 lenient=lenient)


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
