"""The element registry: one entry per nonlinear element type of the model (the Python home of
the element concept; its C home is include/dynval/dv_elem.h).

An entry says the model-file ``type`` name, the dataclass, the C law (``dv_elem_law_t``), the
parameters (file key = dataclass attribute, unit, lower bound, the ``dv_elem_desc_t`` field
that holds it) and whether the element has a contact side. The model file reader and writer,
the C description filler, parameter-name resolution, validation (through ``dv_elem_check``),
discover's effects and trace views and the synthetic generator all read it. The force laws are
never restated here: ``force`` evaluates an element through the core's ``dv_elem_force_block``.

Adding a law: docs/adding-an-element-law.md.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import _core
from dynval.errors import ConfigError

SIDES = ("pos", "neg", "both")
_SIDE_C = {"pos": "DV_SIDE_POS", "neg": "DV_SIDE_NEG", "both": "DV_SIDE_BOTH"}


@dataclass(frozen=True)
class Contact:
    """Bumper/gap element between ``dof_a`` and ``dof_b`` (1-based, dof_a = 0: ground),
    X = x_b - x_a (law: dv_elem.h DV_ELEM_CONTACT; side 'neg' mirrors it, 'both' is the sum)."""

    dof_a: int
    dof_b: int
    gap_m: float
    delta_m: float
    kb_n_per_m: float
    side: str = "pos"
    name: str = ""
    type: str = "contact"


@dataclass(frozen=True)
class Friction:
    """Regularised Coulomb friction on V = v_b - v_a (DV_ELEM_FRICTION): slip force
    ``force_n``, regularisation ``v_eps_m_per_s``."""

    dof_a: int
    dof_b: int
    force_n: float
    v_eps_m_per_s: float
    name: str = ""
    type: str = "friction"


@dataclass(frozen=True)
class CubicSpring:
    """Cubic spring on X = x_b - x_a (DV_ELEM_CUBIC), coefficient ``k3_n_per_m3`` (negative: a
    softening spring)."""

    dof_a: int
    dof_b: int
    k3_n_per_m3: float
    name: str = ""
    type: str = "cubic_spring"


@dataclass(frozen=True)
class VVDamper:
    """Velocity-squared damper on V = v_b - v_a (DV_ELEM_VV), coefficient ``c2_n_s2_per_m2``."""

    dof_a: int
    dof_b: int
    c2_n_s2_per_m2: float
    name: str = ""
    type: str = "vv_damper"


@dataclass(frozen=True)
class StickSlip:
    """Elasto-plastic (Jenkins) friction on X = x_b - x_a (DV_ELEM_STICKSLIP): slider at
    ``force_n``, stick displacement ``slip_m``; history kept by the core."""

    dof_a: int
    dof_b: int
    force_n: float
    slip_m: float
    name: str = ""
    type: str = "stick_slip"


@dataclass(frozen=True)
class ConstantForce:
    """A constant force whatever the motion (DV_ELEM_CONSTANT, g = -force_n): it pushes DOF b
    by +force_n (towards +x) and DOF a by -force_n; from the ground (dof_a = 0): a force
    offset at DOF b."""

    dof_a: int
    dof_b: int
    force_n: float
    name: str = ""
    type: str = "constant_force"


Element = Contact | Friction | CubicSpring | VVDamper | StickSlip | ConstantForce


@dataclass(frozen=True)
class Param:
    """One element parameter: file key and dataclass attribute, unit, the dv_elem_desc_t field
    that holds it, and its lower bound (``strict``: > lower, else >= lower) as dv_elem_check
    enforces it; ``default``: the value when the file omits it (None: required)."""

    name: str
    unit: str
    field: str
    lower: float = 0.0
    strict: bool = False
    default: float | None = None

    def admits(self, v: float) -> bool:
        return bool(np.isfinite(v)) and (v > self.lower if self.strict else v >= self.lower)

    def bound_text(self) -> str:
        return f"{'>' if self.strict else '>='} {self.lower:g} {self.unit}"


@dataclass(frozen=True)
class ElementType:
    """A registry entry."""

    name: str
    cls: type
    law: str  # dv_elem_law_t enumerator
    params: tuple[Param, ...]
    sided: bool = False

    @property
    def law_id(self) -> int:
        return int(getattr(_core.lib, self.law))

    @property
    def on_velocity(self) -> bool:
        """Whether the law reads the relative velocity (the core says: dv_elem_on_velocity)."""
        return bool(_core.lib.dv_elem_on_velocity(self.law_id))

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise ConfigError(f"element type {self.name} has no parameter '{name}' (it has "
                          f"{', '.join(p.name for p in self.params)})")


REGISTRY: dict[str, ElementType] = {t.name: t for t in (
    ElementType("contact", Contact, "DV_ELEM_CONTACT", (
        Param("gap_m", "m", "gap_m"), Param("delta_m", "m", "delta_m", default=0.0),
        Param("kb_n_per_m", "N/m", "kb_n_per_m")), sided=True),
    ElementType("friction", Friction, "DV_ELEM_FRICTION", (
        Param("force_n", "N", "kb_n_per_m"),
        Param("v_eps_m_per_s", "m/s", "delta_m", strict=True))),
    ElementType("cubic_spring", CubicSpring, "DV_ELEM_CUBIC", (
        Param("k3_n_per_m3", "N/m^3", "kb_n_per_m", lower=-np.inf),)),  # < 0: softening
    ElementType("vv_damper", VVDamper, "DV_ELEM_VV", (
        Param("c2_n_s2_per_m2", "N s^2/m^2", "kb_n_per_m"),)),
    ElementType("stick_slip", StickSlip, "DV_ELEM_STICKSLIP", (
        Param("force_n", "N", "kb_n_per_m"), Param("slip_m", "m", "delta_m", strict=True))),
    ElementType("constant_force", ConstantForce, "DV_ELEM_CONSTANT", (
        Param("force_n", "N", "kb_n_per_m", lower=-np.inf),)),
)}
TYPES = tuple(REGISTRY)


def spec(e: Element | str) -> ElementType:
    """The registry entry of an element (or of a type name)."""
    name = e if isinstance(e, str) else e.type
    try:
        return REGISTRY[name]
    except KeyError:
        raise ConfigError(f"unknown element type {name!r} (known: {', '.join(TYPES)})") from None


def make(type_name: str, dof_a: int, dof_b: int, values: Mapping[str, float] | Sequence[float],
         *, side: str = "pos", name: str = "") -> Element:
    """An element of a registered type from its parameters (by name, or in registry order)."""
    t = spec(type_name)
    if isinstance(values, Mapping):
        missing = [p.name for p in t.params if p.name not in values and p.default is None]
        if missing:
            raise ConfigError(f"{t.name}: missing parameter {', '.join(missing)}")
        vals = {p.name: float(values.get(p.name, p.default or 0.0)) for p in t.params}
    else:
        if len(values) != len(t.params):
            raise ConfigError(f"{t.name}: expected {len(t.params)} parameters "
                              f"({', '.join(p.name for p in t.params)}), got {len(values)}")
        vals = {p.name: float(v) for p, v in zip(t.params, values, strict=True)}
    extra: dict[str, Any] = {"side": side} if t.sided else {}
    e: Element = t.cls(dof_a, dof_b, **vals, **extra, name=name)
    return e


def values(e: Element) -> dict[str, float]:
    """The element's parameters by name, in registry order."""
    return {p.name: float(getattr(e, p.name)) for p in spec(e).params}


