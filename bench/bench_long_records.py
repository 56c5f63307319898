#!/usr/bin/env python3
"""Issue 21, long records: `dynval features`, `residual`, `validate` and `discover` on a 1-hour
test with 16 channels at 2 kHz (7.2e6 samples per channel, 922 MB of float64 in an HDF5 file),
each in its own process under /usr/bin/time: wall time and peak resident memory (target: below
2 GB). Writes bench/RESULTS.long.md. Usage (needs h5py and ../shared beside the repository):

    PYTHONPATH=gateway/src python3 bench/bench_long_records.py [--hours 1] [--out FILE]
        [--only features,residual,validate,discover] [--keep DIR]

--keep DIR writes the test there once and reuses it (the rows of one run share one file).
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT.parent / "shared" / "data" / "synthetic" / "lanl4dof-clean" / "declared_model.json"
FS = 2000.0


def write_test(path: Path, hours: float, seed: int = 0) -> int:
    """A white-noise force, acc1-acc4 the declared model's response to it with 1 % noise (so
    validate and discover see a model that explains the test), acc5-acc15 white noise."""
    from dynval import model as mdl

    n = int(hours * 3600 * FS)
    rng = np.random.default_rng(seed)
    force = rng.standard_normal(n)
    m = mdl.load(MODEL)
    with h5py.File(path, "w") as f:
        f.attrs["fs_hz"] = FS
        f.create_dataset("force_N", data=force).attrs["unit"] = "N"
        for k, y in enumerate(mdl.simulate(m, force, FS).values(), start=1):
            y += 0.01 * np.std(y) * rng.standard_normal(n)
            f.create_dataset(f"acc{k}_mps2", data=y).attrs["unit"] = "m/s^2"
        for k in range(5, 16):
            f.create_dataset(f"acc{k}_mps2", data=rng.standard_normal(n)).attrs["unit"] = "m/s^2"
    return n


def commands(test: Path, test2: Path, out: Path) -> dict[str, tuple[str, list[str], int]]:
    """name -> (table label, dynval arguments, tests read: validate needs two)."""
    return {
        "features": ("features (16 channels)", ["features", str(test), "--json"], 1),
        "residual": ("residual (4-DOF model, 4 of the channels)",
                     ["residual", str(MODEL), str(test)], 1),
        "validate": ("validate (two such tests; std @ acc4; zeta2 uncertain, 20 LHS runs, "
                     "2 workers)",
                     ["validate", "--model", str(MODEL), "--experiments", str(test), str(test2),
                      "--features", "std@acc4", "--param",
                      "zeta2=0.01:0.08", "--runs", "20", "--workers", "2",
                      "--json", str(out / "validate.json")], 2),
        "discover": ("discover (4-DOF declared model, 2 workers)",
                     ["discover", str(MODEL), str(test), "--workers", "2",
                      "--json", str(out / "discover.json")], 1),
    }


def _tree(root: int) -> list[int]:
    """root and its descendants (from /proc/*/stat's parent ids)."""
    parent: dict[int, int] = {}
    for d in Path("/proc").iterdir():
        try:
            stat = (d / "stat").read_text()
            parent[int(d.name)] = int(stat[stat.rindex(")") + 2:].split()[1])
        except (ValueError, OSError):
            continue
    out, todo = [], [root]
    while todo:
        p = todo.pop()
        out.append(p)
        todo += [c for c, pp in parent.items() if pp == p]
    return out


def _kb(pid: int, path: str, field: str) -> int:
    try:
        for line in Path(f"/proc/{pid}/{path}").read_text().splitlines():
            if line.startswith(field):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def timed(args: list[str]) -> tuple[float, float, float, float]:
    """(wall s, peak RSS MB of the largest process, peak of the sum of RSS over the command's
    process tree MB, peak of the sum of PSS MB: shared pages counted once) of one dynval
    command; the tree is sampled every 0.5 s."""
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "dynval", "-q", *args]
    tree_rss = tree_pss = 0.0
    with tempfile.TemporaryFile("w+") as err:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, text=True)
        while p.poll() is None:
            pids = _tree(p.pid)[1:]  # not /usr/bin/time itself
            tree_rss = max(tree_rss, sum(_kb(q, "status", "VmRSS:") for q in pids) / 1024)
            tree_pss = max(tree_pss, sum(_kb(q, "smaps_rollup", "Pss:") for q in pids) / 1024)
            time.sleep(0.5)
        err.seek(0)
        stderr = err.read()
    if p.returncode not in (0, 1, 4):  # a model that fails (1) or an inconclusive verdict (4)
        raise SystemExit(f"{' '.join(args)}: exit {p.returncode}\n{stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", stderr)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", stderr)
    assert wall and rss
    parts = [float(x) for x in wall.group(1).split(":")]
    secs = sum(v * 60 ** i for i, v in enumerate(reversed(parts)))
    return secs, int(rss.group(1)) / 1024, tree_rss, tree_pss


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS.long.md"))
    ap.add_argument("--only", default="features,residual,validate,discover")
    ap.add_argument("--keep", type=Path, default=None)
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        where = a.keep or Path(tmp)
        where.mkdir(parents=True, exist_ok=True)
        test = where / f"long16_{a.hours:g}h.h5"
        test2 = where / f"long16_{a.hours:g}h_b.h5"
        cmds = commands(test, test2, Path(tmp))
        only = a.only.split(",")
        for path, seed in ((test, 0), (test2, 1)):
            if not path.is_file() and (path == test or "validate" in only):
                write_test(path, a.hours, seed)
        n = int(a.hours * 3600 * FS)
        mb = test.stat().st_size / 2**20
        for name in only:
            what, args, k = cmds[name]
            secs, rss, tree, pss = timed(args)
            rows.append(f"| {what} | {secs:.1f} | {secs / (k * a.hours):.1f} | {rss:.0f} | "
                        f"{tree:.0f} | {pss:.0f} | {'yes' if tree < 2048 else '**no**'} |")
            print(rows[-1], flush=True)  # noqa: T201 (a benchmark's table)
    text = ("# Long records (issue 21)\n\n"
            f"`python3 bench/bench_long_records.py`: a {a.hours:g}-hour test, 16 channels at "
            f"{FS:g} Hz ({n} samples each, HDF5 file {mb:.0f} MB), each command in its own "
            "process; peak memory is /usr/bin/time's maximum resident set size (the largest "
            "process) and, sampled every 0.5 s over the command's processes (workers "
            "included), the peak of their summed RSS and of their summed PSS (pages shared "
            "between processes counted once: the memory the command takes).\n\n"
            "| command | wall s | s per hour of data | peak RSS MB (largest process) | "
            "peak sum of RSS MB | peak sum of PSS MB | below 2 GB |\n"
            "|---|---:|---:|---:|---:|---:|---|\n" + "\n".join(rows) + "\n")
    Path(a.out).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
