"""What every effect type shares: the fit parameter, the candidate, the reconstructed
states, the DOF-pair geometry, which declared parameters a fit re-adjusts, and the
EffectType base (with NoEffect, the "nothing missing" answer)."""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.model import elements as el


@dataclass(frozen=True)
class Param:
    """One parameter: name, unit, bounds in model units, and whether it is fitted in log.
    ``signed``: either sign, its magnitude in log between 0 and upper - lower (lower: the
    magnitude below which the scale turns linear, through 0). ``null``: for a parameter that
    sets the effect's strength, its value where the effect vanishes (a contact's stiffness 0,
    a change's delta 0, a sensor's current gain): a start far worse than no effect is moved
    toward it (fit.temper); None for a parameter of the effect's shape (a gap, a frequency)."""

    name: str
    unit: str
    lower: float
    upper: float
    log: bool = False
    signed: bool = False
    null: float | None = None


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
    # a shake table's acceleration: the states are relative to the table, inertia sees a + ag
    ag: np.ndarray | None = None


def inertial(st: States, j: int) -> np.ndarray:
    """The absolute acceleration of DOF j (0-based), which a mass (an added one, an
    appendage's) resists: on a shake table the states are relative to the table."""
    return st.a[j] if st.ag is None else np.asarray(st.a[j] + st.ag)


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


DAMPING_REACH = 0.05  # a mode's dashpot force at the band's edge, over its inertia there


def damping_params(m: mdl.Model, band_hz: tuple[float, float]) -> list[str]:
    """The declared damping parameters the tests can inform: modal ratios of the flexible
    modes in or near the input band, from a quarter of its low edge to 1.2 x its high edge
    (of a damping matrix too: the ratio each mode has in it, so a dissipation an earlier fit's
    re-adjustment took in can be given back), or the Rayleigh coefficients; zeros stay fixed.
    A mode under the band still rings on the input's edge and on what elements put there:
    blind 6-DOF seed 4, mode 1 at 0.47 x the band's edge, had taken a friction's dissipation
    in a best-linear model, and left out it was named as a damping change of its own.
    A heavily damped mode further under the band counts too when its dashpot's force at the
    band's low edge, 2 zeta f_i / f_low of the mode's inertia there, reaches DAMPING_REACH: a
    position loop at 1.8 Hz with zeta 0.41 under a 10-250 Hz input (0.14) whose best-linear
    ratio, 0.72, had taken a friction's dissipation in, left the friction found at 1.5 x
    the ideal."""
    p = m.parameters()
    names = [n for n in ("alpha", "beta") if p.get(n, 0.0) > 0]
    if m.damping.type in ("modal", "matrix"):
        f = mdl.natural_frequencies(m)
        for i, fi in enumerate(f):
            zeta = p.get(f"zeta{i + 1}", 0.0)
            near = 1.0 < fi and 0.25 * band_hz[0] <= fi <= 1.2 * band_hz[1]
            under = fi < band_hz[0] and 2 * zeta * fi >= DAMPING_REACH * band_hz[0]
            if zeta > 0 and (near or under):
                names.append(f"zeta{i + 1}")
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


def unit_force(type_name: str, x: np.ndarray | None = None, v: np.ndarray | None = None, *,
                side: str = "pos", **shape: float) -> np.ndarray:
    """The force of a registry element with the given shape parameters and 1 for the others
    (its amplitude), evaluated by the core (model.elements.force): an evidence basis is the
    element's own law, never a copy of it."""
    vals = {p.name: shape.get(p.name, 1.0) for p in el.spec(type_name).params}
    return el.force(el.make(type_name, 0, 1, vals, side=side), x, v)


def element_param(type_name: str, name: str, lower: float, upper: float,
                  log: bool = False, signed: bool = False, null: float | None = None
                  ) -> Param:
    """A fit parameter of an element effect: its registry name and unit, the search bounds
    (``null``: see Param)."""
    return Param(name, el.spec(type_name).param(name).unit, lower, upper, log, signed, null)


def add_element(m: mdl.Model, type_name: str, dof_a: int, dof_b: int,
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
    # effect types with fewer parameters that are special cases of this one or that it can
    # stand in for, at the same place: preferred on a near tie (judge.simplest_nested)
    simpler: tuple[str, ...] = ()
    # a nonlinear element: it may act at a few instants only (a rarely closing contact), where
    # a noisy evidence view swamps it
    nonlinear = False
    # a linear change that moves the resonances: its first-order evidence ranks it low where
    # it shifts one by more than the mode's bandwidth, so the loop screens every candidate of
    # it by simulation (its starts and scan_starts, one simulation each)
    moves_modes = False
    # an effect of the DAQ (a sensor's gain or offset, the anti-alias filter), not of the
    # structure: the verdict names the structure's first (effects.structural)
    measurement_chain = False
    # its places are few and cheap to fit, and its evidence cannot rank them: when one wins a
    # round, the others are fitted too, from its values (judge.siblings)
    fit_every_place = False
    # its law has a linear stiffness at its place (a spring's, a closed contact's, a stuck
    # joint's): a best-linear model's story stiffness there took up part of it, and a change of
    # that stiffness found with it is its own linear part, not a change apart (judge.apart)
    stiffens = False

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

    def simpler_amount(self, simpler: str, values: dict[str, float]) -> float:
        """The evidence amplitude to fit the simpler type ``simpler`` (one of self.simpler)
        from, in place of this effect with its fitted ``values`` (by parameter name); 0: its
        own starts."""
        return 0.0

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        """Starting points of the fit (the best fit over them is kept; more than two are
        screened by one simulation each, fit.screen, and the best two fitted)."""
        return [self.initial(m, cand, amp)]

    def scan_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        """Starting points away from the evidence's: the best of them by one simulation each
        is fitted too (none by default)."""
        return []

    def stuck_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        """Starting points for a candidate fitted again in a round that accepted nothing
        with its residual still large (judge.stuck_unexplained): the best few by one
        simulation each are fitted too (none by default)."""
        return []

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        """Scales of the motion the effect acts on (recorded in the candidate's shape, they
        set its parameter bounds)."""
        return {}

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        """Declared parameters re-adjusted while this candidate is fitted: a declared model
        is often a best linear fit that absorbed part of the effect (see readjust_local)."""
        return ()

    def readjust_wider(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                       ) -> tuple[str, ...]:
        """What the candidate re-adjusts when a round with nothing accepted is fitted again
        (judge.wider_of_round): more than readjust where a best-linear declared model can have
        moved parameters further off; readjust itself for most types."""
        return self.readjust(m, cand, band_hz)

    def other_starts(self, m: mdl.Model, cand: Candidate, init: Sequence[float]
                     ) -> list[list[float]]:
        """Other starting values of the effect's parameters, each fitted too and the best fit
        kept: for an effect whose fit has several basins. []: the one start."""
        return []

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
