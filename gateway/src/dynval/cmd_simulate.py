"""`dynval simulate MODEL TEST.csv -o PRED.csv`: the model's prediction for a test's measured
input, written with the test's column names (time, input, outputs)."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

import numpy as np

from dynval.cli_common import add_test_options, read_with_options
from dynval.errors import InputFileError
from dynval.io import Recording

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("simulate", help="predict a test's outputs from its measured input")
    p.add_argument("model", type=Path, help="model file (dynval format or declared_model.json)")
    p.add_argument("test", type=Path, help="recorded test (CSV: time_s,force_N,acc1_mps2,...)")
    p.add_argument("-o", "--output", type=Path, required=True, help="predicted CSV to write")
    p.add_argument("--oversample", type=int, default=None,
                   help="band-limited input interpolation factor (default: the model's, 4; "
                        "1 = the samples as they are, first-order hold)")
    add_test_options(p)
    p.set_defaults(run=run)


def time_column(path: Path) -> str:
    """The name of the test's time column: a CSV's first header cell, else time_s (the other
    formats have no time column of their own: BRFD's is unnamed, MCAP and text have none)."""
    if path.suffix.lower() != ".csv":
        return "time_s"
    try:
        with open(path, "rb") as f:
            first = f.readline(4096)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    return first.decode("utf-8-sig", "replace").split(",")[0].strip() or "time_s"


def write_prediction(model_path: Path, rec: Recording, test: Path, out: Path,
                     oversample: int | None = None) -> list[str]:
    """Simulate the test rec (read from the file test) and write; returns the column names."""
    from dynval import model as mdl

    m = mdl.load(model_path)
    pred = mdl.simulate_recording(m, rec, oversample=oversample)
    inp = mdl.input_channel(m, rec)
    order = [c for c in rec.names if c in pred] + [c for c in pred if c not in rec.names]
    skipped = [c for c in rec.names if c not in pred and c != inp]
    if skipped:
        log.info("%s: the model does not predict %s", rec.name, ", ".join(skipped))
    t = rec.t0_s + np.arange(rec.n_samples) / rec.fs_hz
    cols = [time_column(test), inp, *order]
    data = np.column_stack([t, rec.channel(inp).data, *(pred[c] for c in order)])
    try:
        np.savetxt(out, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")
    except OSError as exc:
        raise InputFileError(out, f"cannot write: {exc.strerror or exc}") from exc
    return cols


def run(args: argparse.Namespace) -> int:
    rec = read_with_options(args.test, args)
    cols = write_prediction(args.model, rec, args.test, args.output, args.oversample)
    log.info("wrote %s (%s)", args.output, ", ".join(cols))
    return 0
