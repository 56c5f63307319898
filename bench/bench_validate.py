#!/usr/bin/env python3
"""Issue 7 performance figure: a 400-run Latin hypercube of 8192-sample simulations of the
report's 4-DOF model (through the C model + observer) with features, wall time end to end
(process start-up of the pool included), on all cores. Usage:

    python3 bench/bench_validate.py [--runs 400] [--repeat 3] [--workers N]
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time

from dynval import model as mdl
from dynval import synth
from dynval.validate import doe, featvec


def lanl() -> mdl.Model:
    return mdl.from_dict({
        "format": "dynval-model/1", "fs_hz": 640.0, "masses_kg": [6.54, 6.66, 6.86, 6.80],
        "stiffness_n_per_m": [10.0, 399790.0, 399790.0, 399790.0],
        "damping": {"type": "modal", "zeta": [0.01, 0.05, 0.01, 0.01]},
        "input": {"kind": "force", "dof": 1, "channel": "force_N"},
        "outputs": {f"acc{i}_mps2": {"kind": "acc", "dof": i} for i in range(1, 5)}})


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=400)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    m = lanl()
    rec = synth.make_experiments(m, 1, seed=0)[0]
    ranges = [doe.ParamRange("zeta2", 0.01, 0.08), doe.ParamRange("zeta4", 0.001, 0.02)]
    x = doe.latin_hypercube(ranges, a.runs, 0)
    sets = doe.as_sets(ranges, x)
    print(f"cores {os.cpu_count()}, load average {os.getloadavg()[0]:.2f}, runs {a.runs}, "
          f"{rec.n_samples} samples at {rec.fs_hz:g} Hz")
    bumper = dataclasses.replace(m, elements=(mdl.Contact(3, 4, 1e-4, 3e-4, 1.925e6),))
    cases = [(m, spec, over) for spec in ("peak,std@acc3,acc4",
                                          "peak,std,skew,kurt,tm_E,tm_T,tm_D@acc3,acc4",
                                          "segstd64@acc3,acc4") for over in (None, 1)]
    cases += [(bumper, "segstd64@acc3,acc4", None)]
    for mm, spec, over in cases:
        fs = featvec.parse(spec).resolve(rec.names)
        if True:
            job = doe.make_job(mm, [rec.channel("force_N").data], rec.fs_hz, fs, oversample=over,
                               rmse_refs={"acc4_mps2": rec.channel("acc4_mps2").data})
            times = []
            for _ in range(a.repeat):
                t0 = time.perf_counter()
                with doe.Runner(workers=a.workers) as rn:
                    res = rn.run(job, sets)
                times.append(time.perf_counter() - t0)
                assert not res.failed
            kind = "bumper" if mm.elements else "linear"
            print(f"{kind:<6} {spec:<44} oversample {over or m.oversample}: median {statistics.median(times):6.2f} s"
                  f"  (min {min(times):.2f}, max {max(times):.2f}; {len(fs.labels())} features)")


if __name__ == "__main__":
    main()
