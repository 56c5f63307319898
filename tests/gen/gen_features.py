#!/usr/bin/env python3
"""Golden vectors for the waveform features (moments, sliding, segstd, temporal, corr).

Writes tests/data/features_<case>.csv (one sample per line, %.17g) and
tests/data/features_expected.csv (case,feature,value), all computed two-pass in float64 with
numpy/scipy, independent of dynval. Run: python3 tests/gen/gen_features.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal, stats

OUT = Path(__file__).resolve().parent.parent / "data"
FS = 640.0
WIN = 256
SEG_LEN = 64
N_SEG = 64


def cases() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(20261121)
    n = SEG_LEN * N_SEG  # 4096, the report's record
    b, a = signal.butter(4, [20.0, 200.0], btype="bandpass", fs=FS)
    random_bl = signal.lfilter(b, a, rng.standard_normal(n + 512))[512:] * 3.0
    t = np.arange(n) / FS
    decay = np.exp(-4.0 * t) * np.sin(2 * np.pi * 30.0 * t) * 5.0 + 0.01 * rng.standard_normal(n)
    skewed = rng.gamma(2.0, 1.5, n) - 1.0
    offset = 1.0e4 + rng.standard_normal(n)
    return {"random": random_bl, "decay": decay, "skewed": skewed, "offset": offset}


def feature_rows(name: str, x: np.ndarray) -> list[tuple[str, str, float]]:
    rows: list[tuple[str, str, float]] = []

    def basic(prefix: str, v: np.ndarray) -> None:
        rms = float(np.sqrt(np.mean(v * v)))
        peak = float(np.max(np.abs(v)))
        rows.extend([
            (name, f"{prefix}mean", float(np.mean(v))),
            (name, f"{prefix}std", float(np.std(v))),
            (name, f"{prefix}var", float(np.var(v))),
            (name, f"{prefix}rms", rms),
            (name, f"{prefix}skew", float(stats.skew(v))),
            (name, f"{prefix}kurt", float(stats.kurtosis(v, fisher=False))),
            (name, f"{prefix}peak", peak),
            (name, f"{prefix}min", float(np.min(v))),
            (name, f"{prefix}max", float(np.max(v))),
            (name, f"{prefix}crest", peak / rms),
            (name, f"{prefix}kfactor", peak * rms),
        ])

    basic("rec_", x)
    basic("win_", x[-WIN:])
    seg = x.reshape(N_SEG, SEG_LEN).std(axis=1)
    rows.extend((name, f"segstd_{i}", float(v)) for i, v in enumerate(seg))
    dt = 1.0 / FS
    t = np.arange(x.size) * dt
    w = x * x
    m0 = np.sum(w)
    tc = np.sum(t * w) / m0
    d = np.sqrt(np.sum((t - tc) ** 2 * w) / m0)
    s = np.cbrt(np.sum((t - tc) ** 3 * w) / m0)
    k = (np.sum((t - tc) ** 4 * w) / m0) ** 0.25
    e = m0 * dt
    rows.extend([
        (name, "tm_energy", float(e)),
        (name, "tm_time", float(tc)),
        (name, "tm_duration", float(d)),
        (name, "tm_skew", float(s)),
        (name, "tm_kurt", float(k)),
        (name, "tm_amp", float(np.sqrt(e / d))),
    ])
    return rows


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    all_rows: list[tuple[str, str, float]] = []
    cs = cases()
    for name, x in cs.items():
        np.savetxt(OUT / f"features_{name}.csv", x, fmt="%.17g")
        all_rows.extend(feature_rows(name, x))
    # Correlation of two channels: random vs a lagged, noisy copy of itself.
    y = np.roll(cs["random"], 3) * 0.7 + cs["skewed"] * 0.5
    np.savetxt(OUT / "features_corr_y.csv", y, fmt="%.17g")
    all_rows.append(("random", "corr_y", float(np.corrcoef(cs["random"], y)[0, 1])))
    with open(OUT / "features_expected.csv", "w", encoding="ascii") as f:
        f.write("case,feature,value\n")
        for c, feat, v in all_rows:
            f.write(f"{c},{feat},{v:.17g}\n")


if __name__ == "__main__":
    main()
