"""Realistic "measured" tests of a lumped-mass chain with an effect the declared model lacks.

Independent of dynval's model and observer (dv_model/dv_obs): the truth is integrated by a
classical fixed-step Runge-Kutta 4 at ``fine`` x the output rate (default 16) in a small C
kernel compiled on first use with the system's C compiler (``cc``) and loaded with cffi (ABI
mode). The force is band-limited random (white noise through a 4th-order Butterworth band-pass
at the fine rate, linear between fine samples). A DAQ is then imitated: a causal 8th-order
Butterworth low-pass at 0.4 fs on every channel (force included) at the fine rate, decimation
to fs, and white sensor noise of ``noise`` x the clean RMS of each channel.

Effects (``Truth``): contact/gap elements (the report's bumper law, eq. 6-7, either side),
Coulomb friction between a DOF and the ground or two DOFs (regularised F_c tanh(v / v_eps),
v_eps small against the response velocity), a cubic story spring k3 d^3, a velocity-squared
story damper c2 v|v|, and linear changes (story stiffness, masses, damping) and sensor gains.
"""
from __future__ import annotations

import hashlib
import importlib
import logging
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from cffi import FFI

from dynval import model as mdl
from dynval.errors import ConfigError
from dynval.io.recording import Channel, Recording

log = logging.getLogger(__name__)
linalg: Any = importlib.import_module("scipy.linalg")
signal: Any = importlib.import_module("scipy.signal")

# element codes of the kernel
_CONTACT, _FRICTION, _CUBIC, _VV = 1, 2, 3, 4
_SIDE = {"pos": 0, "neg": 1, "both": 2}

