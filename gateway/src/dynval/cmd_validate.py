"""`dynval validate --model MODEL --experiments TESTS... --features SPEC [--param NAME=LO:HI ...]
--json OUT --html OUT`: Mahalanobis validation against the experimental baseline, with an
optional design of experiments (Latin hypercube or full factorial), RMSE, ANOVA R^2 and PCA
(report Section 6)."""
from __future__ import annotations

import argparse
import logging
from typing import Any

from dynval.cli_common import Progress, add_study_options, read_tests, runner_for

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("validate", help="Mahalanobis validation + DOE sweep against tests")
    add_study_options(p)
    p.add_argument("--runs", type=int, default=200, help="Latin hypercube runs (%(default)s)")
    p.add_argument("--doe", choices=("lhs", "factorial"), default="lhs",
                   help="design of experiments (%(default)s)")
    p.add_argument("--levels", type=int, default=3, help="factorial levels (%(default)s)")
    p.add_argument("--ref-test", type=int, default=0, metavar="I",
                   help="0-based test whose force drives the sweep and is the RMSE reference")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dynval import model as mdl
    from dynval.validate import report, study
    from dynval.validate.doe import parse_param

    m = mdl.load(args.model)
    recs = read_tests(args.experiments, args, besides=args.model)
    ranges = [parse_param(t) for t in args.param]
    with runner_for(args) as rn, Progress(args) as bars:
        res, art = study.validate(m, recs, args.features, ranges, runs=args.runs,
                                  design=args.doe, ref_test=args.ref_test,
                                  rmse_channels=args.rmse_channel, seed=args.seed,
                                  levels=args.levels, shrink=args.shrink, runner=rn,
                                  progress=bars.stage)
    if args.json_out:
        report.write_json(res, args.json_out)
        log.info("wrote %s", args.json_out)
    if args.html_out:
        report.write_html(res, art, args.html_out)
        log.info("wrote %s", args.html_out)
    v = res["nominal"]["verdict"]
    print(f"baseline: {res['baseline']['n_tests']} tests x {res['baseline']['n_features']} "
          f"features ({res['baseline']['covariance']} covariance)")
    print(f"model {res['model']}: {'PASS' if v['pass'] else 'FAIL'} - median D "
          f"{v['median_d']:.4g} vs {v['threshold_kind']} threshold {v['threshold']:.4g} "
          f"({100 * v['fraction_within']:.0f} % of tests within)")
    pt = res["nominal"]["paired"]
    if pt["pass"] is not None:
        print(f"paired test (each test's force, bias = 0): {'PASS' if pt['pass'] else 'FAIL'} - "
              f"p = {pt['p_value']:.3g}")
    if "doe" in res:
        d = res["doe"]
        print(f"DOE {d['design']} x {d['runs']}: Spearman(D, RMSE) = "
              f"{d['spearman_d_vs_rmse']:.3f}; best run {d['best_run']}")
    if "pca" in res:
        print(f"PCA: {res['pca']['n_components_98']} components hold 98 %")
    return 0
