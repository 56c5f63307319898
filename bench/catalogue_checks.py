"""Issue 19: `dynval validate --check linearity@acc4 / reciprocity@acc4` (validate.checks) on
independent simulations of the report's 4-DOF structure (dynval.synth, model L2, random force
at DOF 1, 10 tests alternating 12 / 7.2 N RMS; reciprocity: 3 tests at 12 N against 3 with the
force at DOF 4), with and without the bumper, the declared linear model checked: how often
each check fails on the tests and on the model, and how often the model is rejected by it.

    PYTHONPATH=gateway/src python bench/catalogue_checks.py --seeds 20 \
        --out bench/RESULTS.catalogue-checks.md
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np
from dynval import synth
from dynval.validate import checks as chk
from dynval.validate import montecarlo as mc

sys.path.insert(0, str(Path(__file__).resolve().parent))
from catalogue_modal_frf import declared

log = logging.getLogger("catalogue_checks")


def _stat(os_: list[chk.Outcome], side: str) -> str:
    z = np.array([getattr(o, side).z2 for o in os_])
    zc = np.array([getattr(o, side).z2_coh for o in os_])
    return f"{np.median(z):.2f} / {np.median(zc):.2f} ({z.max():.2f} / {zc.max():.2f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("dynval").setLevel(logging.ERROR)
    m = declared()
    t0 = time.perf_counter()
    lines = ["## `dynval validate --check` (bench/catalogue_checks.py)", "",
             (f"{a.seeds} seeds; the declared linear model (L2) checked; fail: z2 or z2_coh > "
              "2; the model is rejected when the check holds on one side and fails on the "
              "other."), "",
             ("| check | truth | tests: z2 / z2_coh median (max) | model: z2 / z2_coh median "
              "(max) | fails on the tests | fails on the model | linear model rejected |"),
             "|---|---|---|---|---|---|---|"]
    for label, truth in (("clean", synth.Truth()),
                         ("bumper", synth.Truth(elements=(mc.BUMPER,), label="bumper"))):
        out: dict[str, list[chk.Outcome]] = {"linearity": [], "reciprocity": []}
        for seed in range(a.seeds):
            recs = synth.generate(m, truth, n_tests=10, seed=4000 + seed, fine=mc.FINE)
            out["linearity"] += chk.run(m, recs, chk.parse(["linearity@acc4"], m,
                                                           list(m.outputs)), "force_N")
            sa, sb = synth.reciprocal(m, truth, 4, n_tests=3, levels_n_rms=(12.0,),
                                      seed=5000 + seed, fine=mc.FINE)
            out["reciprocity"] += chk.run(m, sa, chk.parse(["reciprocity@acc4"], m,
                                                           list(m.outputs)), "force_N",
                                          swapped=sb)
            log.info("%s seed %d (%.0f s)", label, seed, time.perf_counter() - t0)
        for kind, os_ in out.items():
            n = len(os_)
            lines.append(f"| {kind}@acc4 | {label} | {_stat(os_, 'measured')} | {_stat(os_, 'model')} | "
                         f"{sum(not o.measured.passed for o in os_)} of {n} | "
                         f"{sum(not o.model.passed for o in os_)} of {n} | "
                         f"{sum(not o.consistent for o in os_)} of {n} |")
    lines += ["", f"Measured in {time.perf_counter() - t0:.0f} s."]
    text = "\n".join(lines) + "\n"
    if a.out:
        a.out.write_text(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
