"""Long records in discover: a bounded sample of each test.

discover simulates every test hundreds of times (each candidate's fit, its reference, the
evidence views) and keeps residuals and initial-state bases per sample, so its time and
memory grow with the record. A test longer than BUDGET_SAMPLES is replaced by at most
BUDGET_SAMPLES / length evenly spaced segments (the first at the record's start, the last at
its end), each a test of its own. A segment after the first does not start at rest:
discover/initial.py estimates its initial state (always: a lightly restrained structure's
slow mode moves through the whole segment, which initial.py's guard would take for an
effect's residual), and each segment is at least twice the structure's settling time (the
start window initial.py fits, and as long again after it).
Every cut is a note in the result (and a warning in the log), never silent.

The budget: the discover bench cases (10 tests x 8192 samples) take 15-70 s on two cores;
65536 samples keeps one hour-long test in that range and its per-sample arrays (residuals,
predictions, the initial-state bases of 2 n_dof columns per channel) near 100 MB.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from dynval.discover.residual import TestData
from dynval.io.arrays import release_pages

log = logging.getLogger(__name__)

BUDGET_SAMPLES = 65536  # samples per test discover fits on
MIN_SEGMENT = 8192  # shortest segment: a few hundred periods of a 30 Hz mode at 2 kHz


def plan(n: int, settle: int, budget: int | None = None, min_len: int | None = None
         ) -> tuple[np.ndarray, int] | None:
    """(segment starts, segment length) for a record of n samples, or None when the record
    is within the budget (or too short to cut into two segments)."""
    budget = BUDGET_SAMPLES if budget is None else budget
    min_len = MIN_SEGMENT if min_len is None else min_len
    length = max(min_len, 2 * settle)
    k = max(2, budget // length)
    if n <= budget or k * length >= n:
        return None
    return np.linspace(0, n - length, k).round().astype(np.int64), length


def bound(tests: Sequence[TestData], settle: int) -> tuple[list[TestData], list[str]]:
    """The tests discover fits on, each long one cut into segments (copies, so a memory-mapped
    record's pages are let go), and a note per cut test."""
    out: list[TestData] = []
    notes: list[str] = []
    for t in tests:
        p = plan(t.u.size, settle)
        if p is None:
            out.append(t)
            continue
        starts, length = p
        for s in starts:
            cut = slice(int(s), int(s) + length)
            out.append(TestData(f"{t.name} @{s / t.fs_hz:.1f}s", t.fs_hz, np.array(t.u[cut]),
                                {c: np.array(v[cut]) for c, v in t.y.items()}, moving=s > 0))
        for a in (t.u, *t.y.values()):
            release_pages(a)
        notes.append(f"{t.name}: {t.u.size / t.fs_hz:,.0f} s long; discover used {starts.size} "
                     f"evenly spaced segments of {length} samples "
                     f"({100 * starts.size * length / t.u.size:.1f} %), each its own test with "
                     "its initial state estimated")
        log.warning("%s", notes[-1])
    return out, notes
