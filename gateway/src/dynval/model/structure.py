"""Structural edits of a model that add DOFs: an appendage (a secondary mass on a spring and a
dashpot hanging from a DOF: a mode the declared model lacks). The one home of that edit: the
synthetic generator and discover's appendage effect both call it."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from dynval.errors import ConfigError
from dynval.model.schema import Damping, Link, Model
from dynval.model.simulation import linear


def physical_damping(m: Model) -> Damping:
    """m's damping as the matrix the core builds (modal or Rayleigh ratios become the C they
    give on m's modes), without the links' dashpots (the core adds those to it): what stays
    when DOFs are added."""
    c = np.array(linear(m).c)
    for lk in m.links:
        a, b = lk.dof_a - 1, lk.dof_b - 1
        c[[a, b], [a, b]] -= lk.c_n_s_per_m
        c[[a, b], [b, a]] += lk.c_n_s_per_m
    return Damping("matrix", c_n_s_per_m=tuple(tuple(float(v) for v in row) for row in c))


def with_appendage(m: Model, dof: int, mass_kg: float, f_hz: float, zeta: float,
                   name: str = "appendage") -> Model:
    """m with an appendage at ``dof`` (1-based): a new last DOF of ``mass_kg`` held by a link
    of stiffness mass (2 pi f)^2 and damping 2 zeta mass 2 pi f, so that ``f_hz`` and ``zeta``
    are its frequency and damping ratio on a fixed base. The declared damping is kept as the
    physical matrix it is (the structure's dissipation does not move with the new mode);
    outputs, input and elements keep their DOF numbers."""
    if not 1 <= dof <= m.n_dof:
        raise ConfigError(f"appendage at DOF {dof}: out of range 1..{m.n_dof}")
    if not (mass_kg > 0 and f_hz > 0 and zeta >= 0 and math.isfinite(mass_kg * f_hz * zeta)):
        raise ConfigError(f"appendage: mass {mass_kg!r} kg and frequency {f_hz!r} Hz must be "
                          f"> 0, damping ratio {zeta!r} >= 0")
    w = 2 * math.pi * f_hz
    c0 = np.array(physical_damping(m).c_n_s_per_m)
    n = m.n_dof
    c = np.zeros((n + 1, n + 1))
    c[:n, :n] = c0
    names = (*m.dof_names, name) if m.dof_names else ()
    return dataclasses.replace(
        m, masses_kg=(*m.masses_kg, mass_kg), stiffness_n_per_m=(*m.stiffness_n_per_m, 0.0),
        damping=Damping("matrix", c_n_s_per_m=tuple(tuple(float(v) for v in r) for r in c)),
        links=(*m.links, Link(dof, n + 1, mass_kg * w * w, 2 * zeta * mass_kg * w, name)),
        dof_names=names)
