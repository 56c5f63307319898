"""The library of physical effects `dynval discover` can add to a declared model.

Each effect type is a small unit (a subclass of EffectType) that says:

* where it can sit (``locations``: stories, DOFs, channels, modes) and its force law (``law``);
* its parameters with bounds and units (``params``), fitted in scaled coordinates
  (``to_model`` maps the fit vector onto the model);
* how it maps onto the model (``apply``): a parameter change of the linear model, a new entry
  of ``Model.elements``, or an output's sensor gain;
* its evidence basis (``basis``): the shape of the missing force it would produce on every
  DOF, given the states reconstructed from the measurements (see trace.py).

Numbering follows the model (1-based): story s ties DOF s-1 to DOF s (story 1: ground to
DOF 1); X = x_s - x_{s-1} is the story drift. Elements sit between any two DOFs a < b (a = 0:
the ground), X = x_b - x_a: a sliding joint between DOF 1 and DOF 2 is as much a candidate as
a bumper across a story.

Effects that add an element (contact, friction, stick-slip, cubic spring, v|v| damper, a
constant force offset) are
built from the element registry (dynval.model.elements): their parameters carry the registry's
names and units, and their evidence bases are the element's law evaluated by the core
(dv_elem_force_block), never a copy of it. ``available = False`` (ranked on evidence, never
fitted) is left for effect types the model cannot represent.
"""
from __future__ import annotations

import dataclasses
import importlib
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.model import elements as el
from dynval.model.structure import with_appendage

log = logging.getLogger(__name__)
_signal: Any = importlib.import_module("scipy.signal")


@dataclass(frozen=True)
class Param:
    """One parameter: name, unit, bounds in model units, and whether it is fitted in log."""

    name: str
    unit: str
    lower: float
    upper: float
    log: bool = False


@dataclass(frozen=True)
class Candidate:
    """An effect type at a location, e.g. contact at story 4 on the positive side."""

    type: str
    location: dict[str, Any]
    label: str
    available: bool
    note: str = ""
    shape: dict[str, float] = field(default_factory=dict)  # set by the evidence scan


@dataclass
class States:
    """Reconstructed states of the fitting tests (concatenated, n_dof x T each) and the
    model's matrices; ``hp`` filters a (n x T or T) array like the states were filtered."""

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    mass: np.ndarray
    k: np.ndarray
    c: np.ndarray
    modes_w: np.ndarray
    modes_phi: np.ndarray
    hp: Any
    channels_dof: dict[str, int]
    xg: np.ndarray | None = None  # ground displacement / velocity (ground_disp input)
    vg: np.ndarray | None = None
    predicted: dict[str, np.ndarray] = field(default_factory=dict)  # model outputs (fitting)
    reaction_only: bool = False  # the missing force is seen only through the reaction
    fs_hz: float = 0.0  # sample rate of the states
    band_hz: tuple[float, float] = (0.0, 0.0)  # the input's band


