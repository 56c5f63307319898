"""Trace a residual to the effect the model lacks.

* Time: events (windows whose residual RMS stands out), intermittency (share of the residual
  energy in the top 10 % of windows), kurtosis.
* Frequency: where the residual's energy sits: near the model's modes (a resonance shift or a
  damping error), elsewhere inside the input band, or above it (harmonics / impact bursts).
* States (restoring-force surface): when every DOF has an accelerometer, the states are
  reconstructed from the measured accelerations (integrated in the frequency domain above a
  high-pass corner) and the model is inverted: the missing restoring force at each DOF is
  f = F - M a - C v - K x - (forces of the model's elements). Every candidate of the effects
  library offers the shape of the force it would add; its evidence is the share of the missing
  force's energy its best amplitude explains (R^2, with the shape scanned where it has one).
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import features as feat
from dynval import model as mdl
from dynval.discover import effects as fx
from dynval.discover import parallel
from dynval.discover.residual import Observer, TestData
from dynval.errors import DynvalError
from dynval.model import elements as el
from dynval.model.validation import core_limits
from dynval.validate import measurement

log = logging.getLogger(__name__)
signal: Any = importlib.import_module("scipy.signal")
next_fast_len: Any = importlib.import_module("scipy.fft").next_fast_len


@dataclass
class Events:
    """Residual events of one channel in one test: start times (s) of outstanding windows."""

    times_s: list[float]
    intermittency: float
    kurtosis: float


@dataclass
class Spectrum:
    """Fractions of residual energy near the modes, elsewhere in the input band, above it."""

    near_modes: float
    in_band: float
    above_band: float


@dataclass
class Evidence:
    cand: fx.Candidate
    r2: float
    amp: float
    shape: dict[str, float] = field(default_factory=dict)
    # a nonlinear element's equation-error estimate with the declared story stiffnesses and
    # modal damping re-adjusted jointly: (the effect's amplitude, the change of each declared
    # parameter by name); see score()
    joint: tuple[float, dict[str, float]] | None = None


@dataclass
class ForceView:
    """The restoring-force surface data of the fitting tests (concatenated)."""

    states: fx.States
    f_miss: np.ndarray  # n x T (output view: 1 x N, the normalised output residual, negated)
    trim: slice
    # output view: maps a restoring-force field (n x T over the concatenated tests) to the
    # normalised measured outputs it would take away (1 x N); None: f_miss is in DOF space
    propagate: Callable[[np.ndarray], np.ndarray] | None = None
    out_pred: dict[str, np.ndarray] = field(default_factory=dict)  # normalised predictions
    seg_lens: list[int] = field(default_factory=list)  # samples of each test (output view)


def events(r: np.ndarray, fs_hz: float, win: int = 32, k: float = 5.0) -> Events:
    n = r.size // win
    if n < 4:
        return Events([], 0.0, 0.0)
    w = np.sqrt(np.mean(r[: n * win].reshape(n, win) ** 2, axis=1))
    med = float(np.median(w))
    mad = float(np.median(np.abs(w - med))) * 1.4826 or 1e-300
    idx = np.flatnonzero(w > med + k * mad)
    e = w ** 2
    top = np.sort(e)[::-1][: max(1, n // 10)]
    return Events([float(i * win / fs_hz) for i in idx], float(top.sum() / (e.sum() or 1e-300)),
                  float(feat.moments(r).kurt))


def spectrum(r: np.ndarray, fs_hz: float, modes_hz: Sequence[float],
             band_hz: tuple[float, float]) -> Spectrum:
    f, p = signal.welch(r, fs=fs_hz, nperseg=min(512, r.size))
    tot = float(p.sum()) or 1e-300
    near = np.zeros(f.size, dtype=bool)
    for fm in modes_hz:
        if fm > 1.0:
            near |= np.abs(f - fm) <= max(0.06 * fm, 2 * fs_hz / 512)
    inb = (f >= band_hz[0]) & (f <= band_hz[1]) & ~near
    above = f > band_hz[1]
    return Spectrum(float(p[near].sum() / tot), float(p[inb].sum() / tot),
                    float(p[above].sum() / tot))


def input_band(tests: Sequence[TestData]) -> tuple[float, float]:
    """The band holding 98 % of the tests' input power (measurement.input_band)."""
    return measurement.input_band(np.concatenate([t.u for t in tests]), tests[0].fs_hz)


