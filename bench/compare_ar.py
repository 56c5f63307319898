"""Same-run comparisons for the AR benchmarks (bench/bench_ar.c): scipy/numpy on the same kind
of data (8192 samples of a lightly damped 2-mode process, AR(60)).

- ar60_resid_sample: scipy.signal.lfilter over the record (the figure the issue quotes), and
  lfilter called once per sample with its state carried (zi): the streaming API the scipy way.
- ar60_resid_block: scipy.signal.lfilter over the whole record (FIR with the 61 taps).
- ar60_levinson_fit_8192: numpy lags (one np.dot per lag, biased) + scipy.linalg.solve_toeplitz.
- ar60_burg_fit_8192: a plain numpy Burg (vectorised per order, O(n p)).
- ar60_resid_sample / _block: CMSIS-DSP's arm_fir_f64 over the record, through the cmsisdsp
  package (`pip install cmsisdsp`: its C sources built for this host); left out, with a log
  line, when the package is not installed.
"""
from __future__ import annotations

import logging

import numpy as np
from measure import median_ns  # bench/ is on the path (run.py's folder)
from scipy import linalg, signal

N, P = 8192, 60


def _data() -> np.ndarray:
    rng = np.random.default_rng(2024)
    u = rng.uniform(-0.5, 0.5, N)
    y = signal.lfilter([1.0], [1.0, -1.8, 0.95], u)
    z = signal.lfilter([1.0], [1.0, -0.6, 0.9], u)
    return y + z + 0.05 * u


def _levinson(x: np.ndarray, p: int) -> np.ndarray:
    y = x - x.mean()
    n = y.size
    r = np.array([np.dot(y[: n - k], y[k:]) for k in range(p + 1)]) / n
    return np.asarray(linalg.solve_toeplitz(r[:p], r[1 : p + 1]))


def _burg(x: np.ndarray, p: int) -> np.ndarray:
    y = x - x.mean()
    f, b = y[1:].copy(), y[:-1].copy()
    a = np.zeros(0)
    for _ in range(p):
        k = 2.0 * np.dot(f, b) / (np.dot(f, f) + np.dot(b, b))
        a = np.r_[a - k * a[::-1], k]
        f, b = f[1:] - k * b[1:], b[:-1] - k * f[:-1]
    return a


def _cmsis(taps: np.ndarray, xc: np.ndarray) -> list[dict]:
    """arm_fir_f64 over the record (coefficients in time-reversed order, as CMSIS wants)."""
    try:
        import cmsisdsp as dsp  # type: ignore[import-not-found]
    except ImportError:
        logging.getLogger("bench").warning("cmsisdsp not installed: no CMSIS-DSP comparison")
        return []
    rev = np.ascontiguousarray(taps[::-1])

    def fir() -> np.ndarray:
        inst = dsp.arm_fir_instance_f64()
        dsp.arm_fir_init_f64(inst, P + 1, rev, np.zeros(P + N))
        return np.asarray(dsp.arm_fir_f64(inst, xc))

    err = float(np.max(np.abs(fir() - signal.lfilter(taps, [1.0], xc))))
    ns = median_ns(fir, N, 101)
    what = f"CMSIS-DSP arm_fir_f64 over the record (cmsisdsp {dsp.__version__}, max |diff| {err:.1e})"
    return [{"case": c, "what": what, "ns": ns, "unit": "sample"}
            for c in ("ar60_resid_sample", "ar60_resid_block")]


def compare() -> list[dict]:
    x = _data()
    a = _levinson(x, P)
    taps = np.r_[1.0, -a]
    xc = x - x.mean()

    def per_sample() -> None:
        zi = np.zeros(P)
        for v in xc[:512]:
            _, zi = signal.lfilter(taps, [1.0], [v], zi=zi)

    def block() -> None:
        signal.lfilter(taps, [1.0], xc)

    out = _cmsis(taps, xc)
    return out + [
        {"case": "ar60_resid_sample", "what": "scipy lfilter over the record (the issue's figure)",
         "ns": median_ns(block, N, 201), "unit": "sample"},
        {"case": "ar60_resid_sample", "what": "scipy lfilter, one call per sample with zi",
         "ns": median_ns(per_sample, 512, 7, warm=1), "unit": "sample"},
        {"case": "ar60_resid_block", "what": "scipy lfilter over the record (61-tap FIR)",
         "ns": median_ns(block, N, 201), "unit": "sample"},
        {"case": "ar60_levinson_fit_8192",
         "what": "numpy lags (np.dot per lag) + scipy solve_toeplitz",
         "ns": median_ns(lambda: _levinson(x, P), 1, 101), "unit": "fit"},
        {"case": "ar60_burg_fit_8192", "what": "plain numpy Burg (vectorised per order)",
         "ns": median_ns(lambda: _burg(x, P), 1, 51), "unit": "fit"},
    ]


if __name__ == "__main__":
    for c in compare():
        print(f"{c['case']:26s} {c['ns']:12.1f} ns/{c['unit']}  {c['what']}")
