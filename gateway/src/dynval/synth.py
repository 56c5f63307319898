"""Synthetic "measured" tests for tests, studies and benchmarks (not used by the runtime
commands): a truth model simulated by the C core through the binding (dynval.model.simulate),
never C compiled at run time.

Two generators:

* ``generate``: a declared model plus what it lacks (``Truth``: story stiffness and mass
  changes, damping ratios, sensor gains, extra elements of the registry). The truth runs at
  ``fine`` x the output rate (default 16), the force band-limited random (white noise through a
  4th-order Butterworth band-pass at the fine rate, linear between fine samples, the core's
  first-order hold); a DAQ is imitated: an anti-alias low-pass on every channel (force
  included) at the fine rate (``daq``: a causal 8th-order Butterworth at 0.4 fs by default, or
  an alias-free delta-sigma one, which a hammer test's broadband force needs: daq_filter),
  decimation to fs, and white sensor noise of ``noise`` x the clean RMS of each channel.
* ``reciprocal``: generate's tests and the same with the force at another DOF (the
  reciprocity check's pair; generate's two levels give the linearity check's).
* ``make_experiments``: a truth model driven by zero-phase band-limited forces through
  model.simulate, with test-to-test variation of chosen parameters and of the force level, and
  white sensor noise on every channel.

``generate`` makes the report's three test types (Section 4.2): band-limited random (the
default), harmonic (``Sine``: 71 Hz on the linear, 54 Hz on the nonlinear structure) and
impact hammer (``Hammer``: put the model's input at the struck DOF, floor 1 in the report),
and a shaker's swept sine (``Sweep``), as many measured tests are.
"""
from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynval import labels as lb
from dynval import model as mdl
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover import residual as rs
from dynval.errors import ConfigError
from dynval.io.recording import Channel, Recording
from dynval.model.structure import with_appendage

signal: Any = importlib.import_module("scipy.signal")


@dataclass(frozen=True)
class Appendage:
    """A secondary mass hanging from a DOF on a spring and a dashpot: its fixed-base
    frequency and damping ratio (model.structure.with_appendage)."""

    dof: int
    mass_kg: float
    f_hz: float
    zeta: float = 0.02


@dataclass(frozen=True)
class Truth:
    """What the generator's structure has on top of the declared model: relative changes of
    story stiffness (k_scale) and mass (m_add_kg), modal damping ratios (zeta, None: the
    model's damping), sensor gains per output channel, elements (model.elements types) and
    appendages (unmodelled modes; no sensor on them)."""

    k_scale: dict[int, float] = field(default_factory=dict)
    m_add_kg: dict[int, float] = field(default_factory=dict)
    zeta: tuple[float, ...] | None = None
    gains: dict[str, float] = field(default_factory=dict)
    elements: tuple[mdl.Element, ...] = ()
    appendages: tuple[Appendage, ...] = ()
    label: str = "clean"


@dataclass(frozen=True)
class Sine:
    """A harmonic test: a sine of f_hz whose RMS is the test's level, random phase, switched
    on (0.25 s cosine ramp) lead_s before the record so the free transient has died out."""

    f_hz: float
    lead_s: float = 2.0


@dataclass(frozen=True)
class Hammer:
    """An impact-hammer test: half-sine force pulses of width_s whose peak is the test's level,
    at times_s from the record's start."""

    times_s: tuple[float, ...] = (0.1,)
    width_s: float = 0.004


@dataclass(frozen=True)
class Sweep:
    """A swept-sine test (a shaker's chirp): from f0_hz to f1_hz over the record, linear or
    logarithmic in frequency, its RMS the test's level, cosine ramps of ramp_s at both ends
    (a sweep starts and ends at rest, so it carries its own start-up transient)."""

    f0_hz: float
    f1_hz: float
    method: str = "logarithmic"
    ramp_s: float = 0.25


Excitation = Sine | Hammer | Sweep


def excitation_force(exc: Excitation, rng: np.random.Generator, n: int, fs_hz: float,
                     level: float) -> np.ndarray:
    """The force of a harmonic, swept-sine or hammer test at fs_hz, n samples (a Sine's lead
    included)."""
    t = np.arange(n) / fs_hz
    if isinstance(exc, Sweep):
        dur = n / fs_hz
        ramp = np.minimum(1.0, np.minimum(t, dur - t) / exc.ramp_s).clip(0.0, 1.0)
        ramp = 0.5 - 0.5 * np.cos(np.pi * ramp)
        x = ramp * signal.chirp(t, exc.f0_hz, dur, exc.f1_hz, method=exc.method,
                                phi=float(rng.uniform(0, 360)))
        return np.asarray(level * x / np.sqrt(np.mean(x * x)))
    if isinstance(exc, Sine):
        ramp = 0.5 - 0.5 * np.cos(np.pi * np.minimum(t / 0.25, 1.0))
        return np.asarray(level * np.sqrt(2.0) * ramp
                          * np.sin(2 * np.pi * exc.f_hz * t + rng.uniform(0, 2 * np.pi)))
    f = np.zeros(n)
    for t0 in exc.times_s:
        on = (t >= t0) & (t <= t0 + exc.width_s)
        f[on] += level * np.sin(np.pi * (t[on] - t0) / exc.width_s)
    return f