_C_SRC = r"""
#include <math.h>
#define NMAX 8
static double bump(double s, double d, double kb) {
    if (s <= 0.0) return 0.0;
    if (s < d) return kb * s * s / (2.0 * d);
    return kb * (s - 0.5 * d);
}
/* restoring force of the elements into f (size n); el: 7 doubles per element
   {type, a, b, p0, p1, p2, side}; a = -1 is the ground. */
static void elem_force(int n, const double *x, const double *v, int ne, const double *el,
                       double *f) {
    for (int i = 0; i < n; ++i) f[i] = 0.0;
    for (int e = 0; e < ne; ++e) {
        const double *p = el + 7 * e;
        int t = (int)p[0], a = (int)p[1], b = (int)p[2];
        double xa = a < 0 ? 0.0 : x[a], va = a < 0 ? 0.0 : v[a];
        double X = x[b] - xa, V = v[b] - va, g = 0.0;
        if (t == 1) {
            int side = (int)p[6];
            if (side == 0 || side == 2) g += bump(X - p[3], p[4], p[5]);
            if (side == 1 || side == 2) g -= bump(-X - p[3], p[4], p[5]);
        } else if (t == 2) {
            g = p[3] * tanh(V / p[4]);
        } else if (t == 3) {
            g = p[3] * X * X * X;
        } else if (t == 4) {
            g = p[3] * V * fabs(V);
        }
        f[b] += g;
        if (a >= 0) f[a] -= g;
    }
}
static void rhs(int n, const double *minv, const double *K, const double *C, int in_dof,
                double u, const double *x, const double *v, int ne, const double *el,
                double *acc) {
    double f[NMAX];
    elem_force(n, x, v, ne, el, f);
    for (int i = 0; i < n; ++i) {
        double s = (i == in_dof) ? u : 0.0;
        s -= f[i];
        for (int j = 0; j < n; ++j) s -= K[i * n + j] * x[j] + C[i * n + j] * v[j];
        acc[i] = s * minv[i];
    }
}
/* RK4 over u (nsteps+1 samples, linear between them); acc: (nsteps+1) x n */
int gen_run(int n, const double *minv, const double *K, const double *C, int in_dof,
            const double *u, long nsteps, double h, int ne, const double *el, double *acc) {
    double x[NMAX] = {0}, v[NMAX] = {0}, k1x[NMAX], k1v[NMAX], k2x[NMAX], k2v[NMAX],
           k3x[NMAX], k3v[NMAX], k4x[NMAX], k4v[NMAX], xt[NMAX], vt[NMAX];
    if (n < 1 || n > NMAX) return -1;
    rhs(n, minv, K, C, in_dof, u[0], x, v, ne, el, acc);
    for (long s = 0; s < nsteps; ++s) {
        double u0 = u[s], u1 = u[s + 1], um = 0.5 * (u0 + u1);
        for (int i = 0; i < n; ++i) k1x[i] = v[i];
        rhs(n, minv, K, C, in_dof, u0, x, v, ne, el, k1v);
        for (int i = 0; i < n; ++i) {
            xt[i] = x[i] + 0.5 * h * k1x[i]; vt[i] = v[i] + 0.5 * h * k1v[i];
        }
        for (int i = 0; i < n; ++i) k2x[i] = vt[i];
        rhs(n, minv, K, C, in_dof, um, xt, vt, ne, el, k2v);
        for (int i = 0; i < n; ++i) {
            xt[i] = x[i] + 0.5 * h * k2x[i]; vt[i] = v[i] + 0.5 * h * k2v[i];
        }
        for (int i = 0; i < n; ++i) k3x[i] = vt[i];
        rhs(n, minv, K, C, in_dof, um, xt, vt, ne, el, k3v);
        for (int i = 0; i < n; ++i) { xt[i] = x[i] + h * k3x[i]; vt[i] = v[i] + h * k3v[i]; }
        for (int i = 0; i < n; ++i) k4x[i] = vt[i];
        rhs(n, minv, K, C, in_dof, u1, xt, vt, ne, el, k4v);
        for (int i = 0; i < n; ++i) {
            x[i] += h / 6.0 * (k1x[i] + 2.0 * k2x[i] + 2.0 * k3x[i] + k4x[i]);
            v[i] += h / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
            if (!isfinite(x[i]) || !isfinite(v[i])) return -2;
        }
        rhs(n, minv, K, C, in_dof, u1, x, v, ne, el, acc + (s + 1) * n);
    }
    return 0;
}
"""
_CDEF = ("int gen_run(int n, const double *minv, const double *K, const double *C, int in_dof,"
         " const double *u, long nsteps, double h, int ne, const double *el, double *acc);")

_lib_cache: dict[str, Any] = {}


def _kernel() -> tuple[Any, Any]:
    """Compile (once per source version, cached on disk) and load the RK4 kernel."""
    key = hashlib.sha256(_C_SRC.encode()).hexdigest()[:16]
    if key in _lib_cache:
        return _lib_cache["ffi"], _lib_cache[key]
    cache = Path(os.environ.get("DV_GEN_CACHE", Path(tempfile.gettempdir()) / "dynval-gen"))
    cache.mkdir(parents=True, exist_ok=True)
    so = cache / f"gen_rk4_{key}.so"
    if not so.is_file():
        cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
        if cc is None:
            raise ConfigError("the test generator needs a C compiler (cc/gcc) for its kernel")
        src = cache / f"gen_rk4_{key}.c"
        src.write_text(_C_SRC, encoding="utf-8")
        tmp = cache / f"gen_rk4_{key}.{os.getpid()}.so"
        r = subprocess.run([cc, "-O2", "-std=c99", "-shared", "-fPIC", "-o", str(tmp), str(src),
                            "-lm"], capture_output=True, text=True, check=False)
        if r.returncode != 0:
            raise ConfigError(f"compiling the generator kernel failed: {r.stderr.strip()}")
        tmp.replace(so)
    ffi = _lib_cache.get("ffi")
    if ffi is None:
        ffi = FFI()
        ffi.cdef(_CDEF)
        _lib_cache["ffi"] = ffi
    lib = ffi.dlopen(str(so))
    _lib_cache[key] = lib
    return ffi, lib


