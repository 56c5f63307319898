#!/usr/bin/env python3
"""Golden vectors for the lumped-mass model and the observer (dv_model, dv_obs).

Independent of dynval: scipy solve_ivp (DOP853, rtol 1e-10) integrated interval by interval
between samples with the force linear in each interval (the same first-order-hold
interpolation the model assumes), and for the bumper with event location at every boundary
of the piecewise contact law (restart at each event). Also the steady-state Kalman gain from
scipy's solve_discrete_are on a matrix-exponential discretisation.

Writes tests/data/model_*.csv (comma-separated rows, no header, %.17g):
  model_force.csv          N force samples (N), 640 Hz, band-limited 20-200 Hz random
  model_lin_acc.csv        N x 4 accelerations, linear model L2 (m/s^2)
  model_bump05_acc.csv     N x 4 accelerations + contact force, bumper delta 0.5 mm (N1)
  model_bump01_acc.csv     N x 4 accelerations + contact force, bumper delta 0.1 mm (N2)
  model_kalman_gain.csv    8 x 4 steady-state Kalman gain (filtered form) with k1 = KALMAN_K1
  model_freq.csv           4 natural frequencies, Hz
Cubic input hold (dv_model DV_HOLD_CUBIC): the same integrator with the force between samples
given by the Lagrange cubic through f[k-1..k+2] (f[-1] = 0, f[N] = 3 f[N-1] - 3 f[N-2] + f[N-3]),
or by an exact continuous function:
  model_cubic_lin_acc.csv  N x 4, linear model, model_force.csv with the cubic interpolant
  model_cubic_bump05_acc.csv N x 4 + contact force, bumper delta 0.5 mm, cubic interpolant
  model_poly_force.csv     NP force samples of the cubic polynomial POLY (N)
  model_poly_acc.csv       NP x 4 accelerations for the continuous polynomial force
  model_bl_force.csv       N samples of a continuous band-limited force (sum of sinusoids in
                           20-200 Hz, raised-cosine onset over BL_RAMP s)
  model_bl_acc.csv         N x 4 accelerations for the continuous band-limited force
Run: python3 tests/gen/gen_model.py
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy import linalg, signal
from scipy.integrate import solve_ivp

OUT = Path(__file__).resolve().parent.parent / "data"
FS = 640.0
N = 2048
MASS = np.array([6.54, 6.66, 6.86, 6.80])
K_STORY = np.array([10.0, 399790.0, 399790.0, 399790.0])
ZETA_L2 = np.array([0.01, 0.05, 0.01, 0.01])
GAP = 1.0e-4
KB = 1.925e6
FORCE_RMS = 20.0  # N: enough for the bumper to close many times in 3.2 s
KALMAN_Q = 1.0  # N^2, white force variance at every DOF
KALMAN_R = 0.04  # (m/s^2)^2, every acceleration channel
KALMAN_K1 = 2.0e4  # N/m: stiffer rails for the gain check; with k1 = 10 the 0.1 Hz rails mode
# is nearly undetectable from accelerations and scipy's QZ-based DARE reports ill-conditioning
RTOL = 1e-10
ATOL = 1e-16
NP = 256
BL_RAMP = 0.1  # s
BL_COMPONENTS = 400


def stiffness(k: np.ndarray) -> np.ndarray:
    n = k.size
    kk = np.zeros((n, n))
    for i in range(n):
        kk[i, i] += k[i]
        if i > 0:
            kk[i - 1, i - 1] += k[i]
            kk[i, i - 1] -= k[i]
            kk[i - 1, i] -= k[i]
    return kk


def modal_damping(m: np.ndarray, kk: np.ndarray, zeta: np.ndarray):
    w2, phi = linalg.eigh(kk, np.diag(m))  # mass-normalised: phi^T M phi = I
    w = np.sqrt(np.maximum(w2, 0.0))
    mm = np.diag(m)
    c = mm @ phi @ np.diag(2.0 * zeta * w) @ phi.T @ mm
    return c, w / (2.0 * np.pi)


def force_signal(rng: np.random.Generator) -> np.ndarray:
    b, a = signal.butter(4, [20.0, 200.0], btype="bandpass", fs=FS)
    x = signal.lfilter(b, a, rng.standard_normal(N + 1024))[1024:]
    return x * (FORCE_RMS / np.sqrt(np.mean(x * x)))


def contact_g(x: float, delta: float) -> float:
    s = x - GAP
    if s <= 0.0:
        return 0.0
    if s < delta:
        return KB * s * s / (2.0 * delta)
    return KB * (s - 0.5 * delta)


def lagrange_coeffs(f: np.ndarray, k: int) -> np.ndarray:
    """Coefficients of s^0..s^3 (s = (t - t_k) / T) of the cubic through f[k-1..k+2]."""
    nf = f.size
    ext = 3.0 * f[-1] - 3.0 * f[-2] + f[-3]
    w = np.array([f[j] if 0 <= j < nf else (0.0 if j < 0 else ext) for j in range(k - 1, k + 3)])
    lag = np.array([[0, 1, 0, 0], [-1 / 3, -1 / 2, 1, -1 / 6], [1 / 2, -1, 1 / 2, 0],
                    [-1 / 6, 1 / 2, -1 / 2, 1 / 6]])
    return lag @ w


def simulate(f: np.ndarray, c: np.ndarray, kk: np.ndarray, delta: float | None,
             cubic: bool = False):
    """Accelerations (and contact force) at the samples; force linear between samples (cubic:
    the Lagrange cubic through the four nearest samples)."""
    n = MASS.size
    minv = 1.0 / MASS
    dt = 1.0 / FS

    def contact(q):
        if delta is None:
            return 0.0
        return contact_g(q[3] - q[2], delta)

    def accel(q, v, fk):
        g = contact(q)
        fv = -kk @ q - c @ v
        fv[0] += fk
        fv[2] += g  # the element pushes DOF a (=2) by +g and DOF b (=3) by -g
        fv[3] -= g
        return fv * minv, g

    y = np.zeros(2 * n)
    acc = np.zeros((N, n))
    gout = np.zeros(N)
    n_events = 0
    acc[0], gout[0] = accel(y[:n], y[n:], f[0])
    for k in range(N - 1):
        t0, t1 = k * dt, (k + 1) * dt
        f0, f1 = f[k], f[k + 1]
        cc = lagrange_coeffs(f, k) if cubic else None

        def rhs(t, s):
            if cc is not None:
                sl = (t - t0) / dt
                fk = cc[0] + sl * (cc[1] + sl * (cc[2] + sl * cc[3]))
            else:
                fk = f0 + (f1 - f0) * (t - t0) / dt
            a, _ = accel(s[:n], s[n:], fk)
            return np.concatenate([s[n:], a])

        events = []
        if delta is not None:
            def ev_gap(t, s):
                return s[3] - s[2] - GAP

            def ev_full(t, s):
                return s[3] - s[2] - GAP - delta

            ev_gap.terminal = True
            ev_full.terminal = True
            events = [ev_gap, ev_full] if delta > 0.0 else [ev_gap]
        t = t0
        active = list(events)
        while True:
            sol = solve_ivp(rhs, (t, t1), y, method="DOP853", rtol=RTOL, atol=ATOL,
                            events=active or None)
            y = sol.y[:, -1]
            if sol.status == 1 and sol.t[-1] < t1 - 1e-15:
                # an event: restart exactly there; the boundary just crossed is not watched
                # again in this interval (a second crossing within 1/640 s would be smoothed
                # only by the integrator's own error control)
                n_events += 1
                t = float(sol.t[-1])
                fired = [i for i, te in enumerate(sol.t_events) if te.size > 0]
                active = [e for i, e in enumerate(active) if i not in fired]
                continue
            break
        acc[k + 1], gout[k + 1] = accel(y[:n], y[n:], f1)
    return acc, gout, n_events


def simulate_fn(fn, n_samples: int, c: np.ndarray, kk: np.ndarray) -> np.ndarray:
    """Accelerations at the samples of the linear model for a continuous force fn(t)."""
    n = MASS.size
    minv = 1.0 / MASS
    t = np.arange(n_samples) / FS

    def rhs(tt, s):
        fv = -kk @ s[:n] - c @ s[n:]
        fv[0] += fn(tt)
        return np.concatenate([s[n:], fv * minv])

    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(2 * n), method="DOP853", rtol=RTOL,
                    atol=ATOL, t_eval=t, max_step=0.25 / FS)
    acc = np.zeros((n_samples, n))
    for k in range(n_samples):
        fv = -kk @ sol.y[:n, k] - c @ sol.y[n:, k]
        fv[0] += fn(t[k])
        acc[k] = fv * minv
    return acc


def poly_force(t):
    """A cubic polynomial with a root at t = -T (so the hold's zero before t = 0 fits it)."""
    tn = t / (NP / FS)
    return 10.0 * (t * FS + 1.0) / NP * 4.0 * (1.0 - 3.0 * tn + 2.0 * tn * tn)


def bl_force(rng: np.random.Generator):
    """A continuous band-limited force: sinusoids 20-200 Hz, raised-cosine onset."""
    fr = rng.uniform(20.0, 200.0, BL_COMPONENTS)
    ph = rng.uniform(0.0, 2.0 * np.pi, BL_COMPONENTS)
    amp = FORCE_RMS * np.sqrt(2.0 / BL_COMPONENTS)
    w = 2.0 * np.pi * fr

    def fn(t):
        tt = np.asarray(t, dtype=float)
        ramp = np.where(tt < BL_RAMP, 0.5 - 0.5 * np.cos(np.pi * np.clip(tt, 0, None) / BL_RAMP),
                        1.0)
        v = amp * np.sin(np.multiply.outer(tt, w) + ph).sum(axis=-1)
        return ramp * v
    return fn


def kalman_gain(c: np.ndarray, kk: np.ndarray) -> np.ndarray:
    n = MASS.size
    dt = 1.0 / FS
    minv = np.diag(1.0 / MASS)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-minv @ kk, -minv @ c]])
    bw = np.vstack([np.zeros((n, n)), minv])
    e = np.zeros((3 * n, 3 * n))
    e[: 2 * n, : 2 * n] = a * dt
    e[: 2 * n, 2 * n:] = bw * dt
    ex = linalg.expm(e)
    ad, gw = ex[: 2 * n, : 2 * n], ex[: 2 * n, 2 * n:]
    q = gw @ (KALMAN_Q * np.eye(n)) @ gw.T
    cy = a[n:, :]
    r = KALMAN_R * np.eye(n)
    p = linalg.solve_discrete_are(ad.T, cy.T, q, r)
    return p @ cy.T @ np.linalg.inv(cy @ p @ cy.T + r)


