"""`dynval calibrate --model MODEL --experiments TESTS... --features SPEC --param NAME=LO:HI ...
[--method gp|direct|both] --json OUT --html OUT [--model-out CALIBRATED]`: Bayesian calibration
(GP emulator + emcee, and/or emcee on the C model) with the held-out consistency check."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    Progress,
    add_study_options,
    nonnegative_int,
    positive_int,
    runner_for,
    study_inputs,
    write_study_reports,
)

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("calibrate", help="Bayesian calibration of model parameters")
    add_study_options(p)
    p.add_argument("--method", choices=("gp", "direct", "both"), default="both",
                   help="GP emulator + MCMC, MCMC on the C model, or both (%(default)s)")
    p.add_argument("--runs", type=positive_int, default=150, help="LHS runs for the emulator "
                   "(%(default)s)")
    p.add_argument("--holdout", type=nonnegative_int, default=None, metavar="K",
                   help="last K tests held out for the consistency check (default: n/4)")
    p.add_argument("--gp-forces", type=positive_int, default=None, metavar="M",
                   help="training tests whose forces drive the sweep (default: all)")
    p.add_argument("--direct-forces", type=positive_int, default=4, metavar="M",
                   help="training tests whose forces drive each direct MCMC step (%(default)s)")
    p.add_argument("--steps", type=positive_int, default=1500, help="GP MCMC steps (%(default)s)")
    p.add_argument("--direct-steps", type=positive_int, default=300,
                   help="direct MCMC steps (%(default)s)")
    p.add_argument("--oversample", type=positive_int, default=None,
                   help="band-limited input oversampling before the core's cubic hold in the "
                   "sweeps/MCMC (default: 2, the validation hold)")
    p.add_argument("--model-out", type=Path, default=None, metavar="FILE",
                   help="write the calibrated model (posterior mean) here")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Exit code: the held-out check of the calibrated model, 0 PASS, 1 FAIL, 4 INCONCLUSIVE
    (verdict.EXIT); 2 an error."""
    from dynval import model as mdl
    from dynval.validate import study
    from dynval.validate import verdict as vd

    m, recs, ranges = study_inputs(args)
    with runner_for(args) as rn, Progress(args) as bars:
        res, art, m_cal = study.calibrate(
            m, recs, args.features, ranges, method=args.method, runs=args.runs,
            holdout=args.holdout, gp_forces=args.gp_forces, direct_forces=args.direct_forces,
            steps=args.steps, direct_steps=args.direct_steps, rmse_channels=args.rmse_channel,
            seed=args.seed, shrink=args.shrink, oversample=args.oversample, noise=args.noise,
            level=args.level, runner=rn, progress=bars.stage)
    write_study_reports(args, res, art)
    if args.model_out:
        mdl.save(m_cal, args.model_out)
        log.info("wrote %s (calibrated model)", args.model_out)
    for meth, post in res["posterior"].items():
        for n, v in post["parameters"].items():
            print(f"{meth:>6} {n:<16} {v['mean']:.6g} +/- {v['std']:.3g}  "
                  f"{100 * post['interval_level']:g} % interval "
                  f"[{v['lo']:.6g}, {v['hi']:.6g}]")
    v = res["verdict"]
    print("held-out check of the calibrated model: " + vd.headline(v, res["model"]))
    if v["evidence"]:
        for line in vd.evidence_lines(v):
            print(line)
        nom = res["consistency"]["nominal"]["verdict"]
        print(f"  (the nominal model on the same held-out tests: {nom['verdict']})")
    return int(v["exit_code"])
