"""`dynval validate --model MODEL --experiments TESTS... --features SPEC [--param NAME=LO:HI ...]
--json OUT --html OUT`: Mahalanobis validation against the experimental baseline, with an
optional design of experiments (Latin hypercube or full factorial), RMSE, ANOVA R^2 and PCA
(report Section 6)."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    Progress,
    add_study_options,
    nonnegative_int,
    positive_int,
    read_tests,
    runner_for,
    study_inputs,
    write_study_reports,
)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("validate", help="Mahalanobis validation + DOE sweep against tests")
    add_study_options(p)
    p.add_argument("--runs", type=positive_int, default=200,
                   help="Latin hypercube runs (%(default)s)")
    p.add_argument("--doe", choices=("lhs", "factorial"), default="lhs",
                   help="design of experiments (%(default)s)")
    p.add_argument("--levels", type=positive_int, default=3, help="factorial levels (%(default)s)")
    p.add_argument("--ref-test", type=nonnegative_int, default=0, metavar="I",
                   help="0-based test whose force drives the sweep and is the RMSE reference")
    p.add_argument("--check", action="append", default=[], metavar="KIND@CH",
                   help="the report's linearity / reciprocity check (5.3.1) on the tests and "
                   "the model, part of the verdict (repeat): linearity@acc4 (the tests at two "
                   "excitation levels), reciprocity@acc4 (needs --swapped)")
    p.add_argument("--swapped", type=Path, nargs="+", default=[], metavar="TEST",
                   help="reciprocity tests: the force at the DOF of the --check channel, the "
                   "response at the model's input DOF")
    p.add_argument("--rank-against", type=Path, default=None, metavar="MODEL_B",
                   help="feature selection instead of a verdict: rank the --features "
                   "candidates by how well they tell --model from MODEL_B on these tests")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Exit code: 0 PASS, 1 FAIL, 4 INCONCLUSIVE (verdict.EXIT); 2 an error."""
    from dynval.validate import study
    from dynval.validate import verdict as vd

    m, recs, ranges = study_inputs(args)
    swapped = read_tests(args.swapped, args, besides=args.model) if args.swapped else []
    if args.rank_against is not None:
        return _rank(args, m, recs)
    with runner_for(args) as rn, Progress(args) as bars:
        res, art = study.validate(m, recs, args.features, ranges, runs=args.runs,
                                  design=args.doe, ref_test=args.ref_test,
                                  rmse_channels=args.rmse_channel, seed=args.seed,
                                  levels=args.levels, shrink=args.shrink, noise=args.noise,
                                  level=args.level, checks=args.check, swapped=swapped,
                                  runner=rn, progress=bars.stage)
    write_study_reports(args, res, art)
    v = res["verdict"]
    print(vd.headline(v, res["model"]))
    print(f"  baseline: {res['baseline']['n_tests']} tests x "
          f"{res['baseline']['n_features']} features")
    for line in vd.evidence_lines(v):
        print(line)
    if "doe" in res:
        d = res["doe"]
        print(f"DOE {d['design']} x {d['runs']}: Spearman(D, RMSE) = "
              f"{d['spearman_d_vs_rmse']:.3f}; best run {d['best_run']}")
    if "pca" in res:
        print(f"PCA: {res['pca']['n_components_98']} components hold 98 %")
    return int(v["exit_code"])


def _rank(args: argparse.Namespace, m: Any, recs: Any) -> int:
    """--rank-against: the candidate features ranked for the pair of models (exit code 0)."""
    from dynval import model as mdl
    from dynval.validate import report, selection

    m_b = mdl.load(args.rank_against)
    ranked = selection.rank(m, m_b, recs, args.features, noise=args.noise)
    for line in selection.table(ranked, len(recs)):
        print(line)
    yes = [r.feature for r in ranked if r.tells_apart]
    print(f"{len(yes)} of {len(ranked)} candidate features tell A from B with {len(recs)} "
          f"tests (z >= {selection.Z_TELL:.2f}: the one-feature paired test at 5 % has >= 80 % "
          "power)" + (f"; best: {', '.join(yes[:4])}" if yes else ""))
    if args.json_out:
        report.write_json({"format": "dynval-validate/2", "kind": "rank-features",
                           "model_a": str(args.model), "model_b": str(args.rank_against),
                           "n_tests": len(recs), "z_tell": selection.Z_TELL,
                           "ranking": [r.summary() for r in ranked]}, args.json_out)
    return 0
