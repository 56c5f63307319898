"""Simulation through the C core's model and observer (dv_model, dv_obs): the code the
firmware runs; and the linear model's matrices and modes as the core computes them.

Input interpolation: the C core's discretisation is exact for an input that is linear between
samples (first-order hold). A measured force is band-limited (the DAQ's anti-alias filter),
and linear interpolation of it attenuates the response near a mode by sinc^2(f/fs) (4 % at
71.6 Hz sampled at 640 Hz). With ``oversample`` R > 1 the input is first interpolated
band-limited by R (scipy.signal.resample_poly, zeros before t = 0 as the structure starts at
rest), the C code runs at R fs, and every R-th output is kept. R = 1 is the C code on the
samples as they are (bit-identical to dv_obs_simulate). ``cubic`` runs the core on the samples
with its cubic input hold (dv_model DV_HOLD_CUBIC: the Lagrange cubic through four samples,
discretised exactly), the hold the firmware can run too (one sample of latency there).
"""
from __future__ import annotations

import dataclasses
import importlib
import logging
import math
import re
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import _core
from dynval.errors import ConfigError
from dynval.model import daq
from dynval.model import elements as el
from dynval.model.schema import Damping, DaqFilter, Model, Output
from dynval.model.validation import MAX_OVERSAMPLE

log = logging.getLogger(__name__)

_DAMP_C = {"modal": "DV_DAMP_MODAL", "rayleigh": "DV_DAMP_RAYLEIGH", "matrix": "DV_DAMP_MATRIX"}
_INPUT_C = {"force": "DV_INPUT_FORCE", "ground_acc": "DV_INPUT_GROUND_ACC",
            "ground_disp": "DV_INPUT_GROUND_DISP"}
_OUT_C = {"acc": "DV_OUT_ACC", "vel": "DV_OUT_VEL", "disp": "DV_OUT_DISP",
          "story_force": "DV_OUT_SPRING_FORCE", "contact_force": "DV_OUT_ELEM_FORCE",
          "reaction": "DV_OUT_REACTION"}
_STATUS_HINT = {
    "DV_EUNSTABLE": "the damping matrix is not positive semi-definite, the discretisation is "
                    "not finite, or the sample period is too long for the contact stiffness "
                    "(raise simulation.substeps or oversample)",
    "DV_EINVAL": "a value is out of the core's range",
}


def _c(name: str) -> int:
    return int(getattr(_core.lib, name))


def _fill_damping(desc: Any, m: Model) -> None:
    d, n = m.damping, m.n_dof
    if d.type == "modal":
        desc.damp_kind = _c("DV_DAMP_MODAL")
        for i in range(n):
            desc.zeta[i] = d.zeta[i]
    elif d.type == "rayleigh" and d.modes:
        desc.damp_kind = _c("DV_DAMP_RAYLEIGH")
        for j in range(2):
            desc.rayleigh_mode[j] = d.modes[j] - 1
            desc.rayleigh_zeta[j] = d.zeta[j]
    else:
        desc.damp_kind = _c("DV_DAMP_MATRIX")
        cm = damping_matrix_explicit(m)
        for i in range(n):
            for j in range(n):
                desc.c_n_s_per_m[i * n + j] = float(cm[i, j])


def _fill_desc(desc: Any, m: Model) -> None:
    """Write m into a dv_model_desc_t (0-based indices)."""
    lib = _core.lib
    _core.check(lib.dv_model_desc_default(desc), "dv_model_desc_default")
    n = m.n_dof
    desc.n_dof = n
    for i in range(n):
        desc.mass_kg[i] = m.masses_kg[i]
        desc.k_n_per_m[i] = m.stiffness_n_per_m[i]
    _fill_damping(desc, m)
    desc.input_kind = _c(_INPUT_C[m.input.kind])
    desc.input_dof = max(m.input.dof - 1, 0)
    desc.n_elem = len(m.elements)
    for i, e in enumerate(m.elements):
        c = desc.elem[i]
        c.dof_a = lib.DV_GROUND if e.dof_a == 0 else e.dof_a - 1
        c.dof_b = e.dof_b - 1
        el.fill_desc(c, e)
    desc.n_link = len(m.links)
    for i, lk in enumerate(m.links):
        desc.link[i].dof_a, desc.link[i].dof_b = lk.dof_a - 1, lk.dof_b - 1
        desc.link[i].k_n_per_m, desc.link[i].c_n_s_per_m = lk.k_n_per_m, lk.c_n_s_per_m
    desc.n_sub = m.substeps if m.elements else 1
    desc.input_hold = _c("DV_HOLD_CUBIC" if m.interpolation == "cubic" else "DV_HOLD_FOH")
    desc.n_out = len(m.outputs)
    for j, o in enumerate(m.outputs.values()):
        desc.out[j].kind = _c(_OUT_C[o.kind])
        desc.out[j].index = 0 if o.kind == "reaction" else o.index - 1


def damping_matrix_explicit(m: Model) -> np.ndarray:
    """C for the types the core does not build itself (matrix; Rayleigh from alpha, beta, with
    the core's K)."""
    d = m.damping
    if d.type == "matrix":
        return np.asarray(d.c_n_s_per_m, dtype=np.float64)
    if d.explicit_rayleigh:
        return _explicit_rayleigh(m, stiffness_matrix(m))
    raise ConfigError("the core builds modal and mode-based Rayleigh damping itself")


def _explicit_rayleigh(m: Model, k: np.ndarray) -> np.ndarray:
    """C = alpha M + beta K of an explicit Rayleigh model, K the core's (the core builds
    Rayleigh damping from two modal ratios only)."""
    d = m.damping
    mass = np.array(m.masses_kg, dtype=np.float64)
    return float(d.alpha_per_s or 0.0) * np.diag(mass) + float(d.beta_s or 0.0) * k


