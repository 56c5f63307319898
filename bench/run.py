#!/usr/bin/env python3
"""Run every benchmark and write bench/RESULTS.md: the one place for the project's figures.

    python3 bench/run.py            # build (Release, float and double), run, write RESULTS.md
    python3 bench/run.py --quick    # fewer repeats (smoke run, e.g. in CI)

Each bench/bench_<mod>.c program follows one protocol: `--list` prints its cases, `CASE REPS`
prints `case=CASE units=U unit=UNIT ns=X` (median ns per unit over REPS). Times are medians of
several processes (this host is shared and noisy); instruction counts come from valgrind
callgrind as the difference between two REPS values (setup cancels), which is repeatable.
bench/compare_<mod>.py modules give the same-run comparisons (numpy/scipy), and
bench/targets.json the targets each figure is judged against. Sections measured by their own
scripts (bench/RESULTS.<topic>.md: the Cortex-M4 memory budget, the gateway, validation) are
appended as they are.
"""
from __future__ import annotations

import argparse
import datetime as dt
import importlib.util
import json
import logging
import os
import platform
import re
import statistics
import subprocess
import sys
from pathlib import Path

from measure import instructions  # bench/ is the script's folder

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench"
log = logging.getLogger("bench")
PEAK_FLOPS_PER_CYCLE = 32  # double, 2 x 512-bit FMA per cycle (8 lanes x 2 flops x 2 units)
LINE = re.compile(r"case=(\S+) units=(\d+) unit=(\S+) ns=([0-9.eE+-]+)")


def build(real: str) -> Path:
    bdir = ROOT / "build" / f"bench-{'f64' if real == 'double' else 'f32'}"
    subprocess.run(["cmake", "-S", str(ROOT), "-B", str(bdir), "-DCMAKE_BUILD_TYPE=Release",
                    f"-DDV_REAL_TYPE={real}", "-DDV_BUILD_TESTS=OFF", "-DDV_BUILD_BENCH=ON",
                    "-DDV_BUILD_SIM=ON"],
                   check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(bdir), "-j2"], check=True, stdout=subprocess.DEVNULL)
    return bdir


def run_case(exe: Path, case: str, reps: int) -> tuple[int, str, float]:
    out = subprocess.run([str(exe), case, str(reps)], check=True, capture_output=True,
                         text=True).stdout
    m = LINE.search(out)
    if m is None:
        raise RuntimeError(f"{exe.name} {case}: no result line in {out!r}")
    return int(m.group(2)), m.group(3), float(m.group(4))


def clock_ghz(bdir: Path) -> float:
    """Effective core clock now: median over 5 processes of bench_clock (3-cycle multiplies)."""
    ns = [run_case(bdir / "bench" / "bench_clock", "clock_imul_chain", 9)[2] for _ in range(5)]
    return 3.0 / statistics.median(ns)