def contact_onsets(m: mdl.Model, truth: Truth, force_fine: np.ndarray,
                   fs_fine_hz: float) -> np.ndarray:
    """Times (s) at which a contact element of the truth closes (its gap is crossed towards
    contact), sorted: the impacts a feature such as the Holder exponent should find."""
    contacts = [e for e in truth.elements if isinstance(e, mdl.Contact)]
    if not contacts:
        return np.zeros(0)
    dofs = sorted({j for e in contacts for j in (e.dof_a, e.dof_b) if j > 0})
    y = mdl.simulate(truth_model(m, truth, [("disp", j) for j in dofs]), force_fine,
                     fs_fine_hz, oversample=1)
    out: list[np.ndarray] = []
    for e in contacts:
        x = y[f"__disp{e.dof_b}"] - (y[f"__disp{e.dof_a}"] if e.dof_a > 0 else 0.0)
        for sign in {"pos": (1.0,), "neg": (-1.0,), "both": (1.0, -1.0)}[e.side]:
            shut = sign * x > e.gap_m
            out.append(np.flatnonzero(shut[1:] & ~shut[:-1]) + 1.0)
    return np.sort(np.concatenate(out or [np.zeros(0)])) / fs_fine_hz


DAQ_KINDS = ("butter8", "alias-free")


def daq_filter(kind: str, fs_hz: float, fs_fine_hz: float) -> Any:
    """The imitated DAQ's anti-alias low-pass (second-order sections at the fine rate).
    'butter8': a causal 8th-order Butterworth at 0.4 fs, an analog front end: only 44 dB down
    at 0.75 fs, where the 4 ms pulse of a Hammer still has a third of its low-frequency
    spectrum, so a hammer test's force aliases onto the modes (the measured force then drives
    a right model 0.08 % above the measured response: bench/RESULTS.catalogue.md);
    'alias-free': a delta-sigma DAQ's, elliptic, flat within 0.01 dB to 0.45 fs and at least
    100 dB down from 0.55 fs, what a broadband (impact) input needs."""
    if kind == "butter8":
        return signal.butter(8, 0.4 * fs_hz, btype="low", fs=fs_fine_hz, output="sos")
    if kind == "alias-free":
        order, wn = signal.ellipord(0.45 * fs_hz, 0.55 * fs_hz, 0.01, 100.0, fs=fs_fine_hz)
        return signal.ellip(order, 0.01, 100.0, wn, fs=fs_fine_hz, output="sos")
    raise ConfigError(f"daq '{kind}': expected one of {', '.join(DAQ_KINDS)}")


def band_limited_force(rng: np.random.Generator, n: int, fs_hz: float, rms: float,
                       band_hz: tuple[float, float] = (20.0, 200.0), *,
                       zero_phase: bool = False) -> np.ndarray:
    """White noise through a 4th-order Butterworth band-pass, scaled to rms. zero_phase: the
    filter forwards and backwards over 512 extra samples, the first 64 samples ramped in."""
    sos = signal.butter(4, band_hz, btype="bandpass", fs=fs_hz, output="sos")
    if not zero_phase:
        f = signal.sosfilt(sos, rng.standard_normal(n))
        return np.asarray(rms * f / np.sqrt(np.mean(f * f)))
    x = signal.sosfiltfilt(sos, rng.standard_normal(n + 512))[256:256 + n]
    x *= rms / np.sqrt(np.mean(x * x))
    return np.asarray(x * np.minimum(1.0, np.arange(n) / 64.0))


MOTION_KINDS = ("acc", "vel", "disp")


