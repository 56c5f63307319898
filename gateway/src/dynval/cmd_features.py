"""`dynval features FILE`: per-channel waveform features of a recorded test, by the C core."""
from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from dynval.cli_common import add_test_options, int_in, read_with_options
from dynval.errors import CoreError, InputFileError
from dynval.io import Recording

log = logging.getLogger(__name__)

COLUMNS = ("mean", "std", "rms", "skew", "kurt", "peak", "crest", "kfactor")
TEMPORAL = ("energy", "central_time", "rms_duration")


def add_parser(sub: Any) -> None:
    p = sub.add_parser("features", help="per-channel waveform features of a recorded test")
    p.add_argument("file", type=Path,
                   help="recorded test: CSV with a header (time_s,force_N,...), text, BRFD JSON, "
                   "MCAP, UFF 58, MDF 4, HDF5 or MATLAB .mat")
    p.add_argument("--seg-len", type=int_in(2), default=64,
                   help="segment length for segmented STD (%(default)s)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_test_options(p)
    p.set_defaults(run=run)


def compute(rec: Recording, seg_len: int = 64) -> dict[str, Any]:
    from dynval import features
    from dynval.io.arrays import release_pages

    out: dict[str, Any] = {"test": rec.name, "fs_hz": rec.fs_hz, "n_samples": rec.n_samples,
                           "sha256": rec.sha256, "warnings": len(rec.warnings), "channels": {}}
    for ch in rec.channels:
        dropped = _in_range(rec, ch.name, ch.data)
        st = features.moments(ch.data)
        seg = features.segstd(ch.data, seg_len) if ch.data.size >= seg_len else None
        row: dict[str, Any] = {"unit": ch.unit, "role": ch.role, **st.as_dict(),
                               **_temporal_row(rec, ch.name, ch.data)}
        # what the core flags undefined (a constant channel's shape, a zero one's crest) is
        # null, not the 0 it fills in: a number read as one would be wrong
        if not st.shape_defined:
            row["skew"] = row["kurt"] = None
        if not st.crest_defined:
            row["crest"] = None
        if seg is not None:
            row["segstd_min"], row["segstd_max"] = float(seg.min()), float(seg.max())
        _check_finite(rec, ch.name, ch.data, row)
        if dropped:
            row["dropped_out_of_range"] = dropped
        out["channels"][ch.name] = row
        release_pages(ch.data)  # a memory-mapped long record: one channel's pages at a time
    return out


def _temporal_row(rec: Recording, name: str, x: np.ndarray) -> dict[str, float | None]:
    """The channel's temporal moments; for one without energy (every sample 0: a dead or
    unplugged sensor, a channel recorded but not wired) the energy 0 and its central time
    and RMS duration undefined (None, JSON null), logged: the core's DV_ENUMERIC there."""
    from dynval import _core, features

    try:
        tm = features.temporal(x, 1.0 / rec.fs_hz)
    except CoreError as exc:
        if exc.status != _core.lib.DV_ENUMERIC:
            raise
        log.warning("%s: channel %s: every sample is 0: its central time and RMS duration "
                    "are undefined (n/a)", rec.source or rec.name, name)
        return {"energy": 0.0, "central_time": None, "rms_duration": None}
    return {k: getattr(tm, k) for k in TEMPORAL}


def _in_range(rec: Recording, name: str, x: np.ndarray) -> int:
    """How many samples lie beyond the core's feature range |x| <= DV_FEAT_MAX (it drops and
    counts them, like NaN): logged and returned (counted in the output); an error naming the
    channel when no finite sample is left within it."""
    from dynval import contract

    limit = float(contract.MACROS["DV_FEAT_MAX"])
    over = int(np.count_nonzero(np.abs(x) > limit))
    if over and not np.any(np.abs(x) <= limit):
        raise InputFileError(rec.source or rec.name, f"channel {name}: no sample within the "
                             f"features' range |x| <= {limit:.3g} (the core's DV_FEAT_MAX); "
                             "rescale the channel (channel map 'scale')")
    if over:
        log.warning("%s: channel %s: %d sample(s) beyond the features' range |x| <= %.3g "
                    "dropped (counted in dropped_out_of_range)", rec.source or rec.name, name,
                    over, limit)
    return over


def _check_finite(rec: Recording, name: str, x: np.ndarray, row: dict[str, Any]) -> None:
    """Finite samples give finite features, or an error naming the channel: never a NaN or
    Inf printed with exit 0 (a sample near the real type's range overflows its square)."""
    bad = [k for k, v in row.items() if isinstance(v, float) and not math.isfinite(v)]
    if bad:
        peak = float(np.nanmax(np.abs(x), initial=0.0))
        raise InputFileError(rec.source or rec.name, f"channel {name}: {', '.join(bad)} not "
                             f"finite: samples up to {peak:.3g} overflow the feature arithmetic; "
                             "rescale the channel (channel map 'scale')")


def run(args: argparse.Namespace) -> int:
    res = compute(read_with_options(args.file, args), args.seg_len)
    if args.json:
        json.dump(res, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    print(f"{res['test']}: {res['n_samples']} samples at {res['fs_hz']:g} Hz")
    names = list(res["channels"])
    width = max(12, *(len(n) for n in names))
    cols = (*COLUMNS, *TEMPORAL)
    print(f"{'channel':<{width}} {'unit':<6} " + " ".join(f"{c:>12}" for c in cols))
    for n in names:
        r = res["channels"][n]
        print(f"{n:<{width}} {r['unit']:<6} "
              + " ".join(f"{'n/a':>12}" if r[c] is None else f"{r[c]:>12.5g}" for c in cols))
    for n in names:
        if res["channels"][n].get("dropped_out_of_range"):
            print(f"{n}: {res['channels'][n]['dropped_out_of_range']} sample(s) beyond the "
                  "features' range were dropped")
    return 0
