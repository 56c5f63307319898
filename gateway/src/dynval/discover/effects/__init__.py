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
constant force offset) are built from the element registry (dynval.model.elements): their
parameters carry the registry's names and units, and their evidence bases are the element's
law evaluated by the core (dv_elem_force_block), never a copy of it. ``available = False``
(ranked on evidence, never fitted) is left for effect types the model cannot represent.

The modules: base (the EffectType base, the candidate, the states and what the types share),
declared (changes of declared parameters: stiffness, mass, damping, sensor gain and offset,
the DAQ's anti-alias filter),
elements (new model elements), appendage (a new DOF); this package holds the library.
"""
from __future__ import annotations

import logging
from typing import Any

from dynval import model as mdl
from dynval.discover.effects.appendage import Appendage, appendage_motion
from dynval.discover.effects.base import (
    Candidate,
    EffectType,
    NoEffect,
    Param,
    States,
    damping_params,
    drift,
    pair_basis,
    pair_label,
    pairs,
    readjust_every_stiffness,
    readjust_local,
    relative,
)
from dynval.discover.effects.declared import (
    DampingChange,
    DaqAntiAlias,
    MassChange,
    SensorGain,
    SensorOffset,
    StiffnessChange,
)
from dynval.discover.effects.elements import (
    Contact,
    CubicStiffness,
    ForceOffset,
    Friction,
    StickSlipFriction,
    VelocitySquaredDamping,
    rigid_body_like,
)

__all__ = [
    "LIBRARY", "NONE", "Appendage", "Candidate", "Contact", "CubicStiffness", "DampingChange",
    "DaqAntiAlias",
    "EffectType", "ForceOffset", "Friction", "MassChange", "NoEffect", "Param", "SensorGain",
    "SensorOffset", "States", "StickSlipFriction", "StiffnessChange", "VelocitySquaredDamping",
    "appendage_motion", "by_type", "catalogue", "damping_params", "describe", "drift",
    "pair_basis", "pair_label", "pairs", "readjust_every_stiffness", "readjust_local",
    "relative", "rigid_body_like", "structural"]

log = logging.getLogger(__name__)

LIBRARY: tuple[EffectType, ...] = (
    Contact(), StiffnessChange(), MassChange(), DampingChange(), SensorGain(), SensorOffset(),
    Friction(), StickSlipFriction(), CubicStiffness(), VelocitySquaredDamping(), ForceOffset(),
    Appendage(), DaqAntiAlias())
NONE = NoEffect()


def by_type(name: str) -> EffectType:
    for e in (*LIBRARY, NONE):
        if e.type == name:
            return e
    raise KeyError(name)


def link_held_dofs(m: mdl.Model) -> set[int]:
    """The DOFs held only by links (an appendage's mass, added by an accepted effect): no
    story spring on either side and no sensor. No effect is placed on them: their motion is
    the appendage's own, already fitted."""
    k = m.stiffness_n_per_m
    linked = {d for lk in m.links for d in (lk.dof_a, lk.dof_b)}
    seen = {o.index for o in m.outputs.values()}
    return {j for j in range(1, m.n_dof + 1)
            if k[j - 1] == 0 and (j == m.n_dof or k[j] == 0) and j in linked and j not in seen}


def _dofs_of(loc: dict[str, Any]) -> set[int]:
    out = set(loc.get("between", ()))
    if "dof" in loc:
        out.add(int(loc["dof"]))
    if "story" in loc:
        out |= {int(loc["story"]) - 1, int(loc["story"])}
    return out


def catalogue(m: mdl.Model, quiet: bool = False) -> list[Candidate]:
    """Every candidate (type x location) for a model, none on a DOF held only by links
    (link_held_dofs); unavailable types are logged (unless quiet)."""
    out: list[Candidate] = []
    held = link_held_dofs(m)
    for e in LIBRARY:
        cs = [c for c in e.candidates(m) if not _dofs_of(c.location) & held]
        if cs and not e.available and not quiet:
            log.info("effect type %s: %s", e.type, e.note)
        out.extend(cs)
    return out


def structural(entries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The effect entries (discover's JSON ``effects``) of the structure, without those of
    its measurement chain (EffectType.measurement_chain: sensor gains and offsets, the DAQ's
    filter)."""
    return [e for e in entries if not by_type(e["type"]).measurement_chain]


def describe() -> list[dict[str, Any]]:
    """The library as data (for the report and docs)."""
    return [{"type": e.type, "location": e.location_kind, "law": e.law,
             "available": e.available, "note": e.note} for e in (*LIBRARY, NONE)]
