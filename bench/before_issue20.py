"""The validation and calibration method before issue 20 (commit 926bb3d) on the tests the
Monte Carlo of bench/validate_error_rates.py and bench/calibrate_coverage.py generate: how
often its paired test and its eq. 41 verdict reject the exactly right model, and how often
its 95 % intervals hold the true zeta2. Run it on that commit's package:

    git archive 926bb3d gateway/src | tar -x -C /tmp/old
    cp -r gateway/src/dynval/_lib /tmp/old/gateway/src/dynval/
    PYTHONPATH=/tmp/old/gateway/src python bench/before_issue20.py --seeds 100 --cal-seeds 20
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from dynval import model as mdl
from dynval import synth
from dynval.validate import doe, study

log = logging.getLogger("before_issue20")
# the data beside the repository (../shared, as the README says)
MODEL = (Path(__file__).resolve().parents[2] / "shared" / "data" / "synthetic" / "lanl4dof-clean"
         / "declared_model.json")
SPECS = ("peak,std@acc3,acc4", "std@acc3,acc4")
OPTIONS = {"method": "both", "runs": 40, "walkers": 16, "steps": 600, "direct_walkers": 8,
           "direct_steps": 120, "holdout": 2}


def false_rejection(m: mdl.Model, seeds: int) -> None:
    paired = dict.fromkeys(SPECS, 0)
    eq41 = dict.fromkeys(SPECS, 0)
    for seed in range(seeds):
        recs = synth.generate(m, synth.Truth(), n_tests=10, seed=seed, fine=64)
        for s in SPECS:
            res, _ = study.validate(m, recs, s)
            paired[s] += res["nominal"]["paired"]["pass"] is False
            eq41[s] += not res["nominal"]["verdict"]["pass"]
    log.info("right model, %d studies: paired test rejected %s; eq. 41 verdict FAIL %s",
             seeds, paired, eq41)


def coverage(m: mdl.Model, seeds: int) -> None:
    cov: dict[str, list[int]] = {}
    with doe.Runner(workers=1) as rn:
        for seed in range(seeds):
            recs = synth.generate(m, synth.Truth(), n_tests=10, seed=seed, fine=64)
            res, _, _ = study.calibrate(m, recs, "peak,std@acc3,acc4",
                                        [doe.ParamRange("zeta2", 0.01, 0.08)], seed=seed,
                                        runner=rn, **OPTIONS)
            for k, p in res["posterior"].items():
                v = p["parameters"]["zeta2"]
                c = cov.setdefault(k, [0, 0])
                c[0] += 1
                c[1] += v["q2.5"] <= 0.05 <= v["q97.5"]
    log.info("95 %% intervals holding zeta2 = 0.05 (runs, covered): %s", cov)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--cal-seeds", type=int, default=20)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("dynval").setLevel(logging.ERROR)
    m = mdl.load(MODEL)
    false_rejection(m, a.seeds)
    coverage(m, a.cal_seeds)


if __name__ == "__main__":
    main()
