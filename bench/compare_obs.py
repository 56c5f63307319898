"""Same-run comparisons for the observer benchmarks (bench_obs.c), in Python/scipy.

compare() -> list of {"case", "what", "ns", "unit", "nrmse"}:
- obs_step_4dof: scipy.signal.dlsim on the same discretised 4-DOF model (8 states, 4
  accelerations), ns per step over an 8192-sample record; nrmse vs a tight reference.
- sim_record_8192: scipy solve_ivp RK45 (the report's ODE45 analogue) on the 8192-sample
  record, force linear between samples, tolerances tightened until its accuracy is at least
  that of dynval's exact discretisation (NRMSE <= 1e-6 against a DOP853 rtol 1e-11 reference);
  ns per record. Also the accuracy of RK45 at rtol 1e-3 (Matlab's ODE45 default) for scale.
The reference for nrmse is solve_ivp DOP853 at rtol 1e-11 integrated sample interval by sample
interval (the force is only piecewise smooth).
"""
from __future__ import annotations

import time

import numpy as np
from scipy import linalg, signal
from scipy.integrate import solve_ivp

FS = 640.0
N = 8192
MASS = np.array([6.54, 6.66, 6.86, 6.80])
K_STORY = np.array([10.0, 399790.0, 399790.0, 399790.0])
ZETA = np.array([0.01, 0.05, 0.01, 0.01])


def _model():
    n = 4
    kk = np.zeros((n, n))
    for i in range(n):
        kk[i, i] += K_STORY[i]
        if i > 0:
            kk[i - 1, i - 1] += K_STORY[i]
            kk[i, i - 1] -= K_STORY[i]
            kk[i - 1, i] -= K_STORY[i]
    w2, phi = linalg.eigh(kk, np.diag(MASS))
    w = np.sqrt(np.maximum(w2, 0))
    mm = np.diag(MASS)
    c = mm @ phi @ np.diag(2 * ZETA * w) @ phi.T @ mm
    minv = np.diag(1 / MASS)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-minv @ kk, -minv @ c]])
    b = np.zeros((2 * n, 1))
    b[n, 0] = 1 / MASS[0]
    cy = a[n:, :]
    d = b[n:, :]
    return a, b, cy, d


def _force() -> np.ndarray:
    rng = np.random.default_rng(7)
    bb, aa = signal.butter(4, [20.0, 200.0], btype="bandpass", fs=FS)
    x = signal.lfilter(bb, aa, rng.standard_normal(N + 1024))[1024:]
    return 12.0 * x / np.sqrt(np.mean(x * x))


def _reference(a, b, cy, d, f) -> np.ndarray:
    dt = 1 / FS
    x = np.zeros(a.shape[0])
    y = np.zeros((N, cy.shape[0]))
    y[0] = cy @ x + d[:, 0] * f[0]
    for k in range(N - 1):
        f0, f1, t0 = f[k], f[k + 1], k * dt
        sol = solve_ivp(lambda t, s: a @ s + b[:, 0] * (f0 + (f1 - f0) * (t - t0) / dt),
                        (t0, t0 + dt), x, method="DOP853", rtol=1e-11, atol=1e-15)
        x = sol.y[:, -1]
        y[k + 1] = cy @ x + d[:, 0] * f1
    return y


def _nrmse(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.sqrt(np.mean((y - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))))


def _rk45(a, b, cy, d, f, rtol: float) -> np.ndarray:
    t = np.arange(N) / FS
    sol = solve_ivp(lambda tt, s: a @ s + b[:, 0] * np.interp(tt, t, f), (0, t[-1]),
                    np.zeros(a.shape[0]), method="RK45", t_eval=t, rtol=rtol,
                    atol=rtol * 1e-6)
    x = sol.y.T
    return x @ cy.T + f[:, None] * d[:, 0]


def compare() -> list[dict]:
    a, b, cy, d = _model()
    f = _force()
    ref = _reference(a, b, cy, d, f)
    dt = 1 / FS
    # FOH discretisation for dlsim (scipy's own 'foh' method)
    sysd = signal.cont2discrete((a, b, cy, d), dt, method="foh")
    out = []
    ts = []
    for _ in range(5):
        t0 = time.perf_counter_ns()
        _, y, _ = signal.dlsim(sysd[:4] + (dt,), f)
        ts.append((time.perf_counter_ns() - t0) / N)
    out.append({"case": "obs_step_4dof", "what": "scipy.signal.dlsim (FOH-discretised)",
                "ns": float(np.median(ts)), "unit": "step", "nrmse": _nrmse(y, ref)})
    # RK45 at equal or better accuracy: tighten rtol until NRMSE <= 1e-6
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        t0 = time.perf_counter_ns()
        y = _rk45(a, b, cy, d, f, rtol)
        el = time.perf_counter_ns() - t0
        e = _nrmse(y, ref)
        if e <= 1e-6:
            break
    ts = [el]
    for _ in range(2):
        t0 = time.perf_counter_ns()
        _rk45(a, b, cy, d, f, rtol)
        ts.append(time.perf_counter_ns() - t0)
    out.append({"case": "sim_record_8192", "what": f"scipy solve_ivp RK45 rtol {rtol:g}",
                "ns": float(np.median(ts)), "unit": "record", "nrmse": e})
    t0 = time.perf_counter_ns()
    y = _rk45(a, b, cy, d, f, 1e-3)
    out.append({"case": "sim_record_8192", "what": "scipy solve_ivp RK45 rtol 1e-3 (ODE45 "
                "default)", "ns": float(time.perf_counter_ns() - t0), "unit": "record",
                "nrmse": _nrmse(y, ref)})
    return out


if __name__ == "__main__":
    for row in compare():
        print(row)