@dataclass(frozen=True)
class TruthElement:
    """A nonlinear element of the truth. kind: 'contact' (p = gap_m, delta_m, kb_n_per_m,
    side), 'friction' (p = force_n, v_eps_m_per_s), 'cubic' (p = k3_n_per_m3), 'vv'
    (p = c2_n_s2_per_m2). Between DOF a (0 = ground) and DOF b, 1-based; X = x_b - x_a."""

    kind: str
    dof_a: int
    dof_b: int
    p: tuple[float, ...]
    side: str = "pos"


@dataclass(frozen=True)
class Truth:
    """What the generator's structure has on top of the declared model: relative changes of
    story stiffness (k_scale) and mass (m_add_kg), damping ratios (zeta, None: the model's),
    sensor gains per output channel, and nonlinear elements."""

    k_scale: dict[int, float] = field(default_factory=dict)
    m_add_kg: dict[int, float] = field(default_factory=dict)
    zeta: tuple[float, ...] | None = None
    gains: dict[str, float] = field(default_factory=dict)
    elements: tuple[TruthElement, ...] = ()
    label: str = "clean"


def _matrices(m: mdl.Model, truth: Truth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M (diag), K and C of the truth. Modal damping is built from the truth's own modes."""
    n = m.n_dof
    ks = np.array(m.stiffness_n_per_m, dtype=float)
    for s, f in truth.k_scale.items():
        ks[s - 1] *= f
    ms = np.array(m.masses_kg, dtype=float)
    for j, dm in truth.m_add_kg.items():
        ms[j - 1] += dm
    k = np.zeros((n, n))
    for i in range(n):
        k[i, i] += ks[i]
        if i + 1 < n:
            k[i, i] += ks[i + 1]
            k[i, i + 1] = k[i + 1, i] = -ks[i + 1]
    mm = np.diag(ms)
    d = m.damping
    if d.type == "modal" or truth.zeta is not None:
        zeta = np.array(truth.zeta if truth.zeta is not None else d.zeta, dtype=float)
        w2, phi = linalg.eigh(k, mm)
        w = np.sqrt(np.maximum(w2, 0.0))
        c = mm @ phi @ np.diag(2 * zeta * w) @ phi.T @ mm
    else:
        c = mdl.damping_matrix_explicit(m) if d.type != "rayleigh" or not d.modes else None
        if c is None:
            w2, phi = linalg.eigh(k, mm)
            w = np.sqrt(np.maximum(w2, 0.0))
            r, s = d.modes[0] - 1, d.modes[1] - 1
            a_mat = np.array([[1 / (2 * w[r]), w[r] / 2], [1 / (2 * w[s]), w[s] / 2]])
            ab = np.linalg.solve(a_mat, np.array(d.zeta))
            c = ab[0] * mm + ab[1] * k
    return ms, k, c


def band_limited_force(rng: np.random.Generator, n: int, fs_hz: float, rms: float,
                       band_hz: tuple[float, float] = (20.0, 200.0)) -> np.ndarray:
    """White noise through a 4th-order Butterworth band-pass, scaled to rms."""
    sos = signal.butter(4, band_hz, btype="bandpass", fs=fs_hz, output="sos")
    f = signal.sosfilt(sos, rng.standard_normal(n))
    return np.asarray(rms * f / np.sqrt(np.mean(f * f)))


def simulate_truth(m: mdl.Model, truth: Truth, force_fine: np.ndarray,
                   fs_fine_hz: float) -> np.ndarray:
    """Accelerations (len(force_fine) x n) of the truth driven from rest by a force at the
    model's input DOF, RK4 at the fine rate (force linear between fine samples)."""
    if m.input.kind != "force":
        raise ConfigError("the generator drives force-input models only")
    ffi, lib = _kernel()
    ms, k, c = _matrices(m, truth)
    n = m.n_dof
    el = np.zeros(7 * max(len(truth.elements), 1))
    codes = {"contact": _CONTACT, "friction": _FRICTION, "cubic": _CUBIC, "vv": _VV}
    for i, e in enumerate(truth.elements):
        p = list(e.p) + [0.0] * (3 - len(e.p))
        el[7 * i: 7 * i + 7] = [codes[e.kind], e.dof_a - 1, e.dof_b - 1, p[0], p[1], p[2],
                                _SIDE[e.side]]
    u = np.ascontiguousarray(force_fine, dtype=float)
    acc = np.zeros((u.size, n))
    minv = 1.0 / ms
    kk = np.ascontiguousarray(k)
    cc = np.ascontiguousarray(c)

    def dp(a: np.ndarray) -> Any:
        return ffi.cast("double *", ffi.from_buffer(a))

    st = lib.gen_run(n, dp(minv), dp(kk), dp(cc), m.input.dof - 1, dp(u), u.size - 1,
                     1.0 / fs_fine_hz, len(truth.elements), dp(el), dp(acc))
    if st != 0:
        raise ConfigError(f"the generator's integration failed ({st}): unstable or non-finite")
    return acc


def generate(m: mdl.Model, truth: Truth, *, n_tests: int = 10,
             levels_n_rms: tuple[float, ...] = (12.0, 7.2), n_samples: int = 8192,
             fs_hz: float = 640.0, fine: int = 16, noise: float = 0.01, seed: int = 0,
             band_hz: tuple[float, float] = (20.0, 200.0)) -> list[Recording]:
    """n_tests measured tests (levels cycled: test i has force RMS levels[i % len(levels)]),
    as Recordings whose columns are the model's input channel (default 'force_N') and its
    acceleration outputs (other output kinds are not generated)."""
    rng = np.random.default_rng(seed)
    fs_fine = fs_hz * fine
    n_fine = n_samples * fine
    aa = signal.butter(8, 0.4 * fs_hz, btype="low", fs=fs_fine, output="sos")
    in_name = m.input.channel or "force_N"
    acc_outs = {name: o for name, o in m.outputs.items() if o.kind == "acc"}
    if not acc_outs:
        raise ConfigError("the generator produces accelerations: the model has no acc output")
    recs = []
    for i in range(n_tests):
        level = levels_n_rms[i % len(levels_n_rms)]
        f = band_limited_force(rng, n_fine, fs_fine, level, band_hz)
        acc = simulate_truth(m, truth, f, fs_fine)
        cols = {in_name: f}
        for name, o in acc_outs.items():
            cols[name] = acc[:, o.index - 1] * truth.gains.get(name, 1.0)
        chans = []
        for name, x in cols.items():
            y = signal.sosfilt(aa, x)[::fine]
            y = y + noise * float(np.sqrt(np.mean(y * y))) * rng.standard_normal(y.size)
            chans.append(Channel(name=name, data=np.ascontiguousarray(y),
                                 unit="N" if name == in_name else "m/s^2",
                                 role="input" if name == in_name else "output"))
        tag = "high" if level == max(levels_n_rms) else "low"
        recs.append(Recording(name=f"{truth.label}_{tag}_{i + 1:02d}", fs_hz=fs_hz,
                              channels=chans))
    return recs


def write_csv(rec: Recording, path: Path | str) -> None:
    """Write a Recording in the shared data's CSV layout (time_s first). Column names are the
    channel names as they are (a model names its channels by the tests' columns, so a
    generated test must keep them: 'a1' stays 'a1', 'acc1_mps2' stays 'acc1_mps2')."""
    t = rec.t0_s + np.arange(rec.n_samples) / rec.fs_hz
    data = np.column_stack([t] + [c.data for c in rec.channels])
    np.savetxt(path, data, delimiter=",", header=",".join(["time_s", *rec.names]), comments="",
               fmt="%.10g")
