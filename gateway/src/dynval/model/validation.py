"""Validation of a model: physical sense with field-named one-line errors, and the core's own
limits: sizes from the compiled core's description struct and dv_model_buf_len, element laws
and parameters by dv_elem_check (the registry's bounds only name the field it refused)."""
from __future__ import annotations

import dataclasses
import difflib
import functools
import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dynval import _core
from dynval.errors import ConfigError, short_repr
from dynval.model import daq
from dynval.model import elements as el
from dynval.model.schema import (
    DAMPING_TYPES,
    DAQ_FILTER_TYPES,
    INPUT_KINDS,
    INTERPOLATIONS,
    LINK_PARAMS,
    MAX_DAQ_FILTER_ORDER,
    OUTPUT_KINDS,
    Damping,
    DaqFilter,
    Link,
    Model,
)

log = logging.getLogger(__name__)

MAX_OVERSAMPLE = 64  # band-limited interpolation factor (Python side, not a core limit)


class Ctx:
    """Error context: the file and the field being read."""

    def __init__(self, source: str) -> None:
        self.source = source or "<model>"

    def err(self, where: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.source}: field '{where}': {msg}")

    def get(self, obj: Mapping[str, Any], key: str, where: str) -> Any:
        if not isinstance(obj, Mapping):
            raise self.err(where, f"expected an object, got {type(obj).__name__}")
        if key not in obj:
            raise self.err(f"{where}.{key}" if where else key, "missing")
        return obj[key]

    def num(self, v: Any, where: str) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.err(where, f"expected a number, got {short_repr(v)}")
        try:
            x = float(v)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            raise self.err(where, f"must be finite, got {short_repr(v)}")
        return x

    def int_(self, v: Any, where: str) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            if isinstance(v, float) and v.is_integer():
                return int(v)
            raise self.err(where, f"expected an integer, got {short_repr(v)}")
        return int(v)

    def nums(self, v: Any, where: str) -> tuple[float, ...]:
        if not isinstance(v, (list, tuple)):
            raise self.err(where, f"expected a list of numbers, got {type(v).__name__}")
        return tuple(self.num(x, f"{where}[{i}]") for i, x in enumerate(v))

    def choice(self, v: Any, where: str, options: Sequence[str]) -> str:
        if not isinstance(v, str) or v not in options:
            raise self.err(where, f"{short_repr(v)} is not one of {', '.join(options)}"
                           f"{did_you_mean(v, options)}")
        return v

    def known(self, obj: Any, where: str, keys: Sequence[str]) -> None:
        """Every key of obj (when it is an object) is one of keys; else the first unknown one
        is an error with the closest known key."""
        if not isinstance(obj, Mapping):
            return
        for k in obj:
            if k not in keys:
                field = f"{where}.{k}" if where else str(k)
                raise self.err(field, f"unknown key{did_you_mean(k, keys)} (known here: "
                               f"{', '.join(keys)})")


def did_you_mean(word: Any, options: Sequence[str]) -> str:
    """'; did you mean 'x'?' for the closest of options (difflib), or ''."""
    close = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


@functools.cache
def core_limits() -> dict[str, int]:
    """The compiled core's limits: DOFs, outputs, elements (the struct arrays' sizes) and
    sub-steps (the largest n_sub dv_model_buf_len accepts)."""
    d = _core.ffi.new("dv_model_desc_t *")
    _core.check(_core.lib.dv_model_desc_default(d), "dv_model_desc_default")
    lim = {"dof": len(d.mass_kg), "out": len(d.out), "elem": len(d.elem), "link": len(d.link)}
    d.n_dof, d.n_out, d.n_elem = 1, 1, 1
    n_sub = 0
    for s in range(1, 257):
        d.n_sub = s
        if _core.lib.dv_model_buf_len(d) == 0:
            break
        n_sub = s
    lim["sub"] = n_sub
    return lim


def validate(m: Model, ctx: Ctx | None = None) -> None:
    """Check a model for physical sense and the core's limits; ConfigError names the field."""
    c = ctx or Ctx(m.source)
    lim = core_limits()
    n = m.n_dof
    if not 1 <= n <= lim["dof"]:
        raise c.err("masses_kg", f"{n} DOFs; this core supports 1..{lim['dof']}")
    _check_structure(m, c)
    _check_damping(m.damping, n, c)
    _check_io(m, c, lim["out"])
    if len(m.elements) > lim["elem"]:
        raise c.err("elements", f"{len(m.elements)} elements; this core supports {lim['elem']}")
    for i, e in enumerate(m.elements):
        _check_element(e, n, c, f"elements[{i}]")
    if len(m.links) > lim["link"]:
        raise c.err("links", f"{len(m.links)} links; this core supports {lim['link']}")
    for i, lk in enumerate(m.links):
        _check_link(lk, n, c, f"links[{i}]")
    if not 1 <= m.substeps <= lim["sub"]:
        raise c.err("simulation.substeps", f"must be 1..{lim['sub']}, got {m.substeps}")
    if not 1 <= m.oversample <= MAX_OVERSAMPLE:
        raise c.err("simulation.oversample", f"must be 1..{MAX_OVERSAMPLE}, got {m.oversample}")
    if m.interpolation not in INTERPOLATIONS:
        raise c.err("simulation.input_interpolation", f"{m.interpolation!r} is not one of "
                    f"{', '.join(INTERPOLATIONS)}")
    if m.fs_hz is not None and not m.fs_hz > 0:
        raise c.err("fs_hz", f"must be > 0, got {m.fs_hz!r}")
    if m.daq_filter is not None:
        _check_daq_filter(m.daq_filter, m.fs_hz, c)
    _check_in_core(m, c)