def truth_model(m: mdl.Model, truth: Truth,
                motions: Sequence[tuple[str, int]] | None = None) -> mdl.Model:
    """The truth as a model: m with the truth's changes and elements, as outputs the given
    motions (kind, DOF) or every DOF's acceleration (``__acc<j>``, ``__vel<j>``,
    ``__disp<j>``), the samples held linearly (no interpolation)."""
    params = {f"k{s}": m.stiffness_n_per_m[s - 1] * f for s, f in truth.k_scale.items()}
    params.update({f"m{j}": m.masses_kg[j - 1] + dm for j, dm in truth.m_add_kg.items()})
    tm = m.with_params(params) if params else m
    damp = tm.damping if truth.zeta is None else mdl.Damping("modal", zeta=tuple(truth.zeta))
    if motions is None:
        motions = [("acc", j) for j in range(1, m.n_dof + 1)]
    outs = {f"__{k}{j}": mdl.Output(k, j) for k, j in motions}
    tm = dataclasses.replace(tm, damping=damp, outputs=outs,
                             elements=(*m.elements, *truth.elements), interpolation="foh",
                             oversample=1)
    for a in truth.appendages:
        tm = with_appendage(tm, a.dof, a.mass_kg, a.f_hz, a.zeta)
    mdl.validate(tm)
    return tm


def simulate_truth(m: mdl.Model, truth: Truth, force_fine: np.ndarray,
                   fs_fine_hz: float) -> np.ndarray:
    """Accelerations (len(force_fine) x n, absolute) of the truth driven from rest by the
    model's input (a force at its DOF, a shake table's acceleration or a ground displacement),
    by the core at the fine rate."""
    y = mdl.simulate(truth_model(m, truth), force_fine, fs_fine_hz, oversample=1)
    return np.column_stack([y[f"__acc{j}"] for j in range(1, m.n_dof + 1)])


def simulate_truth_motion(m: mdl.Model, truth: Truth, force_fine: np.ndarray,
                          fs_fine_hz: float) -> dict[str, np.ndarray]:
    """The motions the model's outputs measure (``acc<j>``, ``vel<j>``, ``disp<j>``) of the
    truth driven from rest by the model's input, by the core at the fine rate."""
    motions = sorted({(o.kind, o.index) for o in m.outputs.values() if o.kind in MOTION_KINDS})
    y = mdl.simulate(truth_model(m, truth, motions), force_fine, fs_fine_hz, oversample=1)
    return {k[2:]: v for k, v in y.items()}


def best_linear(m: mdl.Model, recs: Sequence[Recording], max_nfev: int = 60) -> mdl.Model:
    """The declared model of the best-linear condition (issue 16, item 1): ``m`` with its
    story stiffnesses k2..kn and its damping (modal ratios, or Rayleigh a and b) fitted to the
    recordings by discover's output-error fit (``max_nfev`` evaluations), the masses and k1
    (the ground spring, or the table's) kept: the linear model a user fits by hand to the same
    tests, into which part of any nonlinearity goes. Raises ConfigError as fit.fit does."""
    tests = rs.prepare(m, recs)
    chans = rs.common_channels(m, tests)
    names = (*(f"k{i}" for i in range(2, m.n_dof + 1)),
             *(n for n in m.parameters() if n.startswith("zeta") or n in ("alpha", "beta")))
    return ft.fit(m, fx.NONE.candidates(m)[0], [], tests, chans,
                  rs.channel_scales(tests, chans), max_nfev, names).model


def generate(m: mdl.Model, truth: Truth, *, n_tests: int = 10,
             levels_n_rms: tuple[float, ...] = (12.0, 7.2), n_samples: int = 8192,
             fs_hz: float = 640.0, fine: int = 16, noise: float = 0.01, seed: int = 0,
             band_hz: tuple[float, float] = (20.0, 200.0), excitation: Excitation | None = None,
             onsets: list[np.ndarray] | None = None, daq: str = "butter8") -> list[Recording]:
    """n_tests measured tests (levels cycled: test i has input RMS levels[i % len(levels)],
    in the input's unit: N, m/s^2 for a shake table, m for a ground displacement; a Hammer's
    level is its peak force), as Recordings whose columns are the model's input channel
    (default 'force_N') and its acceleration, velocity and displacement outputs (other output
    kinds are not generated). excitation: None, band-limited random; a Sine, a Sweep or
    a Hammer.
    onsets: if a list, each test's contact_onsets (s from the record's start) are appended.
    daq: the DAQ's anti-alias filter (daq_filter: 'alias-free' for hammer tests)."""
    rng = np.random.default_rng(seed)
    fs_fine = fs_hz * fine
    aa = daq_filter(daq, fs_hz, fs_fine)
    in_name = m.input.channel or "force_N"
    motion_outs = {name: o for name, o in m.outputs.items() if o.kind in MOTION_KINDS}
    if not motion_outs:
        raise ConfigError("the generator produces motions: the model has no acc, vel or disp "
                          "output")
    recs = []
    for i in range(n_tests):
        level = levels_n_rms[i % len(levels_n_rms)]
        lead = round(excitation.lead_s * fs_hz) if isinstance(excitation, Sine) else 0
        n_fine = (n_samples + lead) * fine
        f = (band_limited_force(rng, n_fine, fs_fine, level, band_hz) if excitation is None
             else excitation_force(excitation, rng, n_fine, fs_fine, level))
        motion = simulate_truth_motion(m, truth, f, fs_fine)
        if onsets is not None:
            t_on = contact_onsets(m, truth, f, fs_fine) - lead / fs_hz
            onsets.append(t_on[(t_on >= 0) & (t_on < n_samples / fs_hz)])
        cols = {in_name: f}
        for name, o in motion_outs.items():
            cols[name] = motion[f"{o.kind}{o.index}"] * truth.gains.get(name, 1.0)
        chans = []
        for name, x in cols.items():
            y = signal.sosfilt(aa, x)[::fine][lead:]
            y = y + noise * float(np.sqrt(np.mean(y * y))) * rng.standard_normal(y.size)
            chans.append(Channel(name=name, data=np.ascontiguousarray(y),
                                 unit=lb.SI_UNIT[m.input.kind] if name == in_name
                                 else lb.SI_UNIT[m.outputs[name].kind],
                                 role="input" if name == in_name else "output"))
        tag = "high" if level == max(levels_n_rms) else "low"
        recs.append(Recording(name=f"{truth.label}_{tag}_{i + 1:02d}", fs_hz=fs_hz,
                              channels=chans))
    return recs