def relative(st: States, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
    """X = x_b - x_a and V = v_b - v_a of DOFs a < b (1-based; a = 0: the ground, which moves
    with a ground-displacement input, as the core's elements to the ground see it)."""
    if a > 0:
        return st.x[b - 1] - st.x[a - 1], st.v[b - 1] - st.v[a - 1]
    if st.xg is not None and st.vg is not None:
        return st.x[b - 1] - st.xg, st.v[b - 1] - st.vg
    return st.x[b - 1], st.v[b - 1]


def drift(st: States, story: int) -> tuple[np.ndarray, np.ndarray]:
    """Story drift and drift velocity (X = x_s - x_{s-1})."""
    return relative(st, story - 1, story)


def pair_basis(st: States, a: int, b: int, g: np.ndarray) -> np.ndarray:
    """Missing forces on all DOFs of an element force g between DOF a and DOF b (it pushes
    DOF b by -g and DOF a by +g): as restoring forces, +g at DOF b and -g at DOF a."""
    out = np.zeros((st.x.shape[0], g.size))
    out[b - 1] = g
    if a >= 1:
        out[a - 1] = -g
    return out


def pairs(n_dof: int) -> list[dict[str, Any]]:
    """Every place an element can sit: DOFs a < b (a = 0 the ground), with the names users
    know where they apply (story s: DOF s-1 to DOF s; dof j: DOF j to the ground)."""
    out = []
    for b in range(1, n_dof + 1):
        for a in range(0, b):
            loc: dict[str, Any] = {"between": [a, b]}
            if b == a + 1:
                loc["story"] = b
            if a == 0:
                loc["dof"] = b
            out.append(loc)
    return out


def pair_label(loc: dict[str, Any]) -> str:
    a, b = loc["between"]
    if a == 0 and b == 1:
        return "story 1 (ground-DOF 1)"
    if a == 0:
        return f"DOF {b} (to ground)"
    if b == a + 1:
        return f"story {b} (DOF {a}-DOF {b})"
    return f"between DOF {a} and DOF {b}"


def damping_params(m: mdl.Model, band_hz: tuple[float, float]) -> list[str]:
    """The declared damping parameters the tests can inform: modal ratios of the flexible
    modes in (or near) the input band, or the Rayleigh coefficients; zeros stay fixed."""
    p = m.parameters()
    names = [n for n in ("alpha", "beta") if p.get(n, 0.0) > 0]
    if m.damping.type == "modal":
        f = mdl.natural_frequencies(m)
        names += [f"zeta{i + 1}" for i, fi in enumerate(f)
                  if 1.0 < fi and 0.5 * band_hz[0] <= fi <= 1.2 * band_hz[1]
                  and p.get(f"zeta{i + 1}", 0.0) > 0]
    return names


def readjust_every_stiffness(m: mdl.Model, band_hz: tuple[float, float],
                             mass_dof: int | None = None) -> tuple[str, ...]:
    """Every declared story stiffness (a zero one, a free end, stays fixed), the mass at
    ``mass_dof`` if given, and the damping: what a best-linear declared model moved to absorb
    an added mass or mode, which moves every mode."""
    p = m.parameters()
    names = [f"k{s}" for s in range(1, m.n_dof + 1) if p.get(f"k{s}", 0.0) > 0]
    if mass_dof is not None and p.get(f"m{mass_dof}", 0.0) > 0:
        names.append(f"m{mass_dof}")
    return tuple(dict.fromkeys([*names, *damping_params(m, band_hz)]))


def readjust_local(m: mdl.Model, dofs: Sequence[int], band_hz: tuple[float, float]
                   ) -> tuple[str, ...]:
    """Stiffness and mass at the DOFs an element touches (the story springs on either side of
    each, the DOFs' masses) and the damping: what a best-linear declared model adjusted to
    absorb the effect, re-adjusted with it (zeros and the ground stay fixed)."""
    p = m.parameters()
    # inertia matters only when some mode reaches the input band (a quasi-static rig behind a
    # rigid reaction mass cannot inform its mass)
    low_edge = max(band_hz[0], band_hz[1] / 50.0)  # a band from DC: its lowest informative part
    dynamic = bool(np.any(mdl.natural_frequencies(m) > 0.3 * low_edge))
    names: list[str] = []
    for j in sorted(set(d for d in dofs if d >= 1)):
        own = (f"k{j}", f"k{j + 1}", f"m{j}") if dynamic else (f"k{j}", f"k{j + 1}")
        names += [n for n in own if p.get(n, 0.0) > 0]
    return tuple(dict.fromkeys([*names, *damping_params(m, band_hz)]))


def _unit_force(type_name: str, x: np.ndarray | None = None, v: np.ndarray | None = None, *,
                side: str = "pos", **shape: float) -> np.ndarray:
    """The force of a registry element with the given shape parameters and 1 for the others
    (its amplitude), evaluated by the core (model.elements.force): an evidence basis is the
    element's own law, never a copy of it."""
    vals = {p.name: shape.get(p.name, 1.0) for p in el.spec(type_name).params}
    return el.force(el.make(type_name, 0, 1, vals, side=side), x, v)


def _param(type_name: str, name: str, lower: float, upper: float, log: bool = False) -> Param:
    """A fit parameter of an element effect: its registry name and unit, the search bounds."""
    return Param(name, el.spec(type_name).param(name).unit, lower, upper, log)


def _add_element(m: mdl.Model, type_name: str, dof_a: int, dof_b: int,
                 values: Sequence[float], name: str, side: str = "pos") -> mdl.Model:
    e = el.make(type_name, dof_a, dof_b, [float(v) for v in values], side=side, name=name)
    return dataclasses.replace(m, elements=(*m.elements, e))


class EffectType:
    """Base of the effect types. Subclasses set the class attributes and methods."""

    type = ""
    location_kind = ""
    law = ""
    available = True
    note = ""
    simpler: tuple[str, ...] = ()  # effect types that are special cases of this one (same place)
    # a nonlinear element: it may act at a few instants only (a rarely closing contact), where
    # a noisy evidence view swamps it
    nonlinear = False

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        raise NotImplementedError

    def label(self, loc: dict[str, Any]) -> str:
        return f"{self.type} " + " ".join(f"{k} {v}" for k, v in loc.items())

    def candidates(self, m: mdl.Model) -> list[Candidate]:
        return [Candidate(self.type, loc, self.label(loc), self.available, self.note)
                for loc in self.locations(m)]

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        """Evidence bases: a list of (shape parameters, restoring-force field n x T) to be
        regressed (one amplitude each) on the missing force."""
        raise NotImplementedError

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        raise NotImplementedError

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        """A start for the fit from the evidence amplitude (regression coefficient)."""
        raise NotImplementedError

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        raise NotImplementedError

    def changes(self, cand: Candidate) -> str:
        """The one declared parameter this candidate changes, if it is only that (a linear
        change: the loop does not offer it once an accepted effect re-adjusted it); ''."""
        return ""

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        """Starting points of the fit (the best fit over them is kept)."""
        return [self.initial(m, cand, amp)]

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        """Scales of the motion the effect acts on (recorded in the candidate's shape, they
        set its parameter bounds)."""
        return {}

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        """Declared parameters re-adjusted while this candidate is fitted: a declared model
        is often a best linear fit that absorbed part of the effect (see readjust_local)."""
        return ()

    def direct_evidence(self, cand: Candidate, residuals: Sequence[dict[str, np.ndarray]]
                        ) -> tuple[float, float] | None:
        """Evidence (share, amplitude) read from the output residuals themselves, for effects
        the restoring-force view cannot see; None: use the view."""
        return None

    def probe(self, m: mdl.Model, cand: Candidate, amount: float) -> mdl.Model | None:
        """For an effect linear in one amount that the views cannot see (a constant force:
        their high-pass takes it away): the model with the effect at a small ``amount``; its
        evidence is then how much of the residual the change of the predictions explains.
        None: the views judge it."""
        return None


class NoEffect(EffectType):
    type = "none"
    law = "the declared model is complete: nothing significant is left in the residual"

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{}]

    def label(self, loc: dict[str, Any]) -> str:
        return "no effect"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        return []

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        return []

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return []

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        return m


