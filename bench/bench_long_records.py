#!/usr/bin/env python3
"""Issue 21, long records: `dynval features` and `dynval residual` on a 1-hour test with 16
channels at 2 kHz (7.2e6 samples per channel, 922 MB of float64 in an HDF5 file), each in its
own process under /usr/bin/time: wall time and peak resident memory (target: below 2 GB).
Writes bench/RESULTS.long.md. Usage (needs h5py and ../shared beside the repository):

    PYTHONPATH=gateway/src python3 bench/bench_long_records.py [--hours 1] [--out FILE]
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT.parent / "shared" / "data" / "synthetic" / "lanl4dof-clean" / "declared_model.json"
FS = 2000.0


def write_test(path: Path, hours: float) -> int:
    """A force and 15 accelerations of white noise (the commands' cost does not depend on the
    values); acc1-acc4 are the declared model's outputs."""
    n = int(hours * 3600 * FS)
    rng = np.random.default_rng(0)
    with h5py.File(path, "w") as f:
        f.attrs["fs_hz"] = FS
        f.create_dataset("force_N", data=rng.standard_normal(n)).attrs["unit"] = "N"
        for k in range(1, 16):
            f.create_dataset(f"acc{k}_mps2", data=rng.standard_normal(n)).attrs["unit"] = "m/s^2"
    return n


def timed(args: list[str]) -> tuple[float, float]:
    """(wall s, peak RSS MB) of one dynval command."""
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "dynval", "-q", *args]
    p = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ}, check=False)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(args)}: exit {p.returncode}\n{p.stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", p.stderr)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)
    assert wall and rss
    parts = [float(x) for x in wall.group(1).split(":")]
    secs = sum(v * 60 ** i for i, v in enumerate(reversed(parts)))
    return secs, int(rss.group(1)) / 1024


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS.long.md"))
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        test = Path(tmp) / "long16.h5"
        n = write_test(test, a.hours)
        mb = test.stat().st_size / 2**20
        for what, args in (("features (16 channels)", ["features", str(test), "--json"]),
                           ("residual (4-DOF model, 4 of the channels)",
                            ["residual", str(MODEL), str(test)])):
            secs, rss = timed(args)
            rows.append(f"| {what} | {secs:.1f} | {secs / a.hours:.1f} | {rss:.0f} | "
                        f"{'yes' if rss < 2048 else '**no**'} |")
            print(rows[-1], flush=True)  # noqa: T201 (a benchmark's table)
    text = ("# Long records (issue 21)\n\n"
            f"`python3 bench/bench_long_records.py`: a {a.hours:g}-hour test, 16 channels at "
            f"{FS:g} Hz ({n} samples each, HDF5 file {mb:.0f} MB), each command in its own "
            "process; peak memory is /usr/bin/time's maximum resident set size.\n\n"
            "| command | wall s | s per hour of data | peak RSS MB | below 2 GB |\n"
            "|---|---:|---:|---:|---|\n" + "\n".join(rows) + "\n")
    Path(a.out).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
