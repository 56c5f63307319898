"""False-rejection rate and power of `dynval validate`'s verdict by Monte Carlo on generated
tests (dynval.validate.montecarlo), written as a markdown table.

    PYTHONPATH=gateway/src python bench/validate_error_rates.py --seeds 200 --wrong-seeds 100 \
        --out gateway/docs/validate-error-rates.table.md
"""
from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from dynval import model as mdl
from dynval.validate import montecarlo as mc

log = logging.getLogger("validate_error_rates")
SPECS = ("peak,std@acc3,acc4", "segstd64@acc4", "kurt@acc4")
# the data beside the repository (../shared, as the README says)
MODEL = (Path(__file__).resolve().parents[2] / "shared" / "data" / "synthetic" / "lanl4dof-clean"
         / "declared_model.json")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--seeds", type=int, default=200, help="seeds for the right model")
    ap.add_argument("--wrong-seeds", type=int, default=100, help="seeds for each wrong model")
    ap.add_argument("--tests", type=int, default=10, help="tests per study")
    ap.add_argument("--spec", action="append", default=None, help="feature specs")
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("dynval").setLevel(logging.ERROR)
    m = mdl.load(a.model)
    specs = a.spec or list(SPECS)
    truths = mc.scenarios(m)
    t0 = time.perf_counter()
    tallies = {}
    for name, sc in truths.items():
        n = a.seeds if name == "right model" else a.wrong_seeds
        tallies.update(mc.run(m, specs, {name: sc}, n, n_tests=a.tests))
        log.info("%s: %d seeds done (%.0f s)", name, n, time.perf_counter() - t0)
    lines = mc.markdown(tallies, specs, list(truths))
    text = "\n".join(lines) + "\n"
    log.info("\n%s", text)
    if a.out:
        a.out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
