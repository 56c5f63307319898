#!/usr/bin/env python3
"""Issue 16 speed figure: `dynval discover` on cases of 10 tests x 8192 samples with up to 6
channels, the shake-table input and a best-linear declared model included, report included
(JSON and the HTML page with its figures), wall time per case; target: under 60 s each on
the 2-core CI machine. Writes bench/RESULTS.discover.md. Usage:

    python3 bench/bench_discover.py [--repeat 1] [--only TEXT] [--daq] [--out FILE]

``--daq``: every declared model states the generator's anti-alias filter (8th-order
Butterworth at 0.4 fs: simulation.daq_filter).
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from dynval import model as mdl
from dynval import synth
from dynval.discover import loop, report
from dynval.io.recording import Recording

ROOT = Path(__file__).resolve().parent.parent


def chain(n: int, kind: str = "force") -> mdl.Model:
    masses = tuple(6.5 + 0.1 * i for i in range(n))
    ks = (10.0 if kind == "force" else 399790.0,) + (399790.0,) * (n - 1)
    return mdl.Model(masses_kg=masses, stiffness_n_per_m=ks,
                     damping=mdl.Damping("modal", (0.01, 0.05) + (0.01,) * (n - 2)),
                     input=mdl.Input(kind, 1 if kind == "force" else 0,
                                     "force_N" if kind == "force" else "table_mps2"),
                     outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, n + 1)},
                     fs_hz=640.0)


def cases() -> dict[str, Callable[[], tuple[mdl.Model, list[Recording]]]]:
    def bumper4() -> tuple[mdl.Model, list[Recording]]:
        m = chain(4)
        el = mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6)
        return m, synth.generate(m, synth.Truth(elements=(el,)), n_tests=10, seed=1)

    def cubic6() -> tuple[mdl.Model, list[Recording]]:
        m = chain(6)
        el = mdl.CubicSpring(4, 5, 4e12)
        return m, synth.generate(m, synth.Truth(elements=(el,)), n_tests=10, seed=2)

    def table_joint4() -> tuple[mdl.Model, list[Recording]]:
        m = chain(4, "ground_acc")
        el = mdl.Friction(1, 2, 2.0, 1e-4)
        return m, synth.generate(m, synth.Truth(elements=(el,)), n_tests=10, seed=3,
                                 levels_n_rms=(3.0, 1.8))

    def best_linear_cubic4() -> tuple[mdl.Model, list[Recording]]:
        m = chain(4)
        recs = synth.generate(m, synth.Truth(elements=(mdl.CubicSpring(2, 3, 5e12),)),
                              n_tests=10, seed=4)
        return synth.best_linear(m, recs), recs

    def sweep_table_contact(n: int, seed: int) -> tuple[mdl.Model, list[Recording]]:
        m = chain(n, "ground_acc")
        recs = synth.generate(m, synth.Truth(elements=(mdl.Contact(1, 2, 1.5e-4, 5e-5, 8e5),)),
                              n_tests=10, seed=seed, levels_n_rms=(3.0, 1.8),
                              excitation=synth.Sweep(8.0, 200.0))
        return synth.best_linear(m, recs), recs

    def appendage4() -> tuple[mdl.Model, list[Recording]]:
        m = chain(4)
        app = synth.Appendage(3, 0.4, 45.0, 0.02)
        return m, synth.generate(m, synth.Truth(appendages=(app,)), n_tests=10, seed=5)

    def stage() -> tuple[mdl.Model, list[Recording]]:
        m = mdl.Model(masses_kg=(5.0, 1.0), stiffness_n_per_m=(0.0, 2.0e4),
                      damping=mdl.Damping("modal", (0.0, 0.02)),
                      input=mdl.Input("force", 1, "force_N"),
                      outputs={"x1_m": mdl.Output("disp", 1), "a1_mps2": mdl.Output("acc", 1),
                               "a2_mps2": mdl.Output("acc", 2)}, fs_hz=640.0)
        els = (mdl.Friction(0, 1, 1.3, 1e-3), mdl.ConstantForce(0, 1, -0.6))
        return m, synth.generate(m, synth.Truth(elements=els), n_tests=10, seed=6)

    return {"4-DOF force, bumper story 4": bumper4,
            "4-DOF force, appendage at DOF 3 (45 Hz)": appendage4,
            "positioning stage, friction + force offset (observer)": stage,
            "6-DOF force, 6 channels, cubic spring 4-5": cubic6,
            "4-DOF shake table, friction joint 1-2": table_joint4,
            "4-DOF best-linear declared model, cubic spring 2-3": best_linear_cubic4,
            "4-DOF shake table, swept sine 8-200 Hz, best-linear, contact 1-2":
                lambda: sweep_table_contact(4, 7),
            "6-DOF shake table, swept sine 8-200 Hz, best-linear, contact 1-2":
                lambda: sweep_table_contact(6, 8)}


def run_case(m: mdl.Model, recs: list[Recording], folder: Path) -> tuple[float, str]:
    t0 = time.perf_counter()
    r = loop.discover(m, recs)
    doc = report.to_json(r)
    report.write_json(doc, folder / "d.json")
    report.write_html(r, doc, folder / "d.html")
    return time.perf_counter() - t0, "; ".join(e["label"] for e in r.effects) or "no effect"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--only", default="", help="run the cases whose name holds this text")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS.discover.md"))
    ap.add_argument("--daq", action="store_true",
                    help="the declared models state the generator's anti-alias filter")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in cases().items():
            if a.only not in name:
                continue
            m, recs = make()
            if a.daq:  # synth.daq_filter("butter8")'s analog twin
                m = dataclasses.replace(m, daq_filter=mdl.DaqFilter("butterworth", 8,
                                                                    0.4 * (m.fs_hz or 640.0)))
            times, found = [], ""
            for _ in range(a.repeat):
                t, found = run_case(m, recs, Path(tmp))
                times.append(t)
            chans = len(m.outputs)
            rows.append(f"| {name} | {len(recs)} x {recs[0].n_samples} x {chans} | "
                        f"{statistics.median(times):.1f} | {max(times):.1f} | {found} |")
            print(rows[-1], flush=True)  # noqa: T201 (a benchmark's table)
    text = ("# discover: wall time per case (issue 16 target: < 60 s, report included)\n\n"
            f"Median of {a.repeat} run(s) per case; `python3 bench/bench_discover.py`.\n\n"
            "| case | tests x samples x channels | median s | max s | effects found |\n"
            "|---|---|---:|---:|---|\n" + "\n".join(rows) + "\n")
    Path(a.out).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