def load_compare(mod_file: Path) -> list[dict]:
    spec = importlib.util.spec_from_file_location(mod_file.stem, mod_file)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return list(mod.compare())


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="few repeats: a smoke run")
    ap.add_argument("--out", type=Path, default=BENCH / "RESULTS.md")
    ap.add_argument("--only", default="", help="comma-separated bench program names")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    # cases on the bundled test data (bench_obs: the bumper test) when ../shared is beside us
    data = ROOT.parent / "shared" / "data"
    if data.is_dir():
        os.environ.setdefault("DV_BENCH_DATA", str(data))
    procs, reps = (1, 5) if args.quick else (5, 31)
    targets = json.loads((BENCH / "targets.json").read_text()) if (BENCH / "targets.json").exists() else {}

    rows: dict[str, list[dict]] = {}
    sizes: list[str] = []
    clock: list[float] = []  # GHz, measured before the first and after the last benchmark
    jobs: list[tuple[str, Path, str]] = []  # (real, program, case)
    for real in ("double", "float"):
        bdir = build(real)
        # bench/ holds the library's benchmarks, firmware_sim/ the firmware loop's
        for exe in sorted([*bdir.glob("bench/bench_*"), *bdir.glob("firmware_sim/bench_*")]):
            if not os.access(exe, os.X_OK) or exe.suffix:
                continue
            if exe.name == "bench_clock" or (args.only and exe.name not in args.only.split(",")):
                continue
            cases = subprocess.run([str(exe), "--list"], capture_output=True, text=True,
                                   check=True).stdout.split()
            sz = subprocess.run([str(exe), "--sizes"], capture_output=True, text=True)
            if sz.returncode == 0:
                for line in sz.stdout.splitlines():
                    sizes.append(f"| {exe.name} | {real} | {line} |")
            jobs += [(real, exe, case) for case in cases]
    clock.append(clock_ghz(ROOT / "build" / "bench-f64"))
    # Rounds over every case rather than one case's processes back to back: the host's slow
    # periods last seconds to minutes, so each case's processes land in different periods and
    # the median is not one period's figure.
    ns: dict[int, list[float]] = {k: [] for k in range(len(jobs))}
    meta: dict[int, tuple[int, str]] = {}
    for rnd in range(procs):
        log.info("round %d of %d", rnd + 1, procs)
        for k, (real, exe, case) in enumerate(jobs):
            units, unit, v = run_case(exe, case, reps)
            ns[k].append(v)
            meta[k] = (units, unit)
    for k, (real, exe, case) in enumerate(jobs):
        log.info("%s %s %s: instructions", real, exe.name, case)
        units, unit = meta[k]
        instr = instructions(exe, case, units)
        rows.setdefault(exe.name, []).append(
            {"case": case, "real": real, "unit": unit, "ns": statistics.median(ns[k]),
             "ns_min": min(ns[k]), "ns_max": max(ns[k]), "instr": instr})

    clock.append(clock_ghz(ROOT / "build" / "bench-f64"))
    comps: dict[str, list[dict]] = {}
    for f in sorted(BENCH.glob("compare_*.py")):
        try:
            for c in load_compare(f):
                comps.setdefault(c["case"], []).append(c)
        except Exception as exc:  # a comparison that cannot run is reported, not hidden
            log.warning("%s failed: %s", f.name, exc)
            comps.setdefault("_failed", []).append({"what": f"{f.name}: {exc}"})

    out = ["# dynval benchmark results", "",
           f"Generated by `python3 bench/run.py` on {dt.date.today().isoformat()}; host: "
           f"{cpu_name()}, {os.cpu_count()} cores, {platform.system()} {platform.release()}.",
           f"Times: median of per-process medians (ns per unit; min-max over processes in "
           f"brackets), {procs} processes per case run in {procs} rounds over all the cases, so "
           f"they fall in different periods of this shared, noisy host. Instructions: valgrind "
           f"callgrind, per unit, the stable figure. Comparisons are measured in the same run.",
           f"Effective clock seen by one thread (bench/bench_clock.c: a chain of dependent "
           f"integer multiplies, 3 cycles each): {clock[0]:.2f} GHz before the benchmarks, "
           f"{clock[-1]:.2f} GHz after them (about 2.9 GHz when the host is quiet). A lower "
           f"figure means other processes shared the cores during the run. It does not catch "
           f"every slow period: the same binary has also run 1.4-1.6x slower at a normal "
           f"figure (a busy sibling thread or memory system), which the min-max ranges show.",
           f"Compute bound: the case's floating-point operations (bench/targets.json: flops, the "
           f"arithmetic of the cheapest known formulation) at this core's peak in double, "
           f"{PEAK_FLOPS_PER_CYCLE} flops per cycle (two AVX-512 fused multiply-add units), at "
           f"{clock[-1]:.2f} GHz. A floor, not a goal: latency-bound code (a recursion) and "
           f"memory traffic stay above it.", ""]
    for prog, rs in rows.items():
        notes: list[str] = []
        out += [f"## {prog}", "", "| case | real | ns/unit [min-max] | instr/unit | compute bound "
                "| target | met |", "|---|---|---|---|---|---|---|"]
        for r in rs:
            tgt = targets.get(r["case"], {}).get(r["real"])
            met = ""
            tdesc = ""
            if tgt:
                parts, ok = [], True
                if "ns" in tgt:
                    parts.append(f"<= {tgt['ns']} ns")
                    ok = ok and r["ns"] <= tgt["ns"]
                if "instr" in tgt and r["instr"] is not None:
                    parts.append(f"<= {tgt['instr']} instr")
                    ok = ok and r["instr"] <= tgt["instr"]
                tdesc, met = ", ".join(parts), ("yes" if ok else "**no**")
            instr = f"{r['instr']:.1f}" if r["instr"] is not None else "n/a"
            flops = targets.get(r["case"], {}).get(r["real"], {}).get("flops")
            bound = f"{flops / (PEAK_FLOPS_PER_CYCLE * clock[-1]):.3g} ns" if flops else ""
            out.append(f"| {r['case']} | {r['real']} | {r['ns']:.2f} [{r['ns_min']:.2f}-"
                       f"{r['ns_max']:.2f}] /{r['unit']} | {instr} | {bound} | {tdesc} | {met} |")
            if tgt and tgt.get("note") and met != "yes":
                notes.append(f"- {r['case']} ({r['real']}): {tgt['note']}")
            # a comparison row names its precision ("real"); rows without one are double's
            same_real = [c for c in comps.get(r["case"], [])
                         if c.get("real", "double") == r["real"]]
            for c in same_real:
                extra = "".join(f", {k} {v:.3g}" for k, v in c.items()
                                if k not in ("case", "what", "ns", "unit") and isinstance(v, float))
                out.append(f"| ↳ comparison: {c['what']} | {r['real']} | {c['ns']:.2f} /{c['unit']}"
                           f" | | | dynval is {c['ns'] / r['ns']:.3g}x as fast{extra} | |")
        out.append("")
        if notes:
            out += ["Notes on targets not met:", "", *notes, ""]
    if sizes:
        out += ["## State sizes", "", "| program | real | size |", "|---|---|---|", *sizes, ""]
    for c in comps.get("_failed", []):
        out.append(f"- comparison not run: {c['what']}")
    # Figures measured by their own scripts (each file says how to regenerate it):
    # RESULTS.m4.md (tests/m4/mem_budget.py), RESULTS.gateway.md, RESULTS.validate.md, ...
    for extra in sorted(BENCH.glob("RESULTS.*.md")):
        out += ["", f"<!-- from bench/{extra.name} -->", extra.read_text().rstrip()]
    args.out.write_text("\n".join(out) + "\n")
    log.info("wrote %s", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
