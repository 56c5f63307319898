"""Same-run comparisons for the waveform-feature benchmarks: numpy on whole arrays."""
from __future__ import annotations

import time

import numpy as np

N = 16384


def _median_ns_per_sample(fn, x: np.ndarray, reps: int = 201) -> float:
    fn(x)  # warm-up
    t = []
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        fn(x)
        t.append((time.perf_counter_ns() - t0) / x.size)
    return float(np.median(t))


def _set(x: np.ndarray) -> float:
    # the per-channel set done the numpy way on one record: moments, 256-sample sliding RMS,
    # 64 segment STDs, temporal moments
    m = x.mean()
    d = x - m
    d2 = d * d
    v = d2.mean()
    sk = (d2 * d).mean() / v**1.5
    ku = (d2 * d2).mean() / v**2
    pk = np.abs(x).max()
    c = np.cumsum(np.concatenate(([0.0], x * x)))
    win = np.sqrt((c[256:] - c[:-256]) / 256)
    seg = x.reshape(64, -1).std(axis=1)
    w = x * x
    t = np.arange(x.size, dtype=float)
    e = w.sum()
    tc = (w * t).sum() / e
    dd = t - tc
    return float(sk + ku + pk + win[-1] + seg[0] + (w * dd * dd).sum() + tc)


def compare() -> list[dict]:
    rng = np.random.default_rng(12345)
    x = 3.0 + 2.0 * rng.standard_normal(N)
    return [
        {"case": "moments_block", "what": "numpy x.std() (one array, no streaming state)",
         "ns": _median_ns_per_sample(np.std, x), "unit": "sample"},
        {"case": "chan_set_block", "what": "numpy, the same feature set on one record",
         "ns": _median_ns_per_sample(_set, x), "unit": "sample"},
    ]