def _check_daq_filter(f: DaqFilter, fs_hz: float | None, c: Ctx) -> None:
    w = "simulation.daq_filter"
    if f.type not in DAQ_FILTER_TYPES:
        raise c.err(f"{w}.type", f"{f.type!r} is not one of {', '.join(DAQ_FILTER_TYPES)}")
    if not 1 <= f.order <= MAX_DAQ_FILTER_ORDER:
        raise c.err(f"{w}.order", f"must be 1..{MAX_DAQ_FILTER_ORDER}, got {f.order}")
    if not (math.isfinite(f.cutoff_hz) and f.cutoff_hz > 0):
        raise c.err(f"{w}.cutoff_hz", f"must be > 0 Hz, got {f.cutoff_hz!r}")
    why = "" if fs_hz is None else daq.cutoff_outside(f, fs_hz)
    if why:
        raise c.err(f"{w}.cutoff_hz", why)


def _check_in_core(m: Model, c: Ctx) -> None:
    """The core's own check of the whole description (dv_model_init; only DV_EINVAL, a value
    out of its range, is a validation error: stability depends on the sample period). After
    the checks above, what it can still refuse is a damping matrix that is not symmetric
    within its tolerance."""
    if _core_refuses(m):
        if m.damping.type == "matrix":
            raise c.err("damping.c_n_s_per_m", "refused by the core's check (dv_model_init: "
                        "DV_EINVAL): not symmetric within its tolerance")
        bad = _out_of_range(m)
        if bad is not None:
            raise c.err(bad[0], f"{bad[1]:g} is out of the core's range (dv_model_init: "
                        "DV_EINVAL; at the median of its kind the model is taken): too far "
                        "from the others for the real type's arithmetic")
        raise ConfigError(f"{c.source}: refused by the core's check (dv_model_init: DV_EINVAL)")


def _core_refuses(m: Model) -> bool:
    """Whether dv_model_init refuses m's description as out of its range (DV_EINVAL)."""
    from dynval.model.simulation import _Core  # the simulation reads this module

    core = _Core(m, 1.0 / m.fs_hz if m.fs_hz else 1e-3)
    st = _core.lib.dv_model_init(core.cm, core.desc, core.dt, core.mptr, core.mlen)
    return bool(st == _core.lib.DV_EINVAL)


def _out_of_range(m: Model) -> tuple[str, float] | None:
    """The mass or story stiffness the core refuses m for ('masses_kg[0]', its value): the
    first whose value set to the median of its kind makes the model acceptable; None when none
    does. A mass of 1e-200 kg among ones of 6.5 kg passes every field's own check, not the
    core's modal arithmetic."""
    for name in ("masses_kg", "stiffness_n_per_m"):
        vals = list(getattr(m, name))
        for i in range(len(vals)):
            trial = [*vals[:i], float(np.median(vals)), *vals[i + 1:]]
            changed: dict[str, Any] = {name: tuple(trial)}
            if trial != vals and not _core_refuses(dataclasses.replace(m, **changed)):
                return f"{name}[{i}]", float(vals[i])
    return None


def _check_structure(m: Model, c: Ctx) -> None:
    n = m.n_dof
    for i, v in enumerate(m.masses_kg):
        if not (math.isfinite(v) and v > 0):
            raise c.err(f"masses_kg[{i}]", f"mass of DOF {i + 1} must be > 0 kg, got {v!r}")
    if len(m.stiffness_n_per_m) != n:
        raise c.err("stiffness_n_per_m", f"expected {n} story stiffnesses (k1 ground-DOF1, "
                    f"k2 DOF1-DOF2, ...), got {len(m.stiffness_n_per_m)}")
    for i, v in enumerate(m.stiffness_n_per_m):
        if not (math.isfinite(v) and v >= 0):
            raise c.err(f"stiffness_n_per_m[{i}]", f"k{i + 1} must be >= 0 N/m, got {v!r}")
    linked = {d for lk in m.links for d in (lk.dof_a, lk.dof_b)}
    if any(k == 0 and i + 2 not in linked for i, k in enumerate(m.stiffness_n_per_m[1:])):
        log.warning("%s: a story stiffness k2..kn is 0 and no link holds its DOF: the chain "
                    "falls apart", c.source)


