"""`dynval residual MODEL TEST.csv [TEST2.csv | FOLDER ...]`: per-channel RMSE and normalised
RMSE (RMSE / RMS of the measured channel) of the model's open-loop prediction."""
from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

from dynval.cli_common import add_test_options, read_tests
from dynval.io import Recording

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("residual", help="per-channel RMSE / NRMSE of a model against tests")
    p.add_argument("model", type=Path, help="model file (dynval format or declared_model.json)")
    p.add_argument("tests", type=Path, nargs="+", help="recorded tests (files or folders)")
    p.add_argument("--oversample", type=int, default=None,
                   help="band-limited input interpolation factor (default: the model's, 4)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_test_options(p)
    p.set_defaults(run=run)


def compute(model_path: Path, recs: list[Recording],
            oversample: int | None = None) -> dict[str, Any]:
    from dynval import labels
    from dynval import model as mdl

    m = mdl.load(model_path)
    res = []
    for rec in recs:
        r = mdl.residual(m, rec, oversample=oversample, keep=False).summary()
        r["file"] = str(rec.source or rec.name)
        units = labels.channel_labels(r["channels"], m, [rec])
        for c, v in r["channels"].items():  # rmse and rms_measured are in the channel's unit
            v["unit"] = units[c].unit
            _undefined(r["file"], c, v)
        res.append(r)
    return {"model": str(model_path), "tests": res}


def _undefined(file: str, c: str, v: dict[str, Any]) -> None:
    """A figure the channel leaves undefined (NRMSE of a channel measured as zero throughout,
    any of a channel with no finite sample) is null, not NaN (not JSON), and a warning."""
    bad = [k for k in ("rmse", "nrmse", "rms_measured") if not math.isfinite(v[k])]
    if not bad:
        return
    why = "no finite sample" if v["n_used"] == 0 else "measured as zero throughout"
    log.warning("%s: channel %s is %s: its %s left undefined (null)", file, c, why,
                ", ".join(bad))
    v.update(dict.fromkeys(bad))


def _num(x: float | None, spec: str) -> str:
    return "n/a" if x is None else format(x, spec)


def run(args: argparse.Namespace) -> int:
    recs = read_tests(args.tests, args, besides=args.model)
    res = compute(args.model, recs, args.oversample)
    if args.json:
        json.dump(res, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    print(f"model {res['model']}")
    for t in res["tests"]:
        print(f"{t['file']}: {t['n_samples']} samples at {t['fs_hz']:g} Hz")
        width = max(12, *(len(c) for c in t["channels"]))
        print(f"  {'channel':<{width}} {'unit':<6} {'rmse':>12} {'nrmse_%':>9} "
              f"{'rms_meas':>12} {'samples':>9}")
        for c, v in t["channels"].items():
            nrmse = None if v["nrmse"] is None else 100 * v["nrmse"]
            print(f"  {c:<{width}} {v['unit']:<6} {_num(v['rmse'], '>12.5g')} "
                  f"{_num(nrmse, '>9.3f'):>9} {_num(v['rms_measured'], '>12.5g'):>12} "
                  f"{v['n_used']:>9}")
    return 0
