"""Coverage of `dynval calibrate`'s 95 % intervals on generated tests with a known parameter
(dynval.validate.montecarlo.coverage), for the GP-emulator and the direct-MCMC routes.

    PYTHONPATH=gateway/src python bench/calibrate_coverage.py --seeds 40
"""
from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.validate import montecarlo as mc

log = logging.getLogger("calibrate_coverage")
# the data beside the repository (../shared, as the README says)
MODEL = (Path(__file__).resolve().parents[2] / "shared" / "data" / "synthetic" / "lanl4dof-clean"
         / "declared_model.json")
OPTIONS = {"method": "both", "runs": 40, "walkers": 16, "steps": 600, "direct_walkers": 8,
           "direct_steps": 120, "holdout": 2}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--spec", default="peak,std@acc3,acc4")
    ap.add_argument("--param", default="zeta2=0.01:0.08")
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("dynval").setLevel(logging.ERROR)
    m = mdl.load(a.model)
    name, rng = a.param.split("=")
    lo, hi = (float(v) for v in rng.split(":"))
    t0 = time.perf_counter()

    def progress(seed: int, res: dict[str, Any]) -> None:
        iv = {k: (p["parameters"][name]["lo"], p["parameters"][name]["hi"])
              for k, p in res["posterior"].items()}
        log.info("seed %d: %s (%.0f s)", seed, iv, time.perf_counter() - t0)

    cov = mc.coverage(m, a.spec, name, lo, hi, a.seeds, options=OPTIONS, on_seed=progress)
    truth = m.parameters()[name]
    lines = [f"| route | 95 % intervals holding {name} = {truth:g} | median width |",
             "|---|---|---|"]
    for meth, c in cov.items():
        lines.append(f"| {meth} | {c.covered} of {c.runs} ({100 * c.rate:.1f} %) | "
                     f"{float(np.median(c.widths or [np.nan])):.3g} |")
    text = "\n".join(lines) + "\n"
    log.info("\n%s", text)
    if a.out:
        a.out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
