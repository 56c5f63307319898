"""Waveform features over numpy arrays, computed by the C core (dv_moments, dv_sliding,
dv_segstd, dv_temporal, dv_corr, dv_chan): the same numbers the firmware produces."""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from dynval._core import DV_RECORD, check, ffi, lib, ptr
from dynval._core import as_doubles as _as_doubles

STATS_NO_SHAPE = 0x1
STATS_NO_CREST = 0x2


@dataclass(frozen=True)
class Stats:
    """Basic statistics (report Table 15, eq. 11-12); population moments, kurtosis 3 = Gaussian."""

    count: int
    mean: float
    var: float
    std: float
    rms: float
    skew: float
    kurt: float
    peak: float
    min: float
    max: float
    crest: float
    kfactor: float
    flags: int

    @property
    def shape_defined(self) -> bool:
        """False for a constant signal: skew and kurt are then reported as 0."""
        return not self.flags & STATS_NO_SHAPE

    @property
    def crest_defined(self) -> bool:
        """False for an all-zero signal: crest is then reported as 0."""
        return not self.flags & STATS_NO_CREST

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class Temporal:
    """Temporal moments (report eq. 14-16, Table 16); times in s from the first sample."""

    energy: float
    central_time: float
    rms_duration: float
    central_skew: float
    central_kurt: float
    root_energy_amp: float
    count: int

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def as_doubles(x: Any) -> np.ndarray:
    """One channel as contiguous float64. A 2-D array is refused rather than flattened (its
    channels would run into one another): pass one column, or numpy.apply_along_axis."""
    shape = np.shape(x)
    if len(shape) > 1 and sum(n > 1 for n in shape) > 1:
        raise ValueError(f"features take one channel (a 1-D array), got shape {shape}: pass "
                         "x[:, j], or numpy.apply_along_axis(f, axis, x) for each channel")
    return _as_doubles(x)


def _stats(c: Any) -> Stats:
    return Stats(int(c.count), c.mean, c.var, c.std, c.rms, c.skew, c.kurt, c.peak, c.min, c.max,
                 c.crest, c.kfactor, int(c.flags))


def _temporal(c: Any) -> Temporal:
    return Temporal(c.energy, c.central_time, c.rms_duration, c.central_skew, c.central_kurt,
                    c.root_energy_amp, int(c.count))


def moments(x: Any) -> Stats:
    """Statistics of the whole array (NaN/Inf samples are dropped; see nonfinite_count)."""
    a = as_doubles(x)
    s = ffi.new("dv_moments_t *")
    check(lib.dv_moments_init(s), "dv_moments_init")
    lib.dv_moments_update_block(s, ptr(a), a.size)
    out = ffi.new("dv_stats_t *")
    check(lib.dv_moments_get(s, out), "dv_moments_get")
    return _stats(out)


def sliding(x: Any, win_len: int) -> Stats:
    """Statistics of the last win_len samples, computed by the streaming window."""
    a = as_doubles(x)
    s = ffi.new("dv_sliding_t *")
    blen = max(int(lib.dv_sliding_buf_len(win_len)), 1)  # 0 for a bad length: init says why
    buf = ffi.new("double[]", blen)
    check(lib.dv_sliding_init(s, win_len, buf, blen), "dv_sliding_init")
    lib.dv_sliding_update_block(s, ptr(a), a.size)
    out = ffi.new("dv_stats_t *")
    check(lib.dv_sliding_get(s, out), "dv_sliding_get")
    return _stats(out)


def sliding_series(x: Any, win_len: int, every: int = 1) -> dict[str, np.ndarray]:
    """Window RMS, peak, crest, STD after every `every` samples (NaN until the window is full)."""
    a = as_doubles(x)
    s = ffi.new("dv_sliding_t *")
    blen = max(int(lib.dv_sliding_buf_len(win_len)), 1)  # 0 for a bad length: init says why
    buf = ffi.new("double[]", blen)
    check(lib.dv_sliding_init(s, win_len, buf, blen), "dv_sliding_init")
    n_out = a.size // every
    res = {k: np.full(n_out, np.nan) for k in ("rms", "peak", "crest", "std")}
    out = ffi.new("dv_stats_t *")
    p = ptr(a)
    for j in range(n_out):
        lib.dv_sliding_update_block(s, p + j * every, every)
        if lib.dv_sliding_get(s, out) == 0:
            res["rms"][j], res["peak"][j], res["std"][j] = out.rms, out.peak, out.std
            res["crest"][j] = out.crest if not out.flags & STATS_NO_CREST else np.nan
    return res