# relative changes screened as starts of linear parameter changes (a resonance shift beyond
# the modes' bandwidth puts the output error's minimum out of reach of a local start)
_REL_GRID = (-0.4, -0.25, -0.15, -0.08, -0.03, 0.03, 0.08, 0.15, 0.25, 0.5)


class StiffnessChange(EffectType):
    type = "stiffness_change"
    location_kind = "story"
    law = "k_s -> k_s + dk: extra story force dk X (linear)"

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        # modal damping on the changed modes is not the structure's damping: fit it jointly
        return tuple(damping_params(m, band_hz))

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        # story 1 is often a soft support (rails): a change there is still a candidate
        return [{"story": s, "between": [s - 1, s]} for s in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        return f"stiffness change, story {loc['story']} (DOF {loc['story'] - 1}-{loc['story']})"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        s = cand.location["story"]
        d, _ = drift(st, s)
        return [({}, pair_basis(st, s - 1, s, d))]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        k = m.stiffness_n_per_m[cand.location["story"] - 1]
        return [Param("dk_n_per_m", "N/m", -0.6 * k, 1.0 * k if k > 100 else 1e5)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        p = self.params(m, cand)[0]
        return [float(np.clip(amp, p.lower * 0.9, p.upper * 0.9))]

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        # the evidence amplitude plus a grid of relative changes (screened by the loop)
        p = self.params(m, cand)[0]
        k = m.stiffness_n_per_m[cand.location["story"] - 1]
        grid = [r * k for r in _REL_GRID if p.lower < r * k < p.upper]
        return [self.initial(m, cand, amp), *([g] for g in grid)]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        s = cand.location["story"]
        return m.with_params({self.changes(cand): m.stiffness_n_per_m[s - 1] + float(values[0])})

    def changes(self, cand: Candidate) -> str:
        return f"k{cand.location['story']}"


class MassChange(EffectType):
    type = "mass_change"
    location_kind = "dof"
    law = "m_j -> m_j + dm: extra inertia force dm a_j at DOF j"

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        # not the other way round (a stiffness change does not re-adjust the masses): the
        # two would span the same models and tie
        return readjust_every_stiffness(m, band_hz)

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"dof": j} for j in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        return f"mass change, DOF {loc['dof']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        j = cand.location["dof"] - 1
        b = np.zeros_like(st.a)
        b[j] = st.a[j]
        return [({}, b)]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        mj = m.masses_kg[cand.location["dof"] - 1]
        return [Param("dm_kg", "kg", -0.6 * mj, 1.5 * mj)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        p = self.params(m, cand)[0]
        return [float(np.clip(amp, p.lower * 0.9, p.upper * 0.9))]

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        p = self.params(m, cand)[0]
        mj = m.masses_kg[cand.location["dof"] - 1]
        grid = [r * mj for r in _REL_GRID if p.lower < r * mj < p.upper]
        return [self.initial(m, cand, amp), *([g] for g in grid)]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        j = cand.location["dof"]
        return m.with_params({self.changes(cand): m.masses_kg[j - 1] + float(values[0])})

    def changes(self, cand: Candidate) -> str:
        return f"m{cand.location['dof']}"


class DampingChange(EffectType):
    type = "damping_change"
    location_kind = "mode"
    law = "zeta_i -> zeta_i + dzeta: extra modal damping force 2 dzeta w_i M phi_i phi_i^T M v"

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        d = m.damping
        if d.type == "rayleigh" and not d.modes:
            return [{"coefficient": "alpha"}, {"coefficient": "beta"}]
        if d.type != "modal":
            return []
        return [{"mode": i} for i in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        if "coefficient" in loc:
            return f"damping change, Rayleigh {loc['coefficient']}"
        return f"damping change, mode {loc['mode']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        if "coefficient" in cand.location:
            v = st.v.copy()
            vg = st.vg if st.vg is not None else 0.0
            if cand.location["coefficient"] == "alpha":
                return [({}, st.mass[:, None] * (v - vg))]
            b = st.k @ v
            # only the ground spring k1 sees the ground motion: K v - k1 v_g e1
            k1 = st.k[0, 0] + (st.k[0, 1] if st.k.shape[0] > 1 else 0.0)
            b[0] -= k1 * vg
            return [({}, b)]
        i = cand.location["mode"] - 1
        w = st.modes_w[i]
        if w < 2 * np.pi * 1.0:  # a rigid-body-like mode: its damping is not observable here
            return []
        mp = st.mass[:, None] * st.modes_phi[:, i:i + 1]
        ci = 2 * w * mp @ mp.T
        return [({}, ci @ st.v)]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        if "coefficient" in cand.location:
            if cand.location["coefficient"] == "alpha":
                a = float(m.damping.alpha_per_s or 0.0)
                return [Param("dalpha_per_s", "1/s", -a, 10 * abs(a) + 1.0)]
            b = float(m.damping.beta_s or 0.0)
            return [Param("dbeta_s", "s", -b, 10 * abs(b) + 1e-3)]
        z = m.damping.zeta[cand.location["mode"] - 1]
        return [Param("dzeta", "1", -z, 0.2)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        p = self.params(m, cand)[0]
        return [float(np.clip(amp, p.lower * 0.9, p.upper * 0.9))]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        if "coefficient" in cand.location:
            c = cand.location["coefficient"]
            base = float((m.damping.alpha_per_s if c == "alpha" else m.damping.beta_s) or 0.0)
            return m.with_params({c: base + float(values[0])})
        i = cand.location["mode"]
        return m.with_params({f"zeta{i}": m.damping.zeta[i - 1] + float(values[0])})


class SensorGain(EffectType):
    type = "sensor_gain"
    location_kind = "channel"
    law = "the channel reads g x the quantity (calibration error); handled on the output"

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"channel": c} for c in m.outputs]

    def label(self, loc: dict[str, Any]) -> str:
        return f"sensor gain, channel {loc['channel']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        c = cand.location["channel"]
        if st.reaction_only:
            if c not in st.predicted:
                return []
            b = np.zeros_like(st.x)
            b[0] = -st.predicted[c]  # the model quantity (gain divided out)
            return [({"reaction": 1.0}, b)]
        if c not in st.channels_dof:
            return []
        j = st.channels_dof[c] - 1
        # a gain error on DOF j's sensor shows as the restoring image of that DOF's column
        b = (np.diag(st.mass)[:, j:j + 1] * st.a[j] + st.c[:, j:j + 1] * st.v[j]
             + st.k[:, j:j + 1] * st.x[j])
        return [({}, b)]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        g0 = m.outputs[cand.location["channel"]].gain
        lo, hi = sorted((0.5 * g0, 2.0 * g0))
        return [Param("gain", "1", lo, hi)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        # missing force = -(1 - 1/g) b  =>  amp = -(1 - 1/g); reaction view: amp = 1 - g
        g0 = m.outputs[cand.location["channel"]].gain
        lo, hi = sorted((0.55 * g0, 1.9 * g0))
        if cand.shape.get("reaction"):
            return [float(np.clip(g0 * (1.0 - amp), lo, hi))]
        g = g0 / (1.0 + amp) if abs(1.0 + amp) > 0.2 else g0
        return [float(np.clip(g, lo, hi))]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        c = cand.location["channel"]
        outs = dict(m.outputs)
        outs[c] = dataclasses.replace(outs[c], gain=float(values[0]))
        return dataclasses.replace(m, outputs=outs)


class SensorOffset(EffectType):
    type = "sensor_offset"
    location_kind = "channel"
    law = ("the channel reads its quantity + b (a DC offset of the sensor or its amplifier); "
           "handled on the output")

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"channel": c} for c in m.outputs]

    def label(self, loc: dict[str, Any]) -> str:
        return f"sensor offset, channel {loc['channel']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        return []  # the state reconstruction high-passes a constant away: see direct_evidence

    def direct_evidence(self, cand: Candidate, residuals: Sequence[dict[str, np.ndarray]]
                        ) -> tuple[float, float] | None:
        """(share of the channel's residual energy a constant explains, that constant)."""
        c = cand.location["channel"]
        rs = [r[c] for r in residuals if c in r]
        if not rs:
            return None
        v = np.concatenate(rs)
        ms = float(np.mean(v * v))
        mean = float(np.mean(v))
        return (mean * mean / ms if ms > 0 else 0.0), mean

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        b0 = m.outputs[cand.location["channel"]].offset
        span = 10 * abs(float(cand.shape.get("amp", 0.0))) + 1e-12
        return [Param("offset", "channel unit", b0 - span, b0 + span)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [m.outputs[cand.location["channel"]].offset + amp]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        c = cand.location["channel"]
        outs = dict(m.outputs)
        outs[c] = dataclasses.replace(outs[c], offset=float(values[0]))
        return dataclasses.replace(m, outputs=outs)


_QUANTILES = (0.6, 0.75, 0.85, 0.9, 0.95, 0.98, 0.99, 0.995, 0.998)


class Contact(EffectType):
    type = "contact"
    location_kind = "story"
    nonlinear = True
    law = ("gap/bumper on the story drift X (report eq. 6-7): s = X - gap (pos side) or "
           "-X - gap (neg); force 0 for s <= 0, kB s^2/(2 delta) for s < delta, kB (s - delta/2) "
           "beyond; a dv_model contact element")

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{**loc, "side": side} for loc in pairs(m.n_dof) for side in ("pos", "neg")]

    def label(self, loc: dict[str, Any]) -> str:
        return f"contact, {pair_label(loc)}, {loc['side']} side"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        a, b = cand.location["between"]
        d, _ = relative(st, a, b)
        side = cand.location["side"]
        y = d if side == "pos" else -d
        out = []
        for q in _QUANTILES:  # a bilinear contact (delta = 0, kB = 1) at the drift's quantiles
            gap = max(float(np.quantile(y, q)), 0.0)
            g = st.hp(_unit_force("contact", d, side=side, gap_m=gap, delta_m=0.0))
            out.append(({"gap_m": gap, "quantile": q}, pair_basis(st, a, b, g)))
        return out

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        a, b = cand.location["between"]
        d, _ = relative(st, a, b)
        return {"drift_rms_m": float(np.std(d))}

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        k = max(m.stiffness_n_per_m)
        dscale = float(cand.shape.get("drift_rms_m", 1e-4))
        return [_param("contact", "gap_m", 0.0, 10 * dscale),
                _param("contact", "delta_m", 1e-3 * dscale, 10 * dscale, log=True),
                _param("contact", "kb_n_per_m", 1e-3 * k, 20 * k, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        ps = self.params(m, cand)
        gap = float(cand.shape.get("gap_m", 0.0))
        dscale = float(cand.shape.get("drift_rms_m", 1e-4))
        kb = float(np.clip(abs(amp), ps[2].lower * 2, ps[2].upper * 0.5))
        return [float(np.clip(gap, 0.0, ps[0].upper * 0.9)), 0.3 * dscale, kb]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        a, b = cand.location["between"]
        return _add_element(m, "contact", a, b, values, f"discovered contact {a}-{b}",
                            cand.location["side"])

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        return readjust_local(m, cand.location["between"], band_hz)


class _ElementEffect(EffectType):
    """An effect that is a new model element (a registry type, model/elements.py): its
    evidence basis and its fit both run the core's law."""

    element = ""  # registry type name
    tag = ""  # in the discovered element's name

    @staticmethod
    def _scale(cand: Candidate, default: float) -> float:
        a = abs(float(cand.shape.get("amp", 0.0)))
        return a if a > 0 else default


class _PairElement(_ElementEffect):
    """An element between DOF a and DOF b (a = 0: the ground), at every pair of the model."""

    location_kind = "pair"
    what = ""
    nonlinear = True

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return pairs(m.n_dof)

    def label(self, loc: dict[str, Any]) -> str:
        return f"{self.what}, {pair_label(loc)}"

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        a, b = cand.location["between"]
        return _add_element(m, self.element, a, b, values, f"discovered {self.tag} {a}-{b}")

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        return readjust_local(m, cand.location["between"], band_hz)

    @staticmethod
    def _rel(st: States, cand: Candidate) -> tuple[np.ndarray, np.ndarray]:
        a, b = cand.location["between"]
        return relative(st, a, b)

    def _basis(self, st: States, cand: Candidate, g: np.ndarray) -> np.ndarray:
        a, b = cand.location["between"]
        return pair_basis(st, a, b, st.hp(g))


class _OneCoefficient(_PairElement):
    """A pair element with one coefficient (its amplitude)."""

    default_scale = 1.0

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        c = self._scale(cand, self.default_scale)
        name = el.spec(self.element).params[0].name
        return [_param(self.element, name, 1e-3 * c, 1e2 * c, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [self._scale(cand, self.default_scale)]

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        x, v = self._rel(st, cand)
        return [({}, self._basis(st, cand, _unit_force(self.element, x, v)))]


def rigid_body_like(m: mdl.Model) -> bool:
    """Whether the model has a mode far below the others (a carriage on a guide, a structure
    on rails): there a constant force moves the whole body and shows only through how it
    balances against friction."""
    f = mdl.natural_frequencies(m)
    return bool(f.size > 1 and f[0] < 1e-3 * f[-1])


class _FrictionOffset(_PairElement):
    """Friction laws with a variant that carries a constant force between the same DOFs
    (``offset`` in the location): asymmetric friction, or friction balancing a force offset
    (a drive's bias, a weight component), as a positioning stage has. On a rigid-body-like
    model the offset is not seen on its own (the friction balances it, the residual keeps no
    mean) and the friction alone fits badly: the two are fitted together."""

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        base = pairs(m.n_dof)
        if not rigid_body_like(m):
            return base
        return [*base, *({**loc, "offset": True} for loc in base)]

    def label(self, loc: dict[str, Any]) -> str:
        return super().label(loc) + (", with a force offset" if loc.get("offset") else "")

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        raise NotImplementedError

    def law_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        return [self.initial(m, cand, amp)]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        ps = self.law_params(m, cand)
        if not cand.location.get("offset"):
            return ps
        span = 2 * ps[0].upper  # the law's force bound
        return [*ps, Param("offset_force_n", "N", -span, span)]

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        extra = [0.0] if cand.location.get("offset") else []
        return [[*s, *extra] for s in self.law_starts(m, cand, amp)]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        n = len(self.law_params(m, cand))
        out = super().apply(m, cand, values[:n])
        if not cand.location.get("offset"):
            return out
        a, b = cand.location["between"]
        return _add_element(out, "constant_force", a, b, values[n:],
                            f"discovered force offset {a}-{b}")


class Friction(_FrictionOffset):
    tag = "friction"
    type = "friction"
    element = "friction"
    what = "friction"
    law = ("Coulomb friction between DOF a and DOF b (or the ground) on the relative velocity V: "
           "F V / sqrt(V^2 + eps^2) (a dv_model friction element, -> F sign(V))")

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        f = self._scale(cand, 1.0)
        vr = float(cand.shape.get("v_rms", 1e-2))
        return [_param("friction", "force_n", 1e-3 * f, 20 * f, log=True),
                _param("friction", "v_eps_m_per_s", 1e-3 * vr, 0.5 * vr, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        vr = float(cand.shape.get("v_rms", 1e-2))
        return [max(abs(amp), 1e-3 * self._scale(cand, 1.0) * 2), 0.03 * vr]

    def law_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        # a sharp and a smooth regularisation: stick-slip data with a presliding range can
        # prefer the smooth one
        f0, e0 = self.initial(m, cand, amp)
        return [[f0, e0], [f0, 10 * e0]]

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        return {"v_rms": float(np.std(self._rel(st, cand)[1]))}

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        _, v = self._rel(st, cand)
        vs = float(np.std(v)) or 1.0
        # the core's friction law, eps relative to the velocity's STD
        return [({"v_eps_rel": eps},
                 self._basis(st, cand, _unit_force("friction", v=v, v_eps_m_per_s=eps * vs)))
                for eps in (0.02, 0.1)]


class StickSlipFriction(_FrictionOffset):
    tag = "stick-slip"
    type = "stick_slip"
    element = "stick_slip"
    what = "stick-slip friction"
    law = ("stick-slip (Jenkins) friction between DOF a and DOF b (or the ground): a stick "
           "spring F/z in series with a slider at F, rate-independent hysteresis (a dv_model "
           "stick_slip element)")
    _FR = (0.003, 0.01, 0.05, 0.15, 0.4, 0.8)

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        x, _ = self._rel(st, cand)
        xs = float(np.std(x)) or 1.0
        # the core's stick-slip law (from the virgin state) over slip_m
        return [({"slip_m": f * xs, "x_rms": xs},
                 self._basis(st, cand, _unit_force("stick_slip", x, slip_m=f * xs)))
                for f in self._FR]

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        f = self._scale(cand, 1.0)
        xs = float(cand.shape.get("x_rms", 1e-4))
        return [_param("stick_slip", "force_n", 1e-3 * f, 20 * f, log=True),
                _param("stick_slip", "slip_m", 1e-4 * xs, 2.0 * xs, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        xs = float(cand.shape.get("x_rms", 1e-4))
        return [max(abs(amp), 2e-3 * self._scale(cand, 1.0)),
                float(cand.shape.get("slip_m", 0.05 * xs))]


class CubicStiffness(_OneCoefficient):
    tag = "cubic"
    type = "cubic_stiffness"
    element = "cubic_spring"
    what = "cubic stiffness"
    default_scale = 1e12
    law = "cubic spring between two DOFs: k3 X^3 (a dv_model cubic_spring element)"


class VelocitySquaredDamping(_OneCoefficient):
    tag = "v|v| damper"
    type = "vv_damping"
    element = "vv_damper"
    what = "velocity-squared damping"
    default_scale = 1e3
    law = "quadratic damper between two DOFs: c2 V |V| (a dv_model vv_damper)"


class ForceOffset(_ElementEffect):
    type = "force_offset"
    element = "constant_force"
    location_kind = "dof"
    law = ("a constant force F at DOF j whatever the motion: a preload, a weight component on "
           "an incline, a force transducer's bias at the input DOF (a dv_model constant_force "
           "element from the ground)")

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"dof": j, "between": [0, j]} for j in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        return f"force offset, DOF {loc['dof']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        return []  # the views high-pass a constant away: judged by probe()

    def probe(self, m: mdl.Model, cand: Candidate, amount: float) -> mdl.Model | None:
        return self.apply(m, cand, [amount])

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        span = 10 * abs(float(cand.shape.get("amp", 0.0))) + float(cand.shape.get("probe", 1.0))
        return [_param("constant_force", "force_n", -span, span)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [amp]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        j = cand.location["dof"]
        return _add_element(m, "constant_force", 0, j, values, f"discovered force offset {j}")


def appendage_motion(a: np.ndarray, fs_hz: float, f_hz: float, zeta: float) -> np.ndarray:
    """The acceleration of an appendage (f_hz, zeta on a fixed base) hanging from a DOF whose
    acceleration is ``a``: the base-excitation transmissibility
    (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2), by the bilinear map warped to keep w."""
    w = 2 * fs_hz * np.tan(np.pi * f_hz / fs_hz)
    b, den = _signal.bilinear([2 * zeta * w, w * w], [1.0, 2 * zeta * w, w * w], fs_hz)
    return np.asarray(_signal.lfilter(b, den, a))


class Appendage(EffectType):
    type = "appendage"
    location_kind = "dof"
    law = ("a secondary mass on a spring and a dashpot hanging from DOF j (a mode the model "
           "lacks): fixed-base frequency f, damping ratio zeta, mass m_a; a new DOF joined by "
           "a dv_model link")
    simpler = ("mass_change",)  # an appendage far above the band moves with its DOF
    _N_GRID = 28

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"dof": j} for j in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        return f"appendage, DOF {loc['dof']}"

    @staticmethod
    def _grid(st: States) -> np.ndarray:
        lo = max(st.band_hz[0], st.band_hz[1] / 50.0, 1e-3)
        hi = min(1.2 * st.band_hz[1], 0.45 * st.fs_hz)
        return np.geomspace(0.7 * lo, hi, Appendage._N_GRID)

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        if st.fs_hz <= 0 or st.band_hz[1] <= 0:
            return []
        j = cand.location["dof"] - 1
        grid = self._grid(st)
        out = []
        for f in grid:
            b = np.zeros_like(st.a)
            b[j] = st.hp(appendage_motion(st.a[j], st.fs_hz, float(f), 0.03))
            out.append(({"f_hz": float(f), "f_lo": float(grid[0]), "f_hi": float(grid[-1]),
                         "m_ref": float(st.mass[j])}, b))
        return out

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        mj = m.masses_kg[cand.location["dof"] - 1]
        f_lo = float(cand.shape.get("f_lo", 1.0))
        f_hi = float(cand.shape.get("f_hi", 1e3))
        return [Param("f_hz", "Hz", 0.7 * f_lo, 1.3 * f_hi, log=True),
                Param("mass_kg", "kg", 1e-4 * mj, 2.0 * mj, log=True),
                Param("zeta", "1", 1e-3, 0.5, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        p = self.params(m, cand)
        f = float(cand.shape.get("f_hz", math.sqrt(p[0].lower * p[0].upper)))
        ma = float(np.clip(abs(amp), 2 * p[1].lower, 0.5 * p[1].upper))
        return [float(np.clip(f, p[0].lower * 1.01, p[0].upper * 0.99)), ma, 0.03]

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        # as a mass change (a new mode moves every mode), with the DOF's own mass
        return readjust_every_stiffness(m, band_hz, cand.location["dof"])

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        f, ma, z = self.initial(m, cand, amp)
        return [[f, ma, z], [f, ma, 0.1]]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        f, ma, z = (float(v) for v in values)
        j = cand.location["dof"]
        return with_appendage(m, j, ma, f, z, f"discovered appendage at DOF {j}")


LIBRARY: tuple[EffectType, ...] = (
    Contact(), StiffnessChange(), MassChange(), DampingChange(), SensorGain(), SensorOffset(),
    Friction(), StickSlipFriction(), CubicStiffness(), VelocitySquaredDamping(), ForceOffset(),
    Appendage())
NONE = NoEffect()


def by_type(name: str) -> EffectType:
    for e in (*LIBRARY, NONE):
        if e.type == name:
            return e
    raise KeyError(name)


def catalogue(m: mdl.Model, quiet: bool = False) -> list[Candidate]:
    """Every candidate (type x location) for a model; unavailable types are logged (unless
    quiet)."""
    out: list[Candidate] = []
    for e in LIBRARY:
        cs = e.candidates(m)
        if cs and not e.available and not quiet:
            log.info("effect type %s: %s", e.type, e.note)
        out.extend(cs)
    return out


def describe() -> list[dict[str, Any]]:
    """The library as data (for the report and docs)."""
    return [{"type": e.type, "location": e.location_kind, "law": e.law,
             "available": e.available, "note": e.note} for e in (*LIBRARY, NONE)]
