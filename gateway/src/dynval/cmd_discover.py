"""`dynval discover MODEL TESTS... --json OUT.json --html OUT.html --model-out UPDATED`:
find what the declared model lacks, add it, and report the error before and after."""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path
from typing import Any

from dynval.cli_common import add_test_options, read_tests
from dynval.errors import ConfigError

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("discover", help="find the effect a declared model lacks, add it, "
                       "report the error before and after")
    p.add_argument("model", type=Path, help="declared model (dynval format or declared_model)")
    p.add_argument("tests", type=Path, nargs="+", help="measured tests (files or folders)")
    p.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="JSON report")
    p.add_argument("--html", type=Path, default=None, metavar="OUT.html", help="HTML report")
    p.add_argument("--model-out", type=Path, default=None, metavar="UPDATED",
                   help="write the model with the accepted effects (dynval format)")
    p.add_argument("--max-effects", type=int, default=3, help="at most this many effects")
    p.add_argument("--min-gain", type=float, default=0.10,
                   help="held-out SSE reduction an effect must bring (default 0.10)")
    p.add_argument("--noise", type=float, default=None, metavar="FRACTION",
                   help="stated sensor noise as a fraction of each channel's RMS (default: "
                        "estimated from the residual's high-frequency PSD)")
    p.add_argument("--uncertain", default="", metavar="P1,P2",
                   help="declared parameters that are uncertain (model parameter names, e.g. "
                        "zeta2,zeta4 or k1,beta): calibrated first, then re-adjusted jointly "
                        "with every candidate effect")
    add_test_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dynval import model as mdl
    from dynval.discover import loop, report

    t0 = time.perf_counter()
    m = mdl.load(args.model)
    recs = read_tests(args.tests, args, besides=args.model)
    noise = None
    if args.noise is not None:
        if not args.noise > 0:
            raise ConfigError(f"--noise must be > 0, got {args.noise}")
        noise = {}
        for c in m.outputs:
            vals = [r.channel(c).data for r in recs if c in r.names]
            if vals:
                import numpy as np

                noise[c] = args.noise * float(np.sqrt(np.mean(np.concatenate(vals) ** 2)))
    unc = tuple(x.strip() for x in args.uncertain.split(",") if x.strip())
    opts = loop.Options(max_effects=args.max_effects, min_gain=args.min_gain, noise=noise,
                        uncertain=unc)
    res = loop.discover(m, recs, opts, on_progress=lambda s: log.debug("%s", s))
    if args.model_out is not None:
        mdl.save(res.model, args.model_out)
    doc = report.to_json(res, str(args.model), str(args.model_out or ""))
    if args.json is not None:
        report.write_json(doc, args.json)
    if args.html is not None:
        report.write_html(res, doc, args.html)
    print(doc["verdict"])
    for e in doc["effects"]:
        ps = ", ".join(f"{k} = {v['value']:.5g} +/- {v['uncertainty'] or float('nan'):.2g} "
                       f"{v['unit']}" for k, v in e["parameters"].items())
        print(f"  {e['label']}: {ps}")
    width = max(8, *(len(c) for c in res.chans))
    print(f"  {'channel':<{width}} {'held-out rmse before':>21} {'after':>12} {'noise':>10}")
    for c in res.chans:
        b = doc["rmse_before"]["held_out"][c]
        a = doc["rmse_after"]["held_out"][c]
        print(f"  {c:<{width}} {b:>21.5g} {a:>12.5g} {doc['noise_floor'][c]:>10.4g}")
    mah = doc["mahalanobis"]
    print(f"  Mahalanobis before {mah.get('before')}, after {mah.get('after')} "
          f"(measured reference {mah.get('measured_reference')})")
    log.info("discover: %d tests in %.1f s", len(recs), time.perf_counter() - t0)
    sys.stdout.flush()
    return 0