def fill_desc(c: Any, e: Element) -> None:
    """Write the law and parameters of e into a dv_elem_desc_t (not its DOFs)."""
    t = spec(e)
    lib = _core.lib
    c.law = t.law_id
    c.side = getattr(lib, _SIDE_C[side_of(e)]) if t.sided else lib.DV_SIDE_POS
    c.gap_m = 0.0
    c.delta_m = 0.0
    c.kb_n_per_m = 0.0
    for p in t.params:
        setattr(c, p.field, float(getattr(e, p.name)))


def side_of(e: Element) -> str:
    """The contact side of e ("pos" for the types without one)."""
    return str(getattr(e, "side", "pos"))


def _desc(e: Element) -> Any:
    c = _core.ffi.new("dv_elem_desc_t *")
    fill_desc(c, e)
    return c


def core_accepts(e: Element) -> bool:
    """Whether dv_elem_check accepts the element's law and parameters."""
    if side_of(e) not in SIDES:
        return False
    return int(_core.lib.dv_elem_check(_desc(e))) == 0


def refusal(e: Element) -> tuple[str, str] | None:
    """None when the core accepts e; else (parameter, reason) naming the first parameter
    outside its registry bound (or the side)."""
    if core_accepts(e):
        return None
    if side_of(e) not in SIDES:
        return "side", f"{side_of(e)!r} is not one of {', '.join(SIDES)}"
    for p in spec(e).params:
        v = float(getattr(e, p.name))
        if not p.admits(v):
            return p.name, f"must be {p.bound_text()}, got {v!r}"
    return "type", "refused by the core's element check (dv_elem_check)"


def force(e: Element, x: Any = None, v: Any = None) -> np.ndarray:
    """The element's force g (N) over a record of relative displacements x = X (m) and
    velocities v = V (m/s), evaluated by the core (dv_elem_force_block; stick-slip from the
    virgin state). Only the array the law reads is needed."""
    t = spec(e)
    z = v if t.on_velocity else x
    if z is None:
        raise ConfigError(f"{t.name}: the law reads {'V' if t.on_velocity else 'X'}, not given")
    a = _core.as_doubles(z)
    out = np.empty_like(a)
    hist = np.zeros(2)
    p = _core.ptr(a)
    null = _core.ffi.NULL
    st = _core.lib.dv_elem_force_block(_desc(e), null if t.on_velocity else p,
                                       p if t.on_velocity else null, a.size, _core.ptr(hist),
                                       _core.ptr(out))
    if st < 0 and st != _core.lib.DV_ENUMERIC:
        _core.check(st, "dv_elem_force_block")
    return out


def relative(e: Element, z: np.ndarray, ground: np.ndarray | float = 0.0) -> np.ndarray:
    """X (or V) of e from per-DOF rows z (n x T, DOF j in row j - 1; DOF 0 is the ground,
    which moves by ``ground``)."""
    za = z[e.dof_a - 1] if e.dof_a > 0 else ground
    return np.asarray(z[e.dof_b - 1] - za)


def restoring(elems: Sequence[Element], x: np.ndarray, v: np.ndarray,
              xg: np.ndarray | float = 0.0, vg: np.ndarray | float = 0.0) -> np.ndarray:
    """Restoring forces (n x T) of the elements on per-DOF displacements and velocities (the
    ground's xg, vg: a ground-displacement input): g at DOF b, -g at DOF a (the element
    pushes DOF a by +g and DOF b by -g)."""
    f = np.zeros_like(x)
    for e in elems:
        g = force(e, relative(e, x, xg), relative(e, v, vg))
        f[e.dof_b - 1] += g
        if e.dof_a > 0:
            f[e.dof_a - 1] -= g
    return f