def save(name: str, arr: np.ndarray) -> None:
    arr = np.atleast_2d(np.asarray(arr, dtype=float))
    if arr.shape[0] == 1:
        arr = arr.T
    np.savetxt(OUT / name, arr, fmt="%.17g", delimiter=",")


def main() -> None:
    rng = np.random.default_rng(20261204)
    kk = stiffness(K_STORY)
    c, fhz = modal_damping(MASS, kk, ZETA_L2)
    f = force_signal(rng)
    save("model_force.csv", f)
    save("model_freq.csv", fhz)
    print("frequencies Hz", fhz)
    t = time.time()
    acc, _, _ = simulate(f, c, kk, None)
    save("model_lin_acc.csv", acc)
    print(f"linear: {time.time() - t:.1f} s, acc rms {np.sqrt(np.mean(acc**2, axis=0))}")
    for name, delta in (("bump05", 5e-4), ("bump01", 1e-4)):
        t = time.time()
        acc, g, nev = simulate(f, c, kk, delta)
        save(f"model_{name}_acc.csv", np.column_stack([acc, g]))
        closes = int(np.sum(np.diff((g > 0).astype(int)) == 1))
        print(f"{name}: {time.time() - t:.1f} s, {nev} events, {closes} closures, "
              f"peak contact force {g.max():.1f} N")
    t = time.time()
    acc, _, _ = simulate(f, c, kk, None, cubic=True)
    save("model_cubic_lin_acc.csv", acc)
    acc, g, nev = simulate(f, c, kk, 5e-4, cubic=True)
    save("model_cubic_bump05_acc.csv", np.column_stack([acc, g]))
    print(f"cubic: {time.time() - t:.1f} s, {nev} events")
    tp = np.arange(NP) / FS
    save("model_poly_force.csv", poly_force(tp))
    save("model_poly_acc.csv", simulate_fn(poly_force, NP, c, kk))
    fn = bl_force(np.random.default_rng(20261205))
    t = time.time()
    save("model_bl_force.csv", fn(np.arange(N) / FS))
    save("model_bl_acc.csv", simulate_fn(lambda tt: float(fn(tt)), N, c, kk))
    print(f"band-limited: {time.time() - t:.1f} s")
    kk1 = stiffness(np.concatenate([[KALMAN_K1], K_STORY[1:]]))
    c1, _ = modal_damping(MASS, kk1, ZETA_L2)
    save("model_kalman_gain.csv", kalman_gain(c1, kk1))


if __name__ == "__main__":
    main()