def reciprocal(m: mdl.Model, truth: Truth, dof: int, **kw: Any
               ) -> tuple[list[Recording], list[Recording]]:
    """The report's reciprocity pair (its Section 5.3.1): generate's tests with the force at
    m's input DOF, and the same number with the force moved to ``dof`` (same channels; the
    response at the first input DOF is then the reciprocal one), from independent draws.
    kw: generate's (levels_n_rms gives the two excitation levels of the linearity check)."""
    if m.input.kind != "force":
        raise ConfigError(f"reciprocity swaps a force's DOF; the model's input is a "
                          f"{m.input.kind}")
    seed = int(kw.pop("seed", 0))
    moved = dataclasses.replace(m, input=dataclasses.replace(m.input, dof=dof))
    mdl.validate(moved)
    moved_truth = dataclasses.replace(truth, label=f"{truth.label}_at{dof}")
    return (generate(m, truth, seed=seed, **kw),
            generate(moved, moved_truth, seed=seed + 1_000_003, **kw))


def make_experiments(truth: mdl.Model, n_tests: int = 20, *, fs_hz: float = 640.0,
                     n_samples: int = 8192, force_rms: float = 12.0,
                     band_hz: tuple[float, float] = (20.0, 200.0), noise: float = 0.01,
                     variation: Mapping[str, float] | None = None, level_var: float = 0.02,
                     force_channel: str = "force_N", seed: int = 0,
                     oversample: int | None = None) -> list[Recording]:
    """n_tests recordings of the truth model. variation: parameter -> relative STD of its
    test-to-test scatter (e.g. {"zeta2": 0.03}); level_var: relative STD of the force RMS;
    noise: sensor noise STD relative to each channel's RMS."""
    rng = np.random.default_rng(seed)
    base = truth.parameters()
    recs = []
    for k in range(n_tests):
        params = {n: base[n] * (1.0 + s * rng.standard_normal())
                  for n, s in (variation or {}).items()}
        m = truth.with_params(params) if params else truth
        rms = force_rms * (1 + level_var * rng.standard_normal())
        f = band_limited_force(rng, n_samples, fs_hz, rms, band_hz, zero_phase=True)
        y = mdl.simulate(m, f, fs_hz, oversample=oversample)
        chans = [Channel(force_channel, f + noise * np.sqrt(np.mean(f * f))
                         * rng.standard_normal(n_samples), "N", "input")]
        for name, v in y.items():
            rms = float(np.sqrt(np.mean(v * v)))
            chans.append(Channel(name, v + noise * rms * rng.standard_normal(n_samples),
                                 "m/s^2" if name.startswith("acc") else "", "output"))
        recs.append(Recording(f"exp{k + 1:02d}", fs_hz, chans))
    return recs


def write_csv(rec: Recording, path: Path | str) -> None:
    """Write a Recording in the shared data's CSV layout (time_s first). Column names are the
    channel names as they are (a model names its channels by the tests' columns, so a
    generated test must keep them: 'a1' stays 'a1', 'acc1_mps2' stays 'acc1_mps2')."""
    t = rec.t0_s + np.arange(rec.n_samples) / rec.fs_hz
    data = np.column_stack([t] + [c.data for c in rec.channels])
    np.savetxt(path, data, delimiter=",", header=",".join(["time_s", *rec.names]), comments="",
               fmt="%.10g")
