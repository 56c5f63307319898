"""What the benchmark scripts measure the same way (run.py and the compare_*.py modules):
callgrind instructions per unit of a bench program's case, and the median time per unit of a
Python callable."""
from __future__ import annotations

import re
import shutil
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path


def instructions(exe: Path, case: str, units: int) -> float | None:
    """Instructions per unit of ``exe case`` under valgrind callgrind (None without valgrind or
    on a failed run): the difference between 3 and 1 REPS, as the program runs one warm-up plus
    REPS timed runs, so set-up cancels and 2 runs of the case remain."""
    if shutil.which("valgrind") is None:
        return None
    counts = []
    for reps in (1, 3):
        r = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                            str(exe), case, str(reps)], capture_output=True, text=True)
        m = re.search(r"Collected : (\d+)", r.stderr)
        if r.returncode != 0 or m is None:
            return None
        counts.append(int(m.group(1)))
    return (counts[1] - counts[0]) / (2 * units)


def median_ns(fn: Callable[[], object], units: int, reps: int, warm: int = 3) -> float:
    """Median ns per unit of ``fn()`` over ``reps`` calls after ``warm`` warm-up calls."""
    for _ in range(warm):
        fn()
    t = []
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        fn()
        t.append((time.perf_counter_ns() - t0) / units)
    return float(statistics.median(t))
