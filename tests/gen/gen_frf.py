#!/usr/bin/env python3
"""Golden vectors for the streaming Welch FRF / coherence estimator (dv_frf).

A second-order resonance (poles of a continuous mode fn, zeta mapped with z = exp(s/fs)) driven
by white noise, with independent noise on the output, both quantised to 16-bit ADC counts so that
the float and the double builds read exactly the numbers scipy saw.

Writes
  tests/data/frf_u.csv, frf_y.csv       input and output, one integer count per line
  tests/data/frf_ref_<case>.csv         one row per bin k = 0..SEG/2:
                                        "Guu Gyy Re(Guy) Im(Guy) coherence", space separated
  tests/data/frf_expected.csv           case,feature,value: fs, seg_len, hop, fn, zeta, n_seg,
                                        and the peak and half-power points of scipy's |H1| (Hz)
References are scipy.signal.welch / csd / coherence with window='hann', nperseg=SEG,
noverlap=SEG-hop, detrend=False, scaling='density', one-sided (Guy = csd(u, y) = E[conj(U) Y]),
independent of dynval. Run: python3 tests/gen/gen_frf.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

OUT = Path(__file__).resolve().parent.parent / "data"
FS = 1024.0
SEG = 512  # df = 2 Hz
FN = 100.0
ZETA = 0.05  # half-power band 2 zeta fn = 10 Hz = 5 bins
N_SEG_50 = 48  # 50 % overlap segments in the record
N = SEG // 2 * (N_SEG_50 + 1) + 100  # 100 trailing samples that complete no segment
CASES = {"ov50": SEG // 2, "ov0": SEG}  # case -> hop


def system() -> tuple[np.ndarray, np.ndarray]:
    wn = 2.0 * np.pi * FN
    s = complex(-ZETA * wn, wn * np.sqrt(1.0 - ZETA * ZETA))
    z = np.exp(s / FS)
    a = np.array([1.0, -2.0 * z.real, abs(z) ** 2])
    b = np.array([0.0, 1.0, 0.0]) * a.sum()  # unit static gain
    return b, a


def half_power(m: np.ndarray) -> tuple[float, float, float]:
    """Peak (3-point parabola vertex) and half-power points (in bins) of the largest |H1| bin,
    |H1| linearly interpolated between bins, the threshold 1/sqrt(2) of the vertex's value."""
    k = int(np.argmax(m))
    a, b, c = m[k - 1], m[k], m[k + 1]
    p = 0.5 * (a - c) / (a - 2 * b + c)
    thr = (b - 0.25 * (a - c) * p) / np.sqrt(2.0)
    j = k
    while m[j - 1] > thr:
        j -= 1
    f1 = j - (m[j] - thr) / (m[j] - m[j - 1])
    j = k
    while m[j + 1] > thr:
        j += 1
    f2 = j + (m[j] - thr) / (m[j] - m[j + 1])
    return float(k + p), float(f1), float(f2)


def main() -> None:
    rng = np.random.default_rng(20261125)
    b, a = system()
    u = rng.standard_normal(N + 2000) * 2000.0
    y = signal.lfilter(b, a, u)[2000:] + rng.standard_normal(N) * 300.0
    u = u[2000:]
    u = np.clip(np.round(u), -32768, 32767)
    y = np.clip(np.round(y), -32768, 32767)
    OUT.mkdir(parents=True, exist_ok=True)
    np.savetxt(OUT / "frf_u.csv", u, fmt="%d")
    np.savetxt(OUT / "frf_y.csv", y, fmt="%d")
    rows = [("all", "fs_hz", FS), ("all", "seg_len", SEG), ("all", "fn_hz", FN),
            ("all", "zeta", ZETA), ("all", "n", N)]
    for case, hop in CASES.items():
        kw = {"fs": FS, "window": "hann", "nperseg": SEG, "noverlap": SEG - hop,
              "detrend": False, "scaling": "density", "return_onesided": True}
        _, guu = signal.welch(u, **kw)
        _, gyy = signal.welch(y, **kw)
        _, guy = signal.csd(u, y, **kw)
        kwc = {k: v for k, v in kw.items() if k not in ("scaling", "return_onesided")}
        _, coh = signal.coherence(u, y, **kwc)
        np.savetxt(OUT / f"frf_ref_{case}.csv",
                   np.column_stack([guu, gyy, guy.real, guy.imag, coh]), fmt="%.17g")
        rows += [(case, "hop", hop), (case, "n_seg", (N - SEG) // hop + 1)]
        fp, f1, f2 = half_power(np.abs(guy / guu))
        rows += [(case, "peak_hz", fp * FS / SEG), (case, "hp_f1_hz", f1 * FS / SEG),
                 (case, "hp_f2_hz", f2 * FS / SEG)]
    with open(OUT / "frf_expected.csv", "w", encoding="ascii") as f:
        f.writelines(f"{r[0]},{r[1]},{r[2]!r}\n" for r in rows)


if __name__ == "__main__":
    main()
