"""`dynval residual MODEL TEST.csv [TEST2.csv | FOLDER ...]`: per-channel RMSE and normalised
RMSE (RMSE / RMS of the measured channel) of the model's open-loop prediction."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from dynval import model as mdl
from dynval.errors import InputFileError
from dynval.io import read_test


def add_parser(sub: Any) -> None:
    p = sub.add_parser("residual", help="per-channel RMSE / NRMSE of a model against tests")
    p.add_argument("model", type=Path, help="model file (dynval format or declared_model.json)")
    p.add_argument("tests", type=Path, nargs="+", help="recorded tests (CSV) or folders of them")
    p.add_argument("--oversample", type=int, default=None,
                   help="band-limited input interpolation factor (default: the model's, 4)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(run=run)


def expand(paths: list[Path]) -> list[Path]:
    """Tests named directly, and the *.csv files of named folders (sorted)."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(p.glob("*.csv"))
            if not found:
                raise InputFileError(p, "folder holds no *.csv tests")
            out.extend(found)
        else:
            out.append(p)
    return out


def compute(model_path: Path, tests: list[Path], oversample: int | None = None) -> dict[str, Any]:
    m = mdl.load(model_path)
    res = []
    for t in expand(tests):
        r = mdl.residual(m, read_test(t), oversample=oversample).summary()
        r["file"] = str(t)
        res.append(r)
    return {"model": str(model_path), "tests": res}


def run(args: argparse.Namespace) -> int:
    res = compute(args.model, args.tests, args.oversample)
    if args.json:
        json.dump(res, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    print(f"model {res['model']}")
    for t in res["tests"]:
        print(f"{t['file']}: {t['n_samples']} samples at {t['fs_hz']:g} Hz")
        width = max(12, *(len(c) for c in t["channels"]))
        print(f"  {'channel':<{width}} {'rmse':>12} {'nrmse_%':>9} {'rms_meas':>12}")
        for c, v in t["channels"].items():
            print(f"  {c:<{width}} {v['rmse']:>12.5g} {100 * v['nrmse']:>9.3f} "
                  f"{v['rms_measured']:>12.5g}")
    return 0
