"""Accelerometer offsets that change from test to test (an amplifier's drift, a DAQ re-zeroed
or warming up between tests, an offset that grows with the range in use).

An acceleration's mean over a record is the change of velocity over the record's length,
about zero for a structure that ends moving about as it started; so the mean of an
acceleration residual over one test is the sensor's offset in that test, not the structure's.
One offset per channel (loop._sensor_offsets) cannot follow offsets that change between
tests: what is left counts as residual and raises the error and its ratio to the noise floor.

A channel gets an offset per test when the per-test means of its residual differ by more than
the scatter of its block means within each test explains (a one-way analysis of variance,
P_VALUE): each test's mean of that channel is then left out of every comparison
(residual.predict), one number out of the thousands of samples in a test. Under 1/f noise
the block means are not independent and the analysis finds a change more often than P_VALUE
(4 of 24 channels with one offset for all tests: seeds 0-5 of the cheap DAQ in
tests/test_discover_offsets.py): the mean left out is then the noise's, which no structure
makes either.
"""
from __future__ import annotations

import importlib
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.discover.residual import TestData, residuals

log = logging.getLogger(__name__)
_stats: Any = importlib.import_module("scipy.stats")

BLOCKS = 8  # block means per test: the within-test scatter of a mean over 1/8 of a record
P_VALUE = 1e-3  # chance that offsets constant over the tests would differ this much


@dataclass(frozen=True)
class Spread:
    """The analysis of variance of one channel's residual means."""

    f: float  # between-test over within-test mean square of the block means
    p: float
    per_test: tuple[float, ...]  # each test's mean residual (channel units)


def analyse(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str]) -> dict[str, Spread]:
    """The spread of each acceleration channel's residual means under model m over whole
    tests (at least two, each with BLOCKS blocks), by channel. Empty when m cannot be
    simulated."""
    acc = [c for c in chans if m.outputs[c].kind == "acc"]
    if len(tests) < 2 or not acc:
        return {}
    res = [residuals(m, TestData(t.name, t.fs_hz, t.u, t.y, start=t.start,
                                    start_x0=t.start_x0), acc) for t in tests]
    if any(r is None or r[acc[0]].size < BLOCKS for r in res):
        return {}
    out = {}
    k = len(tests)
    for c in acc:
        blocks = np.array([[float(np.mean(b)) for b in np.array_split(r[c], BLOCKS)]
                           for r in res if r is not None])  # k x BLOCKS
        test_means = blocks.mean(axis=1)
        between = BLOCKS * float(np.sum((test_means - test_means.mean()) ** 2)) / (k - 1)
        within = float(np.sum((blocks - test_means[:, None]) ** 2)) / (k * (BLOCKS - 1))
        f = between / within if within > 0 else (np.inf if between > 0 else 0.0)
        p = float(_stats.f.sf(f, k - 1, k * (BLOCKS - 1))) if np.isfinite(f) else 0.0
        means = tuple(float(np.mean(r[c])) for r in res if r is not None)
        out[c] = Spread(float(f), p, means)
    return out


def apply(m: mdl.Model, tests: Sequence[TestData], views: Sequence[TestData],
          chans: Sequence[str]) -> list[str]:
    """Give the acceleration channels whose means change from test to test an offset per test
    (TestData.demean, with its mean residual under m) on the tests and on their views.
    Returns a note for the report, or none. Not an effect: the offsets are not the
    structure's and a new test has its own."""
    spread = analyse(m, tests, chans)
    varying = sorted(c for c, s in spread.items() if s.p < P_VALUE)
    if not varying:
        return []
    for i, t in enumerate(tests):
        offsets = {c: spread[c].per_test[i] for c in varying}
        for v in [t, *(v for v in views if v.y is t.y)]:  # a test's views share its records
            v.demean = offsets
    parts = [f"{c} ({min(spread[c].per_test):.3g} to {max(spread[c].per_test):.3g}, "
             f"F = {spread[c].f:.3g})" for c in varying]
    note = ("the mean residual of " + ", ".join(parts) + " changes from test to test more "
            "than within a test (p < " + f"{P_VALUE:g}): an accelerometer's mean over a test is "
            "its offset in that test, or its noise at 0 Hz (the structure's mean acceleration "
            "is about zero), so each test's mean of these channels is left out of every "
            "comparison")
    log.info("%s", note)
    return [note]