def segstd(x: Any, seg_len: int = 64, n_seg: int | None = None) -> np.ndarray:
    """STD of each consecutive segment of seg_len samples over one record of n_seg segments
    (default: as many whole segments as x holds); with more samples, the last whole record.
    NaN/Inf samples are dropped, as the core drops them. The core's arithmetic (sums of the
    samples less each segment's first, added in order) vectorised in numpy: bit-identical to
    dv_segstd."""
    a = as_doubles(x)
    a = a[np.isfinite(a)]
    n_seg = a.size // seg_len if n_seg is None else n_seg
    if seg_len < 2 or n_seg < 1:
        raise ValueError(f"segstd needs at least one segment of {seg_len} >= 2 samples, "
                         f"got {a.size}")
    rec = seg_len * n_seg
    k = a.size // rec
    if k == 0:
        raise ValueError(f"segstd needs a record of {n_seg} x {seg_len} samples, got {a.size}")
    seg = a[(k - 1) * rec: k * rec].reshape(n_seg, seg_len)
    with np.errstate(over="ignore", invalid="ignore"):  # Inf/NaN as the core gives them
        d = np.ascontiguousarray((seg - seg[:, :1]).T)  # (seg_len, n_seg): rows added in order
        s1 = np.cumsum(d, axis=0)[-1]  # cumsum adds in order, as the core does (sum: pairwise)
        s2 = np.cumsum(d * d, axis=0)[-1]
        n = float(seg_len)
        var = (s2 - s1 * s1 / n) / n
        return np.asarray(np.sqrt(np.where(var > 0.0, var, 0.0)), dtype=np.float64)


def temporal(x: Any, dt_s: float) -> Temporal:
    """Temporal moments of the whole array as one record with sample period dt_s."""
    a = as_doubles(x)
    s = ffi.new("dv_temporal_t *")
    check(lib.dv_temporal_init(s, dt_s), "dv_temporal_init")
    lib.dv_temporal_update_block(s, ptr(a), a.size)
    out = ffi.new("dv_temporal_out_t *")
    check(lib.dv_temporal_get(s, out), "dv_temporal_get")
    return _temporal(out)


def corr(x: Any, y: Any) -> float:
    """Correlation coefficient of two equally long channels (eq. 21)."""
    a, b = as_doubles(x), as_doubles(y)
    if a.size != b.size:
        raise ValueError(f"corr needs equal lengths, got {a.size} and {b.size}")
    s = ffi.new("dv_corr_t *")
    check(lib.dv_corr_init(s), "dv_corr_init")
    for u, v in zip(a.tolist(), b.tolist(), strict=True):
        lib.dv_corr_update(s, u, v)
    r = ffi.new("double *")
    check(lib.dv_corr_get(s, r), "dv_corr_get")
    return float(r[0])


@dataclass(frozen=True)
class RecordFeatures:
    """The per-channel feature set of one complete record, as the firmware reports it."""

    index: int
    stats: Stats
    temporal: Temporal | None
    segstd: np.ndarray
    window: Stats | None


def channel_records(x: Any, fs_hz: float, win_len: int = 256, seg_len: int = 64,
                    n_seg: int = 64) -> tuple[list[RecordFeatures], int]:
    """Run the firmware's per-channel bundle (dv_chan) over x: one RecordFeatures per complete
    record of seg_len * n_seg samples. Returns (records, NaN/Inf samples dropped)."""
    a = as_doubles(x)
    cfg = ffi.new("dv_chan_config_t *", {"win_len": win_len, "seg_len": seg_len,
                                         "n_seg": n_seg, "dt_s": 1.0 / fs_hz})
    blen = max(int(lib.dv_chan_buf_len(cfg)), 1)  # 0 for a bad length: init says why
    buf = ffi.new("double[]", blen)
    s = ffi.new("dv_chan_t *")
    check(lib.dv_chan_init(s, cfg, buf, blen), "dv_chan_init")
    used = ffi.new("size_t *")
    st = ffi.new("dv_stats_t *")
    tm = ffi.new("dv_temporal_out_t *")
    win = ffi.new("dv_stats_t *")
    vec = np.empty(n_seg)
    records: list[RecordFeatures] = []
    off = 0
    p = ptr(a)
    while off < a.size:
        r = check(lib.dv_chan_update_block(s, p + off, a.size - off, used), "dv_chan_update_block")
        off += int(used[0])
        if r == DV_RECORD:
            tst = lib.dv_chan_get_record(s, st, tm)
            check(lib.dv_segstd_get(ffi.addressof(s.seg), ptr(vec), n_seg), "dv_segstd_get")
            wst = lib.dv_chan_get_window(s, win)
            records.append(RecordFeatures(len(records), _stats(st),
                                          _temporal(tm) if tst == 0 else None, vec.copy(),
                                          _stats(win) if wst == 0 else None))
    return records, int(s.n_nonfinite)