def _check_damping(d: Damping, n: int, c: Ctx) -> None:
    if d.type == "modal":
        if len(d.zeta) != n:
            raise c.err("damping.zeta", f"expected {n} modal ratios, got {len(d.zeta)}")
        for i, z in enumerate(d.zeta):
            if not (math.isfinite(z) and z >= 0):
                raise c.err(f"damping.zeta[{i}]", f"must be >= 0, got {z!r}")
    elif d.type == "rayleigh":
        if d.modes:
            if len(d.modes) != 2 or len(d.zeta) != 2:
                raise c.err("damping", "rayleigh from modes needs two modes and two zeta")
            for i, k in enumerate(d.modes):
                if not 1 <= k <= n:
                    raise c.err(f"damping.modes[{i}]", f"mode {k} out of range 1..{n}")
            if d.modes[0] == d.modes[1]:
                raise c.err("damping.modes", "the two modes must differ")
        elif d.alpha_per_s is None or d.beta_s is None:
            raise c.err("damping", "rayleigh needs modes + zeta, or alpha_per_s + beta_s")
    elif d.type == "matrix":
        for i, row in enumerate(d.c_n_s_per_m):
            if len(row) != n:
                raise c.err(f"damping.c_n_s_per_m[{i}]", f"row {i + 1} has {len(row)} values; "
                            f"the matrix is {n} x {n}")
        cm = np.asarray(d.c_n_s_per_m, dtype=float) if d.c_n_s_per_m else np.zeros((0, 0))
        if cm.shape != (n, n):
            raise c.err("damping.c_n_s_per_m", f"expected {n} x {n}, got {cm.shape}")
        # its symmetry: the core's tolerance (_check_in_core)
    else:
        raise c.err("damping.type", f"{d.type!r} is not one of {', '.join(DAMPING_TYPES)}")


def _check_io(m: Model, c: Ctx, max_out: int) -> None:
    n = m.n_dof
    if m.input.kind not in INPUT_KINDS:
        raise c.err("input.kind", f"{m.input.kind!r} is not one of {', '.join(INPUT_KINDS)}")
    if m.input.kind == "force" and not 1 <= m.input.dof <= n:
        raise c.err("input.dof", f"DOF {m.input.dof} out of range 1..{n}")
    if not 1 <= len(m.outputs) <= max_out:
        raise c.err("outputs", f"{len(m.outputs)} outputs; need 1..{max_out}")
    for name, o in m.outputs.items():
        w = f"outputs.{name}"
        if o.kind not in OUTPUT_KINDS:
            raise c.err(f"{w}.kind", f"{o.kind!r} is not one of {', '.join(OUTPUT_KINDS)}")
        if o.kind in ("acc", "vel", "disp", "story_force") and not 1 <= o.index <= n:
            raise c.err(w, f"{'story' if o.kind == 'story_force' else 'DOF'} {o.index} out of "
                        f"range 1..{n}")
        if o.kind == "contact_force" and not 1 <= o.index <= len(m.elements):
            raise c.err(f"{w}.element", f"element {o.index} out of range 1..{len(m.elements)}")
        if not (math.isfinite(o.gain) and o.gain != 0):
            raise c.err(f"{w}.gain", f"sensor gain must be finite and non-zero (negative: "
                        f"the sensor's sign convention is reversed), got {o.gain!r}")
        if not math.isfinite(o.offset):
            raise c.err(f"{w}.offset", f"sensor offset must be finite, got {o.offset!r}")


def _check_link(lk: Link, n: int, c: Ctx, w: str) -> None:
    if not 1 <= lk.dof_a <= n or not 1 <= lk.dof_b <= n or lk.dof_a == lk.dof_b:
        raise c.err(f"{w}.between", f"[{lk.dof_a}, {lk.dof_b}]: two different DOFs in 1..{n} "
                    "(a link to the ground is a story spring: k1, or an element)")
    for name, unit in LINK_PARAMS.items():
        v = float(getattr(lk, name))
        if not (math.isfinite(v) and v >= 0):
            raise c.err(f"{w}.{name}", f"must be >= 0 {unit}, got {v!r}")


def _check_element(e: el.Element, n: int, c: Ctx, w: str) -> None:
    """DOFs here (the model's part of the check); law and parameters by dv_elem_check."""
    if e.type not in el.REGISTRY:
        raise c.err(f"{w}.type", f"{e.type!r} is not one of {', '.join(el.TYPES)}")
    if not 0 <= e.dof_a <= n or not 1 <= e.dof_b <= n or e.dof_a == e.dof_b:
        raise c.err(f"{w}.between", f"[{e.dof_a}, {e.dof_b}]: DOFs in 1..{n} (the first "
                    "may be 0 = ground), different")
    bad = el.refusal(e)
    if bad is not None:
        raise c.err(f"{w}.{bad[0]}", bad[1])