class _Core:
    """A C model + open-loop observer with their buffers, reusable for many parameter sets."""

    def __init__(self, m: Model, dt_s: float) -> None:
        ffi = _core.ffi
        self.dt = dt_s
        self.desc = ffi.new("dv_model_desc_t *")
        self.cm = ffi.new("dv_model_t *")
        self.obs = ffi.new("dv_obs_t *")
        self.no = len(m.outputs)
        _fill_desc(self.desc, m)
        self.mlen = int(_core.lib.dv_model_buf_len(self.desc))
        if self.mlen == 0:
            raise ConfigError(f"{m.source or '<model>'}: the core refused the model's sizes")
        self.mbuf = np.zeros(self.mlen)
        self.mptr = _core.ptr(self.mbuf)
        self.olen = 0
        self.obuf = np.zeros(0)
        self.optr: Any = None

    def build_model(self, m: Model) -> None:
        """dv_model_init on the current description."""
        st = _core.lib.dv_model_init(self.cm, self.desc, self.dt, self.mptr, self.mlen)
        if st < 0:
            raise _refused(m, "dv_model_init", st, self.dt)

    def build(self, m: Model, refill: bool = True) -> None:
        if refill:
            _fill_desc(self.desc, m)
        self.build_model(m)
        lib = _core.lib
        olen = int(lib.dv_obs_buf_len(self.cm))
        if olen > self.olen:
            self.olen = olen
            self.obuf = np.zeros(olen)
            self.optr = _core.ptr(self.obuf)
        st = lib.dv_obs_init(self.obs, self.cm, _core.ffi.NULL, self.optr, self.olen)
        if st < 0:
            raise _refused(m, "dv_obs_init", st, self.dt)

    def run(self, u: np.ndarray, y: np.ndarray) -> int:
        """Simulate from rest into y (n x no, C-contiguous); returns the core's status."""
        return int(_core.lib.dv_obs_simulate(self.obs, _core.ptr(u), u.size, _core.ptr(y)))

    def start_at(self, x0: np.ndarray) -> None:
        """Back to rest, then the state x0 (displacements, velocities) at the next sample
        (dv_obs_reset, dv_obs_set_state)."""
        x = np.ascontiguousarray(x0, dtype=float)
        if x.size != 2 * self.desc.n_dof or not np.all(np.isfinite(x)):
            raise ConfigError(f"the initial state must be {2 * self.desc.n_dof} finite values "
                              f"(displacements, then velocities), got {x.size}")
        _core.lib.dv_obs_reset(self.obs)
        _core.check(_core.lib.dv_obs_set_state(self.obs, _core.ptr(x), x.size), "dv_obs_set_state")

    def cont(self, u: np.ndarray, y: np.ndarray) -> int:
        """Simulate on from the current state, open loop (dv_obs_update_block without
        measurements: the same steps as dv_obs_simulate, bit for bit, for a first-order hold)."""
        return int(_core.lib.dv_obs_update_block(self.obs, _core.ptr(u), _core.ffi.NULL, u.size,
                                                 _core.ptr(y), _core.ffi.NULL))

    def matrix(self, which: str) -> np.ndarray:
        """A copy of one of the built model's matrices (dv_model_get_mat, DV_MODEL_MAT_<which>)."""
        view = _core.ffi.new("dv_mat_t *")
        _core.check(_core.lib.dv_model_get_mat(self.cm, _c(f"DV_MODEL_MAT_{which}"), view),
                    "dv_model_get_mat")
        r, c = int(view.rows), int(view.cols)
        buf = _core.ffi.buffer(view.data, r * c * 8)
        return np.frombuffer(buf, dtype=np.float64).reshape(r, c).copy()

    def modes(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        f = np.zeros(n)
        phi = np.zeros(n * n)
        _core.check(_core.lib.dv_model_get_modes(self.cm, _core.ptr(f), _core.ptr(phi), n * n),
                    "dv_model_get_modes")
        return f, phi.reshape(n, n)


def _checked_later(status: int) -> bool:
    """Statuses of a simulation whose outputs are checked instead: DV_ENUMERIC (non-finite input
    samples, held and counted) and DV_EUNSTABLE (the model ran away: the outputs stop being
    finite, which _check_finite reports with its cause, and a fit penalises)."""
    return status in (_core.lib.DV_ENUMERIC, _core.lib.DV_EUNSTABLE)


# the Kalman gain's own refusal (dv_obs_init with a noise model)
_GAIN_HINT = ("the gain found lets the filter grow, or its Riccati solver did not converge (a "
              "mode the outputs do not see leaves the equation without a stabilising solution)")


def _refused(m: Model, func: str, status: int, dt: float, hint: str | None = None) -> ConfigError:
    name = _core.status_name(status)
    hint = _STATUS_HINT.get(name, "") if hint is None else hint
    return ConfigError(f"{m.source or '<model>'}: the core refused the model ({func}: {name}"
                       f"{'; ' + hint if hint else ''}; sample period {dt:g} s)")


def _linear_core(m: Model) -> _Core:
    """The core's model of m's linear part (no elements, one output), built (the damping of an
    explicit Rayleigh model, which needs K, is left out: see linear())."""
    lin = dataclasses.replace(m, elements=(), outputs={"a": Output("acc", 1)})
    if m.damping.explicit_rayleigh:
        lin = dataclasses.replace(lin, damping=Damping("modal", zeta=(0.0,) * m.n_dof))
    core = _Core(lin, 1e-4)
    core.build_model(lin)
    return core


@dataclass(frozen=True)
class Linear:
    """The linear model as the core builds it: masses (kg), K and C (n x n), undamped
    frequencies (Hz, ascending) and mass-normalised mode shapes (column k = mode k+1)."""

    mass: np.ndarray
    k: np.ndarray
    c: np.ndarray
    f_hz: np.ndarray
    phi: np.ndarray

    @property
    def w(self) -> np.ndarray:
        return np.asarray(2 * np.pi * self.f_hz)


def linear(m: Model) -> Linear:
    """K, C and the modes of m's linear part from one build of the core's model
    (dv_model_get_mat, dv_model_get_modes)."""
    core = _linear_core(m)
    k = core.matrix("K")
    f, phi = core.modes(m.n_dof)
    mass = np.array(m.masses_kg, dtype=np.float64)
    c = _explicit_rayleigh(m, k) if m.damping.explicit_rayleigh else core.matrix("C")
    return Linear(mass, k, c, f, phi)


def stiffness_matrix(m: Model) -> np.ndarray:
    """K of the chain (eq. 2), N/m, as the core builds it."""
    return _linear_core(m).matrix("K")


def modes(m: Model) -> tuple[np.ndarray, np.ndarray]:
    """Undamped natural frequencies (Hz, ascending) and mass-normalised mode shapes
    (column k = mode k+1), by the C core's eigen-solution (the core has no cheaper call than
    building the linear model: its eigen-solution is a stage of dv_model_init)."""
    return _linear_core(m).modes(m.n_dof)


def natural_frequencies(m: Model) -> np.ndarray:
    """Undamped natural frequencies of the linear chain, Hz, ascending (contacts open)."""
    return modes(m)[0]


def predict_observed(m: Model, u: Any, y: Mapping[str, np.ndarray], fs_hz: float,
                     q_force_n2: Sequence[float], r_meas: Mapping[str, float],
                     probes: Mapping[str, Output] | None = None) -> dict[str, np.ndarray]:
    """One-step-ahead predictions of every output by the core's observer with the steady-state
    Kalman gain (dv_obs_init with a noise model, dv_obs_update_block): before sample k the
    state is corrected by the measurements up to k - 1, so a drift the open-loop simulation
    accumulates is pulled back while the dynamics within a sample interval stay the model's.
    ``u``: the sampled input, or a PreparedInput of it (prepare_input); ``y``: measured
    channels (the model's outputs; a missing one is not corrected by); ``q_force_n2``: white
    force variance at each DOF, N^2; ``r_meas``: noise variance per channel (channel
    units^2). The input is interpolated as simulate() does (the model's band-limited
    oversampling R: the observer steps at R fs and corrects at the measured samples only), so
    a model predicts the same motion within a sample either way (a cubic hold is held
    linearly here). ``probes``: further outputs to predict (a DOF's displacement, velocity,
    acceleration) that measure nothing: the gain is the model's outputs' and the probes' own
    columns of it are zero, so they read the estimate the measurements make (the core's
    output limit holds for outputs and probes together). A declared DAQ filter is not used:
    the observer corrects with the measured channels and takes the input as measured (a
    PreparedInput with the filter divided out is refused). ConfigError when the core refuses
    the noise model (e.g. an undetectable rigid-body mode) or the model runs away (naming the
    element that makes it)."""
    r = oversample_factor(m)
    fine = _prepared_fine(u, r) if isinstance(u, PreparedInput) else _prepare_input(u, r)
    extra = dict(probes or {})

    def observe(mm: Model) -> tuple[int, np.ndarray]:
        return _observe(mm, fine, r, y, fs_hz, q_force_n2, r_meas, extra)

    st, pred = observe(m)
    if st == _core.lib.DV_EUNSTABLE:
        cause = _divergence_cause(m, lambda mm: observe(mm)[0] != _core.lib.DV_EUNSTABLE)
        raise ConfigError(f"{m.source or '<model>'}: the observer's model ran away (its state "
                          f"is no longer finite): {cause}")
    if st < 0 and st != _core.lib.DV_ENUMERIC:
        _core.check(st, "dv_obs_update_block")
    outs = {**m.outputs, **extra}
    return {c: _sensor(np.ascontiguousarray(pred[:, j]), outs[c]) for j, c in enumerate(outs)}


def _observe(m: Model, fine: np.ndarray, r: int, y: Mapping[str, np.ndarray], fs_hz: float,
             q_force_n2: Sequence[float], r_meas: Mapping[str, float],
             probes: Mapping[str, Output]) -> tuple[int, np.ndarray]:
    """predict_observed's core run on the input at r fs (``fine``): dv_obs_update_block's
    status and the predictions in the model's units at the measured samples (samples x
    outputs, then ``probes``). The gain is the Kalman gain of the model sampled at fs (the
    measurements' rate) with the outputs y measures: the r steps between two measurements
    compose that model's step exactly, so the correction at a measured sample is the one a
    filter at fs makes; between them the measurements are NaN (the core then predicts without
    correcting). Outputs y lacks and probes get zero gain columns and a finite placeholder
    (a NaN would stop the whole correction)."""
    measured = [c for c in m.outputs if c in y]
    if not measured:
        raise ConfigError(f"{m.source or '<model>'}: the observer has no measured output")
    mo = dataclasses.replace(m, interpolation="foh", oversample=1,
                             outputs={c: m.outputs[c] for c in measured})
    lib, ffi = _core.lib, _core.ffi
    noise = ffi.new("dv_obs_noise_t *")
    for j, q in enumerate(q_force_n2):
        noise.q_force_n2[j] = float(q)
    for j, c in enumerate(measured):  # in the model's units: the sensor's gain divided out
        noise.r_meas[j] = float(r_meas.get(c, 1.0)) / m.outputs[c].gain ** 2
    gain = _kalman_gain(mo, 1.0 / fs_hz, noise)
    silent = {**{c: o for c, o in m.outputs.items() if c not in y}, **probes}
    if silent:
        mo = dataclasses.replace(mo, outputs={**mo.outputs, **silent})
        gain = np.hstack([gain.reshape(2 * m.n_dof, len(measured)),
                          np.zeros((2 * m.n_dof, len(silent)))]).ravel()
    core = _Core(mo, 1.0 / (fs_hz * r))
    core.build(mo)
    st = lib.dv_obs_set_gain(core.obs, _core.ptr(gain), gain.size)
    if st < 0:  # a gain the core will not fold (not finite): refused like the model itself
        raise _refused(m, "dv_obs_set_gain", st, core.dt)
    n = fine.size // r
    meas = np.full((n * r, len(mo.outputs)), np.nan)
    meas[::r, len(measured):] = 0.0
    for j, c in enumerate(measured):
        o = m.outputs[c]
        meas[::r, j] = (y[c] - o.offset) / o.gain
    uc = np.ascontiguousarray(fine[:n * r], dtype=np.float64)
    pred = np.zeros((n * r, len(mo.outputs)))
    st = lib.dv_obs_update_block(core.obs, _core.ptr(uc), _core.ptr(meas), n * r,
                                 _core.ptr(pred), ffi.NULL)
    order = [list(mo.outputs).index(c) for c in [*m.outputs, *probes]]
    return int(st), pred[::r][:, order]


def _kalman_gain(m: Model, dt_s: float, noise: Any) -> np.ndarray:
    """The core's steady-state Kalman gain (dv_obs_init with a noise model) of m sampled at
    dt_s, flat (states x outputs, row-major)."""
    core = _Core(m, dt_s)
    core.build_model(m)
    lib = _core.lib
    olen = int(lib.dv_obs_buf_len(core.cm))
    buf = np.zeros(olen)
    st = lib.dv_obs_init(core.obs, core.cm, noise, _core.ptr(buf), olen)
    if st < 0:
        raise _refused(m, "dv_obs_init (Kalman gain)", st, core.dt,
                       _GAIN_HINT if _core.status_name(st) == "DV_EUNSTABLE" else None)
    gain = np.zeros(2 * m.n_dof * len(m.outputs))
    _core.check(lib.dv_obs_get_gain(core.obs, _core.ptr(gain), gain.size), "dv_obs_get_gain")
    return gain


def free_response(m: Model, fs_hz: float, n: int) -> np.ndarray:
    """What the channels read of the linear part's free motion from each unit initial state
    (displacements, then velocities; relative to the ground for a ground input), no input:
    an (n, n_outputs, 2 n_dof) array R, so the outputs from initial state x0 are R @ x0. From
    the core's exact discretisation at 1 / fs_hz (DV_MODEL_MAT_AD, DV_MODEL_MAT_CY)."""
    lin = dataclasses.replace(m, elements=())
    core = _Core(lin, 1.0 / fs_hz)
    core.build_model(lin)
    ad, cy = core.matrix("AD"), core.matrix("CY")
    gains = np.array([o.gain for o in m.outputs.values()])[:, None]
    # CY AD^(jb + i) = (CY AD^(jb)) AD^i: b powers and n / b block starts, not n products
    b = max(1, min(n, int(math.isqrt(max(n, 1)))))
    powers = np.empty((b, *ad.shape))
    powers[0] = np.eye(ad.shape[0])
    for i in range(1, b):
        powers[i] = powers[i - 1] @ ad
    jump = powers[-1] @ ad
    blocks = -(-n // b)
    heads = np.empty((blocks, *cy.shape))
    heads[0] = cy * gains
    for j in range(1, blocks):
        heads[j] = heads[j - 1] @ jump
    out = np.matmul(heads[:, None], powers[None]).reshape(blocks * b, cy.shape[0],
                                                         ad.shape[1])
    return np.ascontiguousarray(out[:n])


def oversample_factor(m: Model, oversample: int | None = None) -> int:
    """The factor simulate() interpolates the input by (its oversample argument, else the
    model's; 1 for a first-order or cubic hold, which the core does itself)."""
    r = m.oversample if oversample is None else int(oversample)
    if m.interpolation in ("foh", "cubic") and oversample is None:
        r = 1
    if not 1 <= r <= MAX_OVERSAMPLE:
        raise ConfigError(f"oversample must be 1..{MAX_OVERSAMPLE}, got {r}")
    return r


# scipy's default Kaiser beta 5 ripples by up to 0.2 % in the pass band: the response STDs of
# the report's frame came out 0.03 % high (two standard errors of a 10-test paired residual);
# beta 12 matches an exact (FFT) band-limited interpolation to 1e-5 up to 0.31 fs
KAISER_BETA = 12.0


# input samples either side of a block that its band-limited interpolation reads (scipy's
# resample_poly filter reaches 10 samples each way)
_CONTEXT = 16
_TAIL = 32  # zeros after the record's last sample, so its tail is not cut by the filter


def interpolate_input(u: np.ndarray, r: int) -> np.ndarray:
    """Band-limited interpolation by r (zeros before the first sample: the structure starts at
    rest; zeros padded after the last so its tail is not cut by the filter)."""
    return _fine_block(u, r, 0, np.asarray(u).size)


def _fine_block(u: Any, r: int, a: int, b: int) -> np.ndarray:
    """interpolate_input(u, r) of the samples a..b-1 only, bit for bit that slice of the whole
    record's (the filter sees the same samples): a long record is interpolated block by block."""
    if r == 1:
        return _core.as_doubles(u[a:b])
    n = np.asarray(u).size
    s, e = max(a - _CONTEXT, 0), min(b + _CONTEXT, n)
    seg = _core.as_doubles(u[s:e])
    if e == n:
        seg = np.concatenate([seg, np.zeros(_TAIL)])
    resample_poly = importlib.import_module("scipy.signal").resample_poly
    fine = resample_poly(seg, r, 1, window=("kaiser", KAISER_BETA))
    return np.ascontiguousarray(fine[(a - s) * r:(b - s) * r])


def _check_input(a: np.ndarray, r: int) -> None:
    if a.size == 0:
        raise ConfigError("the input record is empty")
    if r > 1:
        bad = sum(int(np.count_nonzero(~np.isfinite(a[i:i + BLOCK])))
                  for i in range(0, a.size, BLOCK))
        if bad:
            raise ConfigError(f"the input has {bad} non-finite samples: band-limited "
                              "interpolation needs a complete record (use oversample=1 to let "
                              "the core hold; --oversample 1 on the command line)")


def _prepare_input(u: Any, r: int) -> np.ndarray:
    a = _core.as_doubles(u)
    _check_input(a, r)
    return interpolate_input(a, r)


@dataclass(frozen=True)
class PreparedInput:
    """A sampled input interpolated once (prepare_input) for repeated simulations: simulate()
    takes it in place of the samples (discover simulates each test hundreds of times, and the
    interpolation was a quarter of each run)."""

    fine: np.ndarray  # the input at fs x r
    r: int
    daq: DaqFilter | None = None  # the DAQ filter divided out of it (daq.unmeasured)


def _prepared_fine(u: PreparedInput, r: int, daq_filter: DaqFilter | None = None
                   ) -> np.ndarray:
    """The interpolated input of u, which must have been prepared for the factor r and the
    DAQ filter daq_filter (the model's; the observer's: none)."""
    if u.r != r:
        raise ConfigError(f"the input was prepared for oversample {u.r}, the model simulates "
                          f"at {r}")
    if u.daq != daq_filter:
        raise ConfigError(f"the input was prepared for the DAQ filter {u.daq}, the simulation "
                          f"takes {daq_filter}")
    return u.fine


def prepare_input(m: Model, force_or_motion: Any, oversample: int | None = None,
                  fs_hz: float | None = None) -> PreparedInput:
    """The input as simulate() would interpolate it for m (see simulate); with m's DAQ
    filter divided out when it declares one (fs_hz, else m.fs_hz, is then needed)."""
    r = oversample_factor(m, oversample)
    f = daq.applied(m)
    if f is None:
        return PreparedInput(_prepare_input(force_or_motion, r), r)
    a = _core.as_doubles(force_or_motion)
    _check_input(a, 1)
    return PreparedInput(daq.unmeasured(f, a, _daq_rate(m, fs_hz), r), r, f)


def _daq_rate(m: Model, fs_hz: float | None) -> float:
    fs = fs_hz if fs_hz is not None else m.fs_hz
    if fs is None or not fs > 0:
        raise ConfigError(f"{m.source or '<model>'}: its DAQ filter needs the sample rate")
    assert m.daq_filter is not None
    why = daq.cutoff_outside(m.daq_filter, float(fs))
    if why:
        raise ConfigError(f"{m.source or '<model>'}: simulation.daq_filter.cutoff_hz: {why}")
    return float(fs)


# input samples per block of a simulation (its memory: block x oversample x outputs doubles)
BLOCK = 1 << 16
# simulate_batch interpolates an input once when it takes at most this much interpolated, a
# longer one block by block for each set (an hour at 2 kHz x 4 is 230 MB in every worker)
INTERPOLATE_ONCE_BYTES = 64 << 20


def simulate(m: Model, force_or_motion: Any, fs_hz: float, *,
             oversample: int | None = None, x0: np.ndarray | None = None
             ) -> dict[str, np.ndarray]:
    """Predicted outputs (channel -> array) of the model driven from rest by the sampled input
    (or a PreparedInput of it), through the C core (dv_model_init, dv_obs_init open loop,
    dv_obs_simulate). oversample: band-limited interpolation factor (None: the model's; 1: the
    samples as they are); x0: the state at the first sample instead of rest (displacements,
    then velocities, m and m/s; relative to the ground for a ground input). Runs block by
    block (simulate_blocks)."""
    u = force_or_motion
    n = u.fine.size // u.r if isinstance(u, PreparedInput) else np.asarray(u).size
    out = {name: np.empty(n) for name in m.outputs}
    for a, y in simulate_blocks(m, u, fs_hz, oversample=oversample, x0=x0):
        for j, col in enumerate(out.values()):
            col[a:a + y.shape[0]] = y[:, j]
    return out


def simulate_blocks(m: Model, force_or_motion: Any, fs_hz: float, *,
                    oversample: int | None = None, block: int = BLOCK,
                    x0: np.ndarray | None = None, every_step: bool = False
                    ) -> Iterator[tuple[int, np.ndarray]]:
    """simulate() in blocks of `block` input samples: (first sample, outputs as the sensors
    read them, samples x m.outputs) of each in turn, the state carried across blocks
    (dv_obs_simulate, then dv_obs_update_block open loop) and the input interpolated per block
    (_fine_block): bit for bit the whole record's result, in memory bounded by the block. The
    input may be memory-mapped: a block of it is read at a time. The cubic hold's samples,
    which the core completes a call late, are realigned across blocks (dv_obs_flush completes
    the last one, as dv_obs_simulate does). A model with a DAQ filter that takes part
    (daq.applied) is simulated over the whole record and given as one block (_through_daq).
    every_step: the outputs of every step of the oversampled simulation (r per sample, the
    first at the first sample; not with the cubic hold's realignment), not every r-th."""
    if not fs_hz > 0:
        raise ConfigError(f"fs_hz must be > 0, got {fs_hz!r}")
    if daq.applied(m) is not None:
        yield 0, _through_daq(m, force_or_motion, fs_hz, oversample, x0)
        return
    r = oversample_factor(m, oversample)
    prepared = isinstance(force_or_motion, PreparedInput)
    if isinstance(force_or_motion, PreparedInput):
        u = _prepared_fine(force_or_motion, r)
        n = u.size // r
    else:
        u = np.asarray(force_or_motion).reshape(-1)
        n = u.size
        _check_input(u, r)
    # the cubic hold's core completes a sample at the next one's call: realigned across
    # blocks here for a complete input; with held (non-finite) samples in one block
    late = m.interpolation == "cubic" and (n > block or x0 is not None)
    if late and every_step:
        raise ConfigError("every step of a simulation is not kept with the cubic input hold")
    if late and not all(np.isfinite(u[i:i + BLOCK]).all() for i in range(0, u.size, BLOCK)):
        log.info("cubic input hold with non-finite inputs: %d samples simulated in one block", n)
        block, late = n, x0 is not None  # dv_obs_simulate would reset the start away

    def prefix(k: int) -> np.ndarray:  # the first k steps' input, to find a divergence's cause
        return u[:k] if prepared else _fine_block(u, r, 0, -(-k // r))[:k]

    plain = all(o.gain == 1.0 and o.offset == 0.0 for o in m.outputs.values())

    def outputs(a: int, uf: np.ndarray, yf: np.ndarray) -> tuple[int, np.ndarray]:
        _check_finite(m, uf, yf, dt, a * r, n * r, prefix)
        y = yf if every_step else yf[::r]
        if plain:  # the sensors read the core's outputs as they are (yf is this block's own)
            return a, np.ascontiguousarray(y)
        return a, np.stack([_sensor(np.ascontiguousarray(y[:, j]), o)
                            for j, o in enumerate(m.outputs.values())], axis=1)

    dt = 1.0 / (fs_hz * r)
    if n <= block:
        core = _built(m, dt)
    else:  # its own core: another simulation of m between the blocks (this is a generator)
        core = _Core(m, dt)  # would reset a shared one's state
        core.build(m, refill=False)
    held: tuple[int, np.ndarray, np.ndarray] | None = None  # a block awaiting its last row
    n_bad = 0
    for a in range(0, n, block):
        b = min(a + block, n)
        uf = u[a * r:b * r] if prepared else _fine_block(u, r, a, b)
        yf = np.empty((uf.size, core.no))
        if a == 0 and x0 is not None:
            core.start_at(x0)
        st = core.run(uf, yf) if a == 0 and not late and x0 is None else core.cont(uf, yf)
        if st < 0 and not _checked_later(st):
            _core.check(st, "dv_obs_simulate")
        n_bad = int(core.obs.n_bad_input)  # read now: a shared core runs others after a yield
        if not late:
            yield outputs(a, uf, yf)
            continue
        if held is not None:  # row j of a late block is sample j - 1
            yield outputs(held[0], held[1], np.concatenate([held[2][1:], yf[:1]]))
        held = (a, uf, yf)
    if held is not None:  # the last sample completed as dv_obs_simulate does (dv_obs_flush)
        last = np.empty((1, core.no))
        _core.check(_core.lib.dv_obs_flush(core.obs), "dv_obs_flush")
        _core.check(_core.lib.dv_obs_get(core.obs, _core.ptr(last), _core.ffi.NULL, core.no),
                    "dv_obs_get")
        yield outputs(held[0], held[1], np.concatenate([held[2][1:], last]))
    if n_bad:
        log.warning("%d non-finite input samples: the core held the state there", n_bad)


_BUILT = threading.local()  # per thread: (model, step, its built core) of the last simulation


def _built(m: Model, dt: float) -> _Core:
    """m's core built for the step dt, the last one's again when it is the same model object
    and step (a fit simulates one model for every test: its build was 6 % of a 6-DOF discover
    run), for a record simulated in one call: each starts from rest (dv_obs_simulate resets
    the state and counters), so the same numbers, bit for bit. The model is held, so its id
    is not reused meanwhile."""
    last: tuple[Model, float, _Core] | None = getattr(_BUILT, "last", None)
    if last is not None and last[0] is m and last[1] == dt:
        return last[2]
    core = _Core(m, dt)
    core.build(m, refill=False)
    _BUILT.last = (m, dt, core)
    return core


def _unfiltered(m: Model) -> Model:
    """m without its DAQ filter, the same object for the same m (the last one's, per thread),
    so that _built reuses its core across a fit's tests (a new copy per test rebuilt it: 4 %
    of a 6-DOF run once a filter is found)."""
    last: tuple[Model, Model] | None = getattr(_BUILT, "unfiltered", None)
    if last is not None and last[0] is m:
        return last[1]
    bare = dataclasses.replace(m, daq_filter=None)
    _BUILT.unfiltered = (m, bare)
    return bare


def _through_daq(m: Model, force_or_motion: Any, fs_hz: float, oversample: int | None,
                 x0: np.ndarray | None = None) -> np.ndarray:
    """simulate_blocks' outputs (samples x m.outputs) for a model with a DAQ filter, over the
    whole record at once: driven by the input with the filter divided out (prepare_input),
    measured through it (daq.measured; a sensor's offset is not filtered: it was on before
    the record). An oversampled simulation is read through the filter at its own rate and
    then sampled, as the DAQ filters the analog signal before it samples it: an element's
    harmonics above fs/2 alias only as far as the filter lets them (taken from every r-th
    step first, they aliased at full strength: see daq's module comment)."""
    f = daq.applied(m)
    assert f is not None
    u = (force_or_motion if isinstance(force_or_motion, PreparedInput)
         else prepare_input(m, force_or_motion, oversample, fs_hz))
    bare = _unfiltered(m)
    r = oversample_factor(m, oversample)
    plain = PreparedInput(_prepared_fine(u, r, f), r)
    n = plain.fine.size // r
    # (the cubic hold's start at a state x0 is realigned by a step: simulate_blocks' late)
    fine = r > 1 and not (m.interpolation == "cubic" and x0 is not None)
    y = np.concatenate([b for _, b in simulate_blocks(bare, plain, fs_hz, oversample=r,
                                                      block=max(n, 1), x0=x0,
                                                      every_step=fine)])
    offsets = np.array([o.offset for o in m.outputs.values()])
    if not offsets.any():  # (two passes over the oversampled outputs less)
        read = daq.measured(f, y, fs_hz * r if fine else fs_hz)
        return np.ascontiguousarray(read[::r] if fine else read)
    read = daq.measured(f, y - offsets, fs_hz * r if fine else fs_hz)
    return np.asarray((read[::r] if fine else read) + offsets)


def _run(m: Model, u: np.ndarray, dt: float) -> np.ndarray:
    """The core's outputs (samples x outputs) for the input u at step dt, from rest."""
    core = _Core(m, dt)
    core.build(m, refill=False)
    y = np.empty((u.size, core.no))
    st = core.run(u, y)
    if st < 0 and not _checked_later(st):
        _core.check(st, "dv_obs_simulate")
    return y


def _check_finite(m: Model, u: np.ndarray, y: np.ndarray, dt: float, start: int, total: int,
                  prefix: Callable[[int], np.ndarray]) -> None:
    """A prediction that is not finite where the input is (a diverged simulation) is a
    ConfigError naming the element (or the linear part) that makes it diverge. u, y: the block
    of steps start.. of a record of `total` steps; prefix(k): its first k steps' input."""
    if np.isfinite(y).all():  # the usual case, 25x cheaper than the row-wise test below
        return
    bad = ~np.isfinite(y).all(axis=1) & np.isfinite(u)
    if not bad.any():
        return
    k = start + int(np.argmax(bad))
    uk = prefix(k + 1)
    cause = _divergence_cause(m, lambda probe: bool(np.isfinite(_run(probe, uk, dt)).all()))
    raise ConfigError(f"{m.source or '<model>'}: the simulation diverged at t = {k * dt:.6g} s "
                      f"(step {k} of {total}): {cause}")


def _divergence_cause(m: Model, runs: Callable[[Model], bool]) -> str:
    """Which part of m diverges: each element alone removed, then all of them. ``runs(probe)``:
    whether the probe model runs without diverging (an open-loop simulation, the observer)."""
    def without(keep: Sequence[int]) -> bool:
        elems = tuple(m.elements[i] for i in keep)
        outs = {k: o for k, o in m.outputs.items() if o.kind != "contact_force"}
        return runs(dataclasses.replace(m, elements=elems,
                                        outputs=outs or {"x1": Output("disp", 1)}))

    idx = range(len(m.elements))
    for i in idx:
        if without([j for j in idx if j != i]):
            e = m.elements[i]
            vals = ", ".join(f"{k} = {v:.4g}" for k, v in el.values(e).items())
            softening = isinstance(e, el.CubicSpring) and e.k3_n_per_m3 < 0
            return (f"elements[{i}] ({e.type}, {vals}) makes it unstable at this step; " + (
                "a softening spring driven past its peak restoring force runs away: lower |k3| "
                "or the input" if softening else
                "lower its coefficient, or raise simulation.substeps or oversample"))
    if m.elements and without([]):
        return "the elements together make it unstable; check their coefficients"
    return ("the linear model is unstable at this step: check masses_kg, stiffness_n_per_m "
            "and damping")


def _sensor(q: np.ndarray, o: Output) -> np.ndarray:
    """What the channel reads of the model's quantity q: gain x q + offset."""
    if o.gain != 1.0:
        q = q * o.gain
    return q + o.offset if o.offset != 0.0 else q


def simulate_batch(m: Model, force_or_motion: Any, fs_hz: float,
                   param_sets: Sequence[Mapping[str, float]], *, oversample: int | None = None,
                   on_progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Simulate many parameter variants (Model.with_params names: m1, k2, zeta3, e1.gap_m, ...)
    of one model for one input. Returns an array (n_sets, n_samples, n_outputs), outputs in
    the order of m.channels. The input is interpolated once; each run rebuilds only the C
    model and observer in preallocated buffers, and simulates in blocks (simulate_blocks) through
    a block-long buffer at the oversampled rate."""
    if not fs_hz > 0:
        raise ConfigError(f"fs_hz must be > 0, got {fs_hz!r}")
    if daq.applied(m) is not None:
        return _batch_through_daq(m, force_or_motion, fs_hz, param_sets, oversample,
                                  on_progress)
    r = oversample_factor(m, oversample)
    a = _core.as_doubles(force_or_motion)
    _check_input(a, r)
    n = a.size
    if r > 1 and n * r * 8 > INTERPOLATE_ONCE_BYTES:  # per block, for each set
        def fine(i: int, j: int) -> np.ndarray:
            return _fine_block(a, r, i // r, j // r)
    else:
        u = interpolate_input(a, r)

        def fine(i: int, j: int) -> np.ndarray:
            return u[i:j]
    core = _Core(m, 1.0 / (fs_hz * r))
    base = _core.ffi.new("dv_model_desc_t *")
    _fill_desc(base, m)
    size = _core.ffi.sizeof("dv_model_desc_t")
    setters = _desc_setters(m)
    out = np.empty((len(param_sets), n, core.no))
    blk = BLOCK * r
    late = m.interpolation == "cubic" and n * r > blk  # see simulate_blocks
    # (a band-limited input is complete: _check_input; held samples are the core's, r = 1)
    if late and r == 1 and not all(np.isfinite(a[i:i + blk]).all() for i in range(0, n, blk)):
        blk, late = n * r, False
    work = np.empty((min(n * r, blk), core.no)) if r > 1 or late else None
    for i, ps in enumerate(param_sets):
        _core.ffi.memmove(core.desc, base, size)
        if all(name in setters for name in ps):
            for name, value in ps.items():
                v = float(value)
                if not math.isfinite(v):
                    raise ConfigError(f"parameter set {i}: {name} = {value!r} is not finite")
                setters[name](core.desc, v)
        else:  # a parameter the description does not hold directly (Rayleigh alpha, beta)
            try:
                _fill_desc(core.desc, m.with_params(ps))
            except ConfigError as exc:
                raise ConfigError(f"parameter set {i}: {exc}") from None
        try:
            core.build(m, refill=False)
        except ConfigError as exc:
            raise ConfigError(f"parameter set {i} {dict(ps)}: {exc}") from None
        st = _run_blocks(core, fine, n * r, out[i], r, blk, work, late)
        if st < 0 and not _checked_later(st):
            _core.check(st, "dv_obs_simulate")
        if on_progress is not None:
            on_progress(i + 1, len(param_sets))
    gains = np.array([o.gain for o in m.outputs.values()])
    offsets = np.array([o.offset for o in m.outputs.values()])
    if np.any(gains != 1.0):
        out *= gains
    if np.any(offsets != 0.0):
        out += offsets
    return out


def _batch_through_daq(m: Model, force_or_motion: Any, fs_hz: float,
                       param_sets: Sequence[Mapping[str, float]], oversample: int | None,
                       on_progress: Callable[[int, int], None] | None) -> np.ndarray:
    """simulate_batch for a model with a DAQ filter: each set over the whole record
    (_through_daq), the input prepared once."""
    u = prepare_input(m, force_or_motion, oversample, fs_hz)
    out = []
    for i, ps in enumerate(param_sets):
        try:
            mi = m.with_params(dict(ps))
        except ConfigError as exc:
            raise ConfigError(f"parameter set {i}: {exc}") from None
        out.append(_through_daq(mi, u, fs_hz, oversample))
        if on_progress is not None:
            on_progress(i + 1, len(param_sets))
    return np.stack(out) if out else np.empty((0, u.fine.size // u.r, len(m.outputs)))


def _run_blocks(core: _Core, fine: Callable[[int, int], np.ndarray], size: int, y: np.ndarray,
                r: int, blk: int, work: np.ndarray | None, late: bool) -> int:
    """The fine input (fine(i, j): its steps i..j-1, size steps) from rest into y (every r-th
    step's outputs), blk steps at a time through `work` (blk x outputs; None for r = 1
    without `late`: straight into y); the worst status. late: the cubic hold's core gives
    step k at the call of step k + 1 (realigned here, the last step completed by dv_obs_flush
    as dv_obs_simulate does)."""
    worst = 0
    for a in range(0, size, blk):
        uf = fine(a, min(a + blk, size))
        dst = y[a:a + uf.size] if work is None else work[:uf.size]
        st = core.run(uf, dst) if a == 0 and not late else core.cont(uf, dst)
        if st < 0 and (worst >= 0 or _checked_later(worst)):  # the first real error
            worst = st
        if late:  # row j is step a + j - 1: keep the multiples of r
            j0 = 0 if a and r == 1 else 1
            rows = dst[j0:uf.size:r]
            y[(a + j0 - 1) // r:(a + j0 - 1) // r + rows.shape[0]] = rows
        elif work is not None:
            y[a // r:(a + uf.size) // r] = work[:uf.size:r]
    if late and r == 1:
        last = np.empty(core.no)
        _core.check(_core.lib.dv_obs_flush(core.obs), "dv_obs_flush")
        _core.check(_core.lib.dv_obs_get(core.obs, _core.ptr(last), _core.ffi.NULL, core.no),
                    "dv_obs_get")
        y[-1] = last
    return worst


def _desc_setters(m: Model) -> dict[str, Callable[[Any, float], None]]:
    """Direct writers into a dv_model_desc_t for each parameter name (validated by the core:
    mass <= 0, negative stiffness etc. give DV_EINVAL, reported as ConfigError)."""
    s: dict[str, Callable[[Any, float], None]] = {}

    def arr(field_: str, i: int) -> Callable[[Any, float], None]:
        def f(d: Any, v: float) -> None:
            getattr(d, field_)[i] = v
        return f

    def con(i: int, attr: str) -> Callable[[Any, float], None]:
        def f(d: Any, v: float) -> None:
            setattr(d.elem[i], attr, v)
        return f

    for i in range(m.n_dof):
        s[f"m{i + 1}"] = arr("mass_kg", i)
        s[f"k{i + 1}"] = arr("k_n_per_m", i)
    if m.damping.type == "modal":
        for i in range(m.n_dof):
            s[f"zeta{i + 1}"] = arr("zeta", i)
    elif m.damping.type == "rayleigh" and m.damping.modes:
        for i in range(2):
            s[f"zeta{i + 1}"] = arr("rayleigh_zeta", i)
    def link(i: int, attr: str) -> Callable[[Any, float], None]:
        def f(d: Any, v: float) -> None:
            setattr(d.link[i], attr, v)
        return f

    for i, e in enumerate(m.elements):
        for p in el.spec(e).params:
            s[f"e{i + 1}.{p.name}"] = con(i, p.field)
    for i in range(len(m.links)):
        for name in ("k_n_per_m", "c_n_s_per_m"):
            s[f"l{i + 1}.{name}"] = link(i, name)
    if m.damping.explicit_rayleigh:
        # masses and stiffnesses also enter C = a M + b K: recompute C in Python for them
        s = {k: v for k, v in s.items() if not re.match(r"^(?:[mk]\d+|l\d+\.k_n_per_m)$", k)}
    return s


