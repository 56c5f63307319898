#!/usr/bin/env python3
"""Issue 16 item 9: do discover's uncertainties cover the truth? Blind generated cases on the
report's 4-DOF frame (a cubic spring, friction at a DOF, a stiffness loss, a contact; the
story, size and seed drawn per case), 6 tests each; for every case the fitted parameter, its
Gauss-Newton sigma (`uncertainty_fit`), the combined sigma with the test-to-test scatter
(`uncertainty`) and whether +-2 sigma holds the truth. Writes bench/RESULTS.coverage.md.

    python3 bench/bench_discover_coverage.py [--seeds 12] [--out bench/RESULTS.coverage.md]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop

ROOT = Path(__file__).resolve().parent.parent


def declared() -> mdl.Model:
    return mdl.Model(masses_kg=(6.54, 6.66, 6.86, 6.80),
                     stiffness_n_per_m=(10.0, 399790.0, 399790.0, 399790.0),
                     damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01)),
                     input=mdl.Input("force", 1, "force_N"),
                     outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)},
                     fs_hz=640.0)


def case(seed: int) -> tuple[str, gen.Truth, str, float]:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    kind = seed % 4
    if kind == 0:
        k3 = float(10 ** rng.uniform(12.0, 12.8))
        return "cubic", gen.Truth(elements=(mdl.CubicSpring(story - 1, story, k3),)), \
            "k3_n_per_m3", k3
    if kind == 1:
        f = float(rng.uniform(0.3, 1.0))
        return "friction", gen.Truth(elements=(mdl.Friction(0, story, f, 1e-4),)), "force_n", f
    if kind == 2:
        loss = float(rng.uniform(0.03, 0.15))
        return "stiffness loss", gen.Truth(k_scale={story: 1 - loss}), "dk_n_per_m", \
            -loss * 399790.0
    gap = float(rng.uniform(0.8e-4, 1.2e-4))
    return "contact", gen.Truth(elements=(mdl.Contact(story - 1, story, gap, 1e-4, 1.925e6),)), \
        "gap_m", gap


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS.coverage.md"))
    a = ap.parse_args()
    rows, cov_fit, cov_all = [], 0, 0
    for seed in range(a.seeds):
        kind, truth, name, want = case(seed)
        r = loop.discover(declared(), gen.generate(declared(), truth, n_tests=6, seed=seed))
        ps = [e["parameters"][name] for e in r.effects if name in e["parameters"]]
        if not ps:
            rows.append(f"| {seed} | {kind} | {want:.4g} | not found | | | | no |")
            continue
        p = ps[0]
        err = abs(p["value"] - want)
        ok_fit, ok = err <= 2 * p["uncertainty_fit"], err <= 2 * p["uncertainty"]
        cov_fit += ok_fit
        cov_all += ok
        rows.append(f"| {seed} | {kind} | {want:.4g} | {p['value']:.4g} | "
                    f"{p['uncertainty_fit']:.2g} | {p['uncertainty']:.2g} | "
                    f"{err / p['uncertainty']:.2f} | {'yes' if ok else 'no'} |")
        print(rows[-1], flush=True)  # noqa: T201 (a benchmark's table)
    text = ("# discover: do the uncertainties cover the truth? (issue 16, item 9)\n\n"
            f"{a.seeds} blind generated cases on the 4-DOF frame, 6 tests each; "
            "`python3 bench/bench_discover_coverage.py`.\n"
            f"Covered at 2 sigma: {cov_all} of {a.seeds} with the test-to-test scatter "
            f"(Student-t widened), {cov_fit} of {a.seeds} with the Gauss-Newton sigma alone.\n\n"
            "| seed | case | true | fitted | sigma fit | sigma | error / sigma | covered |\n"
            "|---|---|---:|---:|---:|---:|---:|---|\n" + "\n".join(rows) + "\n")
    Path(a.out).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