@functools.lru_cache(maxsize=16)
def _hp_response(n: int, fs: float, f_hp: float, f_lp: float | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The bins of an n-point real FFT and the high-pass's (low-pass's) gain there, read-only
    (kept: every evidence basis of a round is filtered through the same one)."""
    f = np.fft.rfftfreq(n, 1.0 / fs)
    with np.errstate(divide="ignore"):
        h = 1.0 / (1.0 + (f_hp / np.maximum(f, 1e-12)) ** 8)  # |4th-order Butterworth|^2
    h[0] = 0.0
    if f_lp is not None:
        h /= 1.0 + (f / f_lp) ** 8
    f.setflags(write=False)
    h.setflags(write=False)
    return f, h


# a motion sensor's derivative order below an acceleration (its spectrum times (j w)^order)
ORDER = {"acc": 0, "vel": 1, "disp": 2}


def _integrate(y: np.ndarray, orders: Sequence[int], fs: float, f_hp: float,
               f_lp: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """High-passed (and low-passed below f_lp) acceleration, velocity and displacement (zero
    phase, frequency domain, zero-padded to twice the length) from rows of accelerations,
    velocities or displacements (orders: ORDER of each row)."""
    n = y.shape[-1]
    nf = next_fast_len(2 * n, real=True)
    f, h = _hp_response(nf, fs, f_hp, f_lp)
    w = 2 * np.pi * f
    w[0] = 1.0
    spec = np.fft.rfft(y, nf, axis=-1) * h
    if any(orders):
        spec *= (1j * w)[None, :] ** np.asarray(orders)[:, None]
    ah = np.fft.irfft(spec, nf, axis=-1)[..., :n]
    vh = np.fft.irfft(spec / (1j * w), nf, axis=-1)[..., :n]
    xh = np.fft.irfft(-spec / (w ** 2), nf, axis=-1)[..., :n]
    return ah, vh, xh


def _hp(x: np.ndarray, fs: float, f_hp: float, f_lp: float | None = None,
        nf: int | None = None) -> np.ndarray:
    """x high-passed (zero phase) on an nf-point zero-padded grid (default: a quarter more
    than x's length), cut back to x's length."""
    n = x.shape[-1]
    nf = nf or next_fast_len(n + n // 4, real=True)
    _, h = _hp_response(nf, fs, f_hp, f_lp)
    return np.asarray(np.fft.irfft(np.fft.rfft(x, nf, axis=-1) * h, nf, axis=-1)[..., :n])


def _set_rates(st: fx.States, tests: Sequence[TestData],
               band_hz: tuple[float, float] | None = None) -> None:
    """The sample rate and input band (computed unless given) the effects' bases need
    (filters over frequency)."""
    st.fs_hz = tests[0].fs_hz
    st.band_hz = input_band(tests) if band_hz is None else band_hz


def matrices(m: mdl.Model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Masses, K, C and the modes (rad/s, mass-normalised shapes), as the C core builds them
    (model.linear)."""
    lin = mdl.linear(m)
    return lin.mass, lin.k, lin.c, lin.w, lin.phi


def _external(m: mdl.Model, t: TestData, mass: np.ndarray, k: np.ndarray, c: np.ndarray,
              hp: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray | None,
                                                               np.ndarray | None]:
    """The input's force on every DOF (n x T) in the model's coordinates, and the ground's
    displacement and velocity where the elements see them (ground_disp), all high-passed:
    a force at its DOF; a ground acceleration a_g in relative coordinates, -M 1 a_g; a ground
    displacement u in absolute ones, K 1 u + C 1 u'."""
    n = m.n_dof
    u = hp(t.u)
    if m.input.kind == "force":
        f = np.zeros((n, u.size))
        f[m.input.dof - 1] = u
        return f, None, None
    if m.input.kind == "ground_acc":
        return -mass[:, None] * u[None, :], None, None
    vg = hp(np.gradient(t.u) * t.fs_hz)
    return k.sum(axis=1)[:, None] * u + c.sum(axis=1)[:, None] * vg, u, vg


# a view built from differentiated velocities or displacements stops at this x the input
# band's upper edge (at most 0.45 fs): their noise grows with frequency there (1 % white noise
# on a single-DOF oscillator's velocity sensor: its missing force correlates at 0.99 with an
# accelerometer's in the band)
LP_BAND = 1.5


def view_corner(modes_w: np.ndarray, band: tuple[float, float]) -> float:
    """The views' high-pass corner (Hz): 0.4 x the lowest flexible mode, and at least half the
    input band's lower edge: below it the structure barely moves and the sensors' low-frequency
    noise (a cheap DAQ's 1/f), integrated twice, would swamp the displacements a gap or a
    stick-slip acts on; in the output view it would be most of the residual (a free 3-DOF
    chain under the observer: 95 % of its one-step errors below 5 Hz, a 20-240 Hz input)."""
    flex = modes_w[modes_w > 2 * np.pi * 1.0]
    f_hp = 0.4 * float(flex.min()) / (2 * np.pi) if flex.size else 5.0
    return max(f_hp, 0.5 * band[0])


def force_view(m: mdl.Model, tests: Sequence[TestData], motions: bool = False
               ) -> ForceView | None:
    """Reconstruct states and the missing force, or None when not every DOF carries an
    accelerometer. A force input, a shake table (ground acceleration: the states relative to
    the ground, from the measured absolute accelerations minus the table's) and a prescribed
    ground displacement all give the same view. ``motions``: with a force input, a DOF
    without an accelerometer may have a velocity or displacement sensor, differentiated (the
    view then stops above the input band, LP_BAND); None when every DOF has an accelerometer
    (the plain view)."""
    chan_dof: dict[str, int] = {}
    # per DOF its accelerometer; with a force input, a DOF without one its velocity or
    # displacement sensor (differentiated)
    kinds = ORDER if motions and m.input.kind == "force" else ("acc",)
    for kind in kinds:
        for name, o in m.outputs.items():
            if (o.kind == kind and all(name in t.y for t in tests)
                    and (kind == "acc" or o.index not in chan_dof.values())):
                chan_dof.setdefault(name, o.index)
    dofs = {d: name for name, d in chan_dof.items()}
    n = m.n_dof
    if sorted(dofs) != list(range(1, n + 1)):
        return None
    orders = [ORDER[m.outputs[dofs[j]].kind] for j in range(1, n + 1)]
    if motions and not any(orders):
        return None
    mass, k, c, w, phi = matrices(m)
    fs = tests[0].fs_hz
    band = input_band(tests)
    f_hp = view_corner(w, band)
    # a differentiated displacement or velocity sensor's noise grows with frequency: the view
    # stops above the input band (LP_BAND x its upper edge)
    f_lp = min(LP_BAND * band[1], 0.45 * fs) if any(orders) else None
    xs: list[np.ndarray] = []
    vs: list[np.ndarray] = []
    as_: list[np.ndarray] = []
    fs_list: list[np.ndarray] = []
    grounds: list[tuple[np.ndarray, np.ndarray]] = []
    tables: list[np.ndarray] = []
    trim_frac = 0.04

    def hp(z: np.ndarray) -> np.ndarray:
        # bases built from nonlinear functions of the states get the same high-pass
        return _hp(z, fs, f_hp, f_lp)

    for t in tests:
        # each DOF's motion as its sensor reads it (an acceleration, else as ``orders`` say)
        y = np.vstack([(t.y[dofs[j]] - m.outputs[dofs[j]].offset) / m.outputs[dofs[j]].gain
                       for j in range(1, n + 1)])
        if m.input.kind == "ground_acc":
            y = y - t.u[None, :]  # the model's coordinates are relative to the table
        ah, vh, xh = _integrate(y, orders, fs, f_hp, f_lp)
        fext, ug, vg = _external(m, t, mass, k, c, hp)
        f_el = hp(el.restoring(m.elements, xh, vh, 0.0 if ug is None else ug,
                               0.0 if vg is None else vg))
        fm = fext - mass[:, None] * ah - c @ vh - k @ xh - f_el
        cut = int(trim_frac * t.u.size)
        sl = slice(cut, t.u.size - cut)
        xs.append(xh[:, sl])
        vs.append(vh[:, sl])
        as_.append(ah[:, sl])
        fs_list.append(fm[:, sl])
        if ug is not None and vg is not None:
            grounds.append((ug[sl], vg[sl]))
        if m.input.kind == "ground_acc":
            tables.append(hp(t.u)[sl])

    xg = np.concatenate([g[0] for g in grounds]) if grounds else None
    vgs = np.concatenate([g[1] for g in grounds]) if grounds else None
    st = fx.States(np.hstack(xs), np.hstack(vs), np.hstack(as_), mass, k, c, w, phi, hp,
                   chan_dof, xg, vgs, ag=np.concatenate(tables) if tables else None)
    _set_rates(st, tests, band)
    return ForceView(st, np.hstack(fs_list), slice(None))


def reaction_view(m: mdl.Model, tests: Sequence[TestData]) -> ForceView | None:
    """For a model whose measured output is the reaction (force on the ground), e.g. an
    element driven by a prescribed stroke (ground_disp input): the states come from the
    model's own open-loop simulation (the observer's estimate), the ground motion from the
    input, and the missing force is the reaction residual, seen at DOF 1 (a missing story-1
    or DOF-1-to-ground force g changes the reaction by g). Other effects act on the reaction
    only through the dynamics: their bases are judged on their DOF-1 row."""
    rc = [c for c, o in m.outputs.items() if o.kind == "reaction" and all(c in t.y for t in tests)]
    if not rc or m.input.kind == "ground_acc":
        return None
    c0 = rc[0]
    n = m.n_dof
    mass, k, c, w, phi = matrices(m)
    xs, vs, as_, fl, xg, vg = [], [], [], [], [], []
    pred: dict[str, list[np.ndarray]] = {ch: [] for ch in m.outputs}
    for t in tests:
        p = _simulate_states(m, t)
        if p is None:
            return None
        xs.append(_dof_rows(p, "x", n))
        vs.append(_dof_rows(p, "v", n))
        as_.append(_dof_rows(p, "a", n))
        f = np.zeros((n, t.u.size))
        f[0] = (t.y[c0] - p[c0]) / m.outputs[c0].gain
        fl.append(f)
        for ch, o in m.outputs.items():
            pred[ch].append((p[ch] - o.offset) / o.gain)
        if m.input.kind == "ground_disp":
            xg.append(t.u)
            vg.append(np.gradient(t.u) * t.fs_hz)
        else:
            xg.append(np.zeros(t.u.size))
            vg.append(np.zeros(t.u.size))

    def ident(z: np.ndarray) -> np.ndarray:
        return z

    st = fx.States(np.hstack(xs), np.hstack(vs), np.hstack(as_), mass, k, c, w, phi, ident,
                   {}, np.concatenate(xg), np.concatenate(vg),
                   {ch: np.concatenate(v) for ch, v in pred.items()}, True)
    _set_rates(st, tests)
    return ForceView(st, np.hstack(fl), slice(None))


def _frf(m: mdl.Model, chans: Sequence[str], nf: int, fs: float) -> np.ndarray:
    """Frequency responses (rfft grid of length nf, n_out x n_dof) of the model's linear part
    from a force at each DOF to each output channel (acc/vel/disp, with its gain)."""
    mass, k, c, _, _ = matrices(m)
    w = 2 * np.pi * np.fft.rfftfreq(nf, 1.0 / fs)
    dyn = (k[None, :, :] - (w ** 2)[:, None, None] * np.diag(mass)[None, :, :]
           + 1j * w[:, None, None] * c[None, :, :])
    if float(np.min(np.abs(np.linalg.det(dyn[:1])))) == 0.0:  # a rigid-body mode at DC
        dyn[0] += np.eye(mass.size) * 1e-9 * float(np.max(np.abs(k)) or 1.0)
    hx = np.linalg.inv(dyn)  # nfreq x n x n, displacement per force
    rows = []
    for ch in chans:
        o = m.outputs[ch]
        fac = {"acc": -(w ** 2), "vel": 1j * w, "disp": np.ones_like(w)}[o.kind] * o.gain
        rows.append(fac[:, None] * hx[:, o.index - 1, :])
    return np.stack(rows, axis=1)  # nfreq x n_out x n


def _dof_rows(p: dict[str, np.ndarray], kind: str, n: int) -> np.ndarray:
    """n x samples: the __<kind><j> series of _simulate_states() for DOF j = 1..n."""
    return np.vstack([p[f"__{kind}{j}"] for j in range(1, n + 1)])


def _simulate_states(m: mdl.Model, t: TestData) -> dict[str, np.ndarray] | None:
    """The model's outputs and every DOF's displacement, velocity and acceleration (__x<j>,
    __v<j>, __a<j>): open loop, or in observer mode (t.observer) the observer's one-step
    estimate, which the measurements hold where the open-loop simulation drifts; in runs
    within the core's output limit."""
    probes: dict[str, mdl.Output] = {}
    for j in range(1, m.n_dof + 1):
        probes[f"__x{j}"] = mdl.Output("disp", j)
        probes[f"__v{j}"] = mdl.Output("vel", j)
        probes[f"__a{j}"] = mdl.Output("acc", j)
    limit = core_limits()["out"]
    out: dict[str, np.ndarray] = {}
    try:
        if t.observer is None:
            want = {**m.outputs, **probes}
            names = list(want)
            for i in range(0, len(names), limit):
                probe = dataclasses.replace(m, outputs={c: want[c] for c in names[i:i + limit]})
                out.update(mdl.simulate(probe, t.input_for(probe), t.fs_hz))
            return out
        per = limit - len(m.outputs)  # every run carries the measured outputs that correct it
        if per < 1:
            return None
        names = list(probes)
        for i in range(0, len(names), per):
            out.update(mdl.predict_observed(m, t.observer_input(m), t.y, t.fs_hz,
                                            t.observer.q_force_n2, t.observer.r_meas,
                                            {c: probes[c] for c in names[i:i + per]}))
    except DynvalError:
        return None
    return out


IMPULSE_DELAY = 32  # samples: the band-limited interpolation's ringing before an impulse


def _innovation_frf(m: mdl.Model, obs: Observer, chans: Sequence[str], nf: int, fs: float
                    ) -> np.ndarray:
    """_frf's counterpart in observer mode (nfreq x n_out x n_dof): what a unit-sample force at
    each DOF, which the model lacks, leaves in the observer's one-step errors. The sensors read
    the linear part's open-loop response to it; the observer, which does not know the force, is
    corrected by those readings, so the errors are its innovations of that response (a drift
    the force starts is held, as in the tests). ConfigError when the core refuses a run."""
    lin = dataclasses.replace(m, elements=(), outputs={c: m.outputs[c] for c in chans})
    f = np.zeros(nf)
    f[IMPULSE_DELAY] = 1.0
    cols = []
    for j in range(1, m.n_dof + 1):
        mj = dataclasses.replace(lin, input=mdl.Input("force", j))
        y = mdl.simulate(mj, f, fs)
        p = mdl.predict_observed(mj, np.zeros(nf), y, fs, obs.q_force_n2, obs.r_meas)
        e = np.vstack([np.roll(y[c] - p[c], -IMPULSE_DELAY) for c in chans])
        cols.append(np.fft.rfft(e, axis=-1))
    return np.stack(cols, axis=-1).transpose(1, 0, 2)


def output_view(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
                scales: dict[str, float]) -> ForceView | None:
    """The evidence view for any sensor set (some DOFs without an accelerometer, the force at
    any DOF): the states of every DOF come from the model's own open-loop simulation and a
    candidate's restoring-force field g is judged by what it would take away from the
    measured outputs, G g, with G the model's linear frequency response from a force at each
    DOF to each channel (first-order, Born approximation: y_meas = y_model - G g). In
    observer mode the states are the observer's estimates, the residual its one-step errors,
    and G what a force leaves in them (_innovation_frf): an open-loop residual there is the
    drift. Channels are normalised by their measured RMS, as in the fit. On a shake
    table the states are relative to it and G is the same (the table's motion is prescribed:
    a missing force changes the relative motion only). The residual and every image are
    high-passed at view_corner, as the force view's states are. None for a ground-displacement
    input or when a channel is not an acc/vel/disp output."""
    table = m.input.kind == "ground_acc"
    if m.input.kind not in ("force", "ground_acc") or not chans:
        return None
    if any(m.outputs[c].kind not in ("acc", "vel", "disp") for c in chans):
        return None
    n = m.n_dof
    mass, k, c, w, phi = matrices(m)
    fs = tests[0].fs_hz
    f_hp = view_corner(w, input_band(tests))
    xs, vs, as_, target, tables = [], [], [], [], []
    pred: dict[str, list[np.ndarray]] = {ch: [] for ch in chans}
    lens: list[int] = []
    for t in tests:
        p = _simulate_states(m, t)
        if p is None:
            return None
        xs.append(_dof_rows(p, "x", n))
        vs.append(_dof_rows(p, "v", n))
        # the core's acceleration outputs are absolute; its states are relative to a table
        as_.append(_dof_rows(p, "a", n) - (t.u[None, :] if table else 0.0))
        if table:
            tables.append(t.u)
        ln = t.u.size
        nf = next_fast_len(2 * ln, real=True)  # the grid propagate() filters the images on
        target.append(np.concatenate([-_hp(t.y[ch] - p[ch], fs, f_hp, nf=nf) / scales[ch]
                                      for ch in chans]))
        for ch in chans:
            pred[ch].append(_hp(p[ch], fs, f_hp, nf=nf) / scales[ch])
        lens.append(ln)
    frf: dict[int, np.ndarray] = {}
    obs = tests[0].observer
    for ln in set(lens):
        nf = next_fast_len(2 * ln, real=True)
        try:
            frf[ln] = _frf(m, chans, nf, fs) if obs is None else _innovation_frf(m, obs, chans,
                                                                                 nf, fs)
        except DynvalError:
            return None
        frf[ln] = frf[ln] * _hp_response(nf, fs, f_hp)[1][:, None, None]
    inv_scale = np.array([1.0 / scales[ch] for ch in chans])
    # by the DOF the force is at, then channel, then frequency: one DOF's block read whole
    # (indexing the frequency-first array by DOF copied it per basis, a third of the view)
    by_dof = {ln: np.ascontiguousarray(h.transpose(2, 1, 0)) for ln, h in frf.items()}

    def propagate(b: np.ndarray) -> np.ndarray:
        parts = []
        i0 = 0
        rows = np.flatnonzero(np.any(b != 0.0, axis=1))
        for ln in lens:
            seg = b[rows, i0:i0 + ln]
            i0 += ln
            h = by_dof[ln]
            nf = 2 * (h.shape[2] - 1)
            if rows.size == 0:
                parts.append(np.zeros(len(chans) * ln))
                continue
            spec = np.fft.rfft(seg, nf, axis=-1)  # r x F
            ys = h[rows[0]] * spec[0]  # channels x F
            for i in range(1, rows.size):
                ys += h[rows[i]] * spec[i]
            y = np.fft.irfft(ys, nf, axis=-1)[:, :ln] * inv_scale[:, None]
            parts.append(y.ravel())
        return np.concatenate(parts)

    def ident(z: np.ndarray) -> np.ndarray:
        return z

    st = fx.States(np.hstack(xs), np.hstack(vs), np.hstack(as_), mass, k, c, w, phi, ident,
                   {}, ag=np.concatenate(tables) if tables else None)
    _set_rates(st, tests)
    return ForceView(st, np.concatenate(target)[None, :], slice(None), propagate,
                     {ch: np.concatenate(v) for ch, v in pred.items()}, lens)


def _output_gain_basis(view: ForceView, cand: fx.Candidate) -> np.ndarray | None:
    """A sensor gain in the output view: channel c's prediction (normalised), zero elsewhere
    (layout of the target: per test, the channels one after the other); its amplitude is
    1 - g/g0 (the reaction view's convention)."""
    ch = cand.location["channel"]
    if ch not in view.out_pred:
        return None
    out = []
    i0 = 0
    for ln in view.seg_lens:
        for c, v in view.out_pred.items():
            out.append(v[i0:i0 + ln] if c == ch else np.zeros(ln))
        i0 += ln
    return np.concatenate(out)


_NUISANCE = ("stiffness_change", "damping_change")


def _declared_name(cand: fx.Candidate) -> str:
    """The declared parameter a nuisance basis's coefficient adds to (a story stiffness k<s>
    in N/m, a modal damping ratio zeta<i>), '' for one that adds to none by itself (a
    Rayleigh coefficient's basis)."""
    if cand.type == "stiffness_change":
        return fx.by_type(cand.type).changes(cand)
    return f"zeta{cand.location['mode']}" if "mode" in cand.location else ""


class _Products:
    """A basis's |bv|^2, bv.f, Q'bv and bv.f_res, for its image bv: the basis itself when
    1-D, else the rows of an n x T restoring-force field (the force view's layout, DOF by
    DOF) taken over only the rows it is not zero on (an element between two DOFs of six:
    a third of the products)."""

    def __init__(self, f: np.ndarray, f_res: np.ndarray, qt: np.ndarray, rows: int) -> None:
        self.f, self.f_res, self.qt = f, f_res, qt
        self.f_rows, self.res_rows = f.reshape(rows, -1), f_res.reshape(rows, -1)
        self.qt_rows = qt.reshape(qt.shape[0], rows, -1)
        self.rows = rows

    def __call__(self, b: np.ndarray) -> tuple[float, float, np.ndarray, float]:
        if b.ndim == 1:
            return float(b @ b), float(b @ self.f), self.qt @ b, float(b @ self.f_res)
        bb = bf = bfr = 0.0
        qb = np.zeros(self.qt.shape[0])
        for r in np.flatnonzero(np.any(b[:self.rows] != 0.0, axis=1)):
            bb += float(b[r] @ b[r])
            bf += float(b[r] @ self.f_rows[r])
            bfr += float(b[r] @ self.res_rows[r])
            qb += self.qt_rows[:, r] @ b[r]
        return bb, bf, qb, bfr


def score(view: ForceView, cands: Sequence[fx.Candidate], workers: int = 1
          ) -> list[Evidence]:
    """Evidence of each candidate: the partial R^2 of its best-shaped basis on the missing
    force once the linear model's own parameters (story stiffnesses, damping) may re-adjust:
    (R^2(nuisance + candidate) - R^2(nuisance)) / (1 - R^2(nuisance)). A declared model that
    was calibrated on the data has absorbed what a stiffness or damping change can of the
    effect; the partial R^2 looks at what is left. Candidates that are themselves stiffness or
    damping changes get their plain R^2. The candidates are scored on up to ``workers``
    processes (the same numbers)."""
    ro = view.states.reaction_only
    f = (view.f_miss[:1] if ro else view.f_miss).ravel()
    ff = float(f @ f) or 1e-300

    def image(b: np.ndarray) -> np.ndarray:
        if view.propagate is not None:
            return view.propagate(b)
        return (b[:1] if ro else b).ravel()

    def dense(b: np.ndarray) -> np.ndarray:  # a basis as bases() gives it, as its image
        return b if b.ndim == 1 else image(b)

    def bases(cand: fx.Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        """The candidate's bases, as restoring-force fields (n x T) where the view reads them
        as they are, else as their images (1-D: the output view's)."""
        if view.propagate is not None and cand.type == "sensor_gain":
            g = _output_gain_basis(view, cand)
            return [] if g is None else [({"reaction": 1.0}, g)]
        return [(sh, b if view.propagate is None else image(b))
                for sh, b in fx.by_type(cand.type).basis(view.states, cand)]

    nuis, nuis_params = [], []
    for cand in cands:
        if cand.type in _NUISANCE:
            for _, b in bases(cand):
                nuis.append(dense(b))
                nuis_params.append(_declared_name(cand))
    # Q' stored row by row (Q' b read contiguously: 2.6 x faster a product than Q's columns)
    qt = np.zeros((0, f.size))
    to_coef = np.zeros((0, 0))  # q' g -> the nuisance columns' coefficients of g (a's pinv)
    if nuis:
        a = np.column_stack(nuis)
        u, sv, vt = np.linalg.svd(a, full_matrices=False)
        keep = sv > 1e-9 * (sv[0] if sv.size else 1.0)
        qt = np.ascontiguousarray(u[:, keep].T)
        to_coef = vt[keep].T / sv[keep]
    qf = qt @ f
    f_res = f - qt.T @ qf
    r2_n = 1.0 - float(f_res @ f_res) / ff
    fr = float(f_res @ f_res) or 1e-300
    products = _Products(f, f_res, qt, 1 if ro else view.f_miss.shape[0])

    def joint(qb: np.ndarray, amp: float) -> tuple[float, dict[str, float]]:
        # the candidate's coefficient in the regression on [nuisances, basis] is its
        # projection with the nuisances out (Frisch-Waugh-Lovell); the nuisances' own
        # coefficients are those of f - amp bv: a best-linear stiffness's absorbed part
        dk = to_coef @ (qf - amp * qb)
        return amp, {n: float(d) for n, d in zip(nuis_params, dk, strict=True) if n}

    def evidence(cand: fx.Candidate) -> Evidence:
        plain = cand.type in _NUISANCE
        nonlinear = fx.by_type(cand.type).nonlinear
        best = Evidence(cand, 0.0, 0.0)
        for shape, b in bases(cand):
            bb, bf, qb, bfr = products(b)
            if bb <= 0:
                continue
            amp = bf / bb
            if plain:
                r2 = amp * amp * bb / ff
            else:
                # the basis with the nuisance span taken out, br = bv - Q Q'bv, is not formed
                # (one product of Q less): br.f_res = bv.f_res as f_res is orthogonal to Q, and
                # |br|^2 = |bv|^2 - |Q'bv|^2, computed directly where that difference cancels
                brr = bb - float(qb @ qb)
                if brr <= 1e-6 * bb:
                    br = dense(b) - qt.T @ qb
                    brr = float(br @ br)
                if brr <= 1e-12 * bb:
                    continue
                r2 = bfr ** 2 / brr / fr
                # the coefficient's sign with the linear nuisances taken out: a softening
                # spring's evidence, against a best-linear model's stiffness too
                shape = {**shape, "sign": 1.0 if bfr >= 0 else -1.0}
            if r2 > best.r2:
                # a linear change's basis is nearly collinear with the nuisances' (a mass
                # against the stiffnesses in a band): no joint estimate for it
                best = Evidence(cand, r2, amp, dict(shape),
                                joint(qb, bfr / brr) if nonlinear else None)
        best.shape.update(fx.by_type(cand.type).motion_scales(view.states, cand))
        return best

    out = parallel.ordered_map(evidence, cands, workers)
    out.sort(key=lambda e: -e.r2)
    log.debug("evidence: the linear nuisance bases explain %.3f of the missing force", r2_n)
    return out


def surface(view: ForceView, story: int) -> tuple[np.ndarray, np.ndarray]:
    """Story drift and the missing story force (from the top: g_n = f_n, g_s = f_s + g_{s+1}
    as restoring forces) for the restoring-force-surface plot."""
    f = view.f_miss
    n = f.shape[0]
    g = np.zeros(f.shape[1])
    for j in range(n, story - 1, -1):
        g = g + f[j - 1]
    d, _ = fx.drift(view.states, story)
    return d, g


def describe(evs: Sequence[Events], sp: Sequence[Spectrum]) -> dict[str, Any]:
    """A short summary of the time and frequency traits."""
    inter = float(np.mean([e.intermittency for e in evs])) if evs else math.nan
    kurt = float(np.mean([e.kurtosis for e in evs])) if evs else math.nan
    nm = float(np.mean([s.near_modes for s in sp])) if sp else math.nan
    ab = float(np.mean([s.above_band for s in sp])) if sp else math.nan
    ib = float(np.mean([s.in_band for s in sp])) if sp else math.nan
    if inter > 0.3 or kurt > 5:
        t_kind = "intermittent (bursts: impacts, stick-slip)"
    else:
        t_kind = "steady"
    if ab > 0.25:
        f_kind = "broadband / harmonics above the input band"
    elif nm > 0.6:
        f_kind = "concentrated at the resonances (frequency shift or damping)"
    else:
        f_kind = "spread over the input band"
    return {"time": t_kind, "frequency": f_kind, "intermittency": inter, "kurtosis": kurt,
            "energy_near_modes": nm, "energy_in_band": ib, "energy_above_band": ab}
