"""`dynval validate --model MODEL --experiments TESTS... --features SPEC [--param NAME=LO:HI ...]
--json OUT --html OUT`: Mahalanobis validation against the experimental baseline, with an
optional design of experiments (Latin hypercube or full factorial), RMSE, ANOVA R^2 and PCA
(report Section 6)."""
from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from dynval import model as mdl
from dynval.cli_common import add_test_options, read_with_options
from dynval.cmd_residual import expand
from dynval.io.recording import Recording

log = logging.getLogger(__name__)


def add_common(p: Any) -> None:
    """Options shared by validate and calibrate."""
    p.add_argument("--model", type=Path, required=True, help="model file (dynval format or "
                   "declared_model.json)")
    p.add_argument("--experiments", type=Path, nargs="+", required=True, metavar="TEST",
                   help="recorded tests (files or folders of *.csv), the experimental baseline")
    p.add_argument("--features", required=True, metavar="SPEC",
                   help="feature vector, e.g. 'peak,std@acc3,acc4' or 'segstd64@acc4' "
                   "(see gateway/docs/validate-schema.md)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=LO:HI",
                   help="uncertain parameter with a uniform range (repeat), e.g. zeta2=0.01:0.08")
    p.add_argument("--rmse-channel", action="append", default=None, metavar="CH",
                   help="channel(s) of the RMSE (eq. 47) (default: the feature channels)")
    p.add_argument("--seed", type=int, default=0, help="design / MCMC seed (%(default)s)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the sweeps on a Dask distributed scheduler (tcp://host:8786)")
    p.add_argument("--shrink", choices=("auto", "always", "never"), default="auto",
                   help="Ledoit-Wolf covariance shrinkage (auto: when tests <= features + 1)")
    p.add_argument("--json", dest="json_out", type=Path, default=None, metavar="OUT",
                   help="write the JSON result here")
    p.add_argument("--html", dest="html_out", type=Path, default=None, metavar="OUT",
                   help="write the self-contained HTML report here")
    add_test_options(p)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("validate", help="Mahalanobis validation + DOE sweep against tests")
    add_common(p)
    p.add_argument("--runs", type=int, default=200, help="Latin hypercube runs (%(default)s)")
    p.add_argument("--doe", choices=("lhs", "factorial"), default="lhs",
                   help="design of experiments (%(default)s)")
    p.add_argument("--levels", type=int, default=3, help="factorial levels (%(default)s)")
    p.add_argument("--ref-test", type=int, default=0, metavar="I",
                   help="0-based test whose force drives the sweep and is the RMSE reference")
    p.set_defaults(run=run)


def read_tests(args: argparse.Namespace) -> list[Recording]:
    return [read_with_options(t, args) for t in expand(args.experiments)]


@contextlib.contextmanager
def bars(args: argparse.Namespace) -> Iterator[Callable[[str], Callable[[int, int], None] | None]]:
    """A progress factory for the study functions: one tqdm bar per stage, only on a TTY."""
    opened: list[Any] = []

    def factory(stage: str) -> Callable[[int, int], None] | None:
        if getattr(args, "quiet", False) or not sys.stderr.isatty():
            return None
        import importlib

        bar: Any = importlib.import_module("tqdm").tqdm(desc=stage, leave=False)
        opened.append(bar)

        def cb(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()
        return cb

    try:
        yield factory
    finally:
        for b in opened:
            b.close()


def runner_for(args: argparse.Namespace) -> Any:
    from dynval.validate.doe import Runner

    return Runner(workers=args.workers, scheduler=args.scheduler)


def run(args: argparse.Namespace) -> int:
    from dynval.validate import report, study
    from dynval.validate.doe import parse_param

    m = mdl.load(args.model)
    recs = read_tests(args)
    ranges = [parse_param(t) for t in args.param]
    with runner_for(args) as rn, bars(args) as prog:
        res, art = study.validate(m, recs, args.features, ranges, runs=args.runs,
                                  design=args.doe, ref_test=args.ref_test,
                                  rmse_channels=args.rmse_channel, seed=args.seed,
                                  levels=args.levels, shrink=args.shrink, runner=rn,
                                  progress=prog)
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
