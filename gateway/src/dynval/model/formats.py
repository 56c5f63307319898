"""Model files: dynval's own format (``"format": "dynval-model/1"``, gateway/docs/model-format.md)
and the ``declared_model.json`` layout of the shared test data (``masses_kg``,
``story_stiffness_N_per_m`` {k1..kn}, ``damping``, ``input``, ``outputs``, ``fs_Hz``); JSON, or
YAML with a .yaml/.yml suffix. Element entries are read and written through the registry
(model/elements.py)."""
from __future__ import annotations

import dataclasses
import importlib
import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dynval.errors import ConfigError, InputFileError
from dynval.io.jsonfile import read_mapping_file
from dynval.model import elements as el
from dynval.model.schema import (
    DAMPING_TYPES,
    DAQ_FILTER_TYPES,
    FORMAT,
    INPUT_KINDS,
    INTERPOLATIONS,
    MODEL_KEYS,
    OUTPUT_INDEX_KEY,
    OUTPUT_KINDS,
    Damping,
    DaqFilter,
    Input,
    Link,
    Model,
    Output,
)
from dynval.model.validation import Ctx, validate


def _yaml() -> Any:
    return importlib.import_module("yaml")  # PyYAML


def _read_mapping(path: Path) -> dict[str, Any]:
    try:
        data = read_mapping_file(path)
    except InputFileError as exc:  # a model is configuration: the same one line, ConfigError
        raise ConfigError(f"{exc} (model file)") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a model file holds one object, found {type(data).__name__}")
    return data


def load(path: Path | str) -> Model:
    """Read a model file (dynval's format or the declared_model.json layout) and validate it."""
    p = Path(path)
    return from_dict(_read_mapping(p), source=str(p))


def from_dict(d: Mapping[str, Any], source: str = "") -> Model:
    """Build and validate a model from a parsed file (either layout)."""
    ctx = Ctx(source)
    if "format" in d:
        if d["format"] != FORMAT:
            raise ctx.err("format", f"unsupported format {d['format']!r} (this dynval reads "
                          f"{FORMAT!r})")
        m = _from_dynval(d, ctx)
    elif "masses_kg" in d and "story_stiffness_N_per_m" in d:
        m = _from_declared(d, ctx)
    else:
        raise ConfigError(f"{ctx.source}: not a model file: expected \"format\": \"{FORMAT}\" "
                          "or the declared_model.json layout (masses_kg, story_stiffness_N_per_m)")
    m = dataclasses.replace(m, source=ctx.source)
    validate(m, ctx)
    return m


def _damping(d: Any, ctx: Ctx, where: str) -> Damping:
    t = ctx.choice(ctx.get(d, "type", where), f"{where}.type", DAMPING_TYPES)
    ctx.known(d, where, MODEL_KEYS["damping"])
    if t == "modal":
        return Damping("modal", zeta=ctx.nums(ctx.get(d, "zeta", where), f"{where}.zeta"))
    if t == "matrix":
        c = ctx.get(d, "c_n_s_per_m", where) if "c_n_s_per_m" in d else ctx.get(
            d, "C_matrix_N_s_per_m", where)
        if not isinstance(c, (list, tuple)):
            raise ctx.err(f"{where}.c_n_s_per_m", "expected a list of rows")
        rows = tuple(ctx.nums(r, f"{where}.c_n_s_per_m[{i}]") for i, r in enumerate(c))
        return Damping("matrix", c_n_s_per_m=rows)
    if "alpha_per_s" in d or "beta_s" in d:
        return Damping("rayleigh",
                       alpha_per_s=ctx.num(ctx.get(d, "alpha_per_s", where),
                                           f"{where}.alpha_per_s"),
                       beta_s=ctx.num(ctx.get(d, "beta_s", where), f"{where}.beta_s"))
    src = d.get("fitted_to", d)
    w = f"{where}.fitted_to" if "fitted_to" in d else where
    if "fitted_to" in d:
        ctx.known(src, w, MODEL_KEYS["fitted_to"])
    modes = ctx.get(src, "modes", w) if "modes" in src else ctx.get(src, "mode", w)
    if not isinstance(modes, (list, tuple)):
        raise ctx.err(f"{w}.modes", "expected two mode numbers")
    mm = tuple(ctx.int_(x, f"{w}.modes[{i}]") for i, x in enumerate(modes))
    return Damping("rayleigh", modes=mm, zeta=ctx.nums(ctx.get(src, "zeta", w), f"{w}.zeta"))


def _dof(v: Any, ctx: Ctx, where: str) -> int:
    if v == "ground":
        return 0
    return ctx.int_(v, where)



def _element(e: Any, ctx: Ctx, w: str) -> el.Element:
    """One entry of ``elements``: its type's registry parameters, ``between``, ``side``."""
    t = el.spec(ctx.choice(ctx.get(e, "type", w), f"{w}.type", el.TYPES))
    ctx.known(e, w, (*MODEL_KEYS["element"], *(p.name for p in t.params)))
    btw = ctx.get(e, "between", w)
    if not isinstance(btw, (list, tuple)) or len(btw) != 2:
        raise ctx.err(f"{w}.between", "expected two DOFs [a, b] (a may be \"ground\")")
    vals = {p.name: ctx.num(ctx.get(e, p.name, w) if p.default is None
                            else e.get(p.name, p.default), f"{w}.{p.name}") for p in t.params}
    side = ctx.choice(e.get("side", "pos"), f"{w}.side", el.SIDES) if t.sided else "pos"
    return el.make(t.name, _dof(btw[0], ctx, f"{w}.between[0]"),
                   _dof(btw[1], ctx, f"{w}.between[1]"), vals, side=side,
                   name=str(e.get("name", "")))


def _daq_filter(d: Any, ctx: Ctx) -> DaqFilter | None:
    w = "simulation.daq_filter"
    if d is None:
        return None
    if not isinstance(d, Mapping):
        raise ctx.err(w, "expected an object with type, order and cutoff_hz")
    ctx.known(d, w, MODEL_KEYS["daq_filter"])
    return DaqFilter(ctx.choice(ctx.get(d, "type", w), f"{w}.type", DAQ_FILTER_TYPES),
                     ctx.int_(ctx.get(d, "order", w), f"{w}.order"),
                     ctx.num(ctx.get(d, "cutoff_hz", w), f"{w}.cutoff_hz"))


def _link(e: Any, ctx: Ctx, w: str) -> Link:
    """One entry of ``links``: ``between`` two DOFs, ``k_n_per_m``, ``c_n_s_per_m`` (0)."""
    ctx.known(e, w, MODEL_KEYS["link"])
    btw = ctx.get(e, "between", w)
    if not isinstance(btw, (list, tuple)) or len(btw) != 2:
        raise ctx.err(f"{w}.between", "expected two DOFs [a, b]")
    return Link(ctx.int_(btw[0], f"{w}.between[0]"), ctx.int_(btw[1], f"{w}.between[1]"),
                ctx.num(ctx.get(e, "k_n_per_m", w), f"{w}.k_n_per_m"),
                ctx.num(e.get("c_n_s_per_m", 0.0), f"{w}.c_n_s_per_m"),
                name=str(e.get("name", "")))


def _from_dynval(d: Mapping[str, Any], ctx: Ctx) -> Model:
    ctx.known(d, "", MODEL_KEYS["model"])
    masses = ctx.nums(ctx.get(d, "masses_kg", ""), "masses_kg")
    ks = ctx.nums(ctx.get(d, "stiffness_n_per_m", ""), "stiffness_n_per_m")
    damp = _damping(ctx.get(d, "damping", ""), ctx, "damping")
    di = ctx.get(d, "input", "")
    kind = ctx.choice(ctx.get(di, "kind", "input"), "input.kind", INPUT_KINDS)
    ctx.known(di, "input", MODEL_KEYS["input"])
    dof = ctx.int_(ctx.get(di, "dof", "input"), "input.dof") if kind == "force" else 0
    ch = di.get("channel")
    if ch is not None and not isinstance(ch, str):
        raise ctx.err("input.channel", f"expected a column name, got {ch!r}")
    outs_raw = ctx.get(d, "outputs", "")
    if not isinstance(outs_raw, Mapping):
        raise ctx.err("outputs", "expected an object: channel name -> {kind, dof|story|element}")
    outs: dict[str, Output] = {}
    for name, o in outs_raw.items():
        w = f"outputs.{name}"
        ok = ctx.choice(ctx.get(o, "kind", w), f"{w}.kind", OUTPUT_KINDS)
        ctx.known(o, w, MODEL_KEYS["output"])
        key = OUTPUT_INDEX_KEY.get(ok)
        outs[str(name)] = Output(ok, ctx.int_(ctx.get(o, key, w), f"{w}.{key}") if key else 0,
                                 gain=ctx.num(o.get("gain", 1.0), f"{w}.gain"),
                                 offset=ctx.num(o.get("offset", 0.0), f"{w}.offset"))
    er = d.get("elements", [])
    if not isinstance(er, (list, tuple)):
        raise ctx.err("elements", "expected a list of elements")
    elems = tuple(_element(e, ctx, f"elements[{i}]") for i, e in enumerate(er))
    lr = d.get("links", [])
    if not isinstance(lr, (list, tuple)):
        raise ctx.err("links", "expected a list of links")
    links = tuple(_link(e, ctx, f"links[{i}]") for i, e in enumerate(lr))
    sim = d.get("simulation", {})
    if not isinstance(sim, Mapping):
        raise ctx.err("simulation", "expected an object")
    ctx.known(sim, "simulation", MODEL_KEYS["simulation"])
    fs = d.get("fs_hz")
    names = d.get("dofs", ())
    return Model(
        masses_kg=masses, stiffness_n_per_m=ks, damping=damp,
        input=Input(kind, dof, ch), outputs=outs, elements=elems, links=links,
        substeps=ctx.int_(sim.get("substeps", 8), "simulation.substeps"),
        oversample=ctx.int_(sim.get("oversample", 4), "simulation.oversample"),
        interpolation=ctx.choice(sim.get("input_interpolation", "bandlimited"),
                                 "simulation.input_interpolation", INTERPOLATIONS),
        daq_filter=_daq_filter(sim.get("daq_filter"), ctx),
        fs_hz=None if fs is None else ctx.num(fs, "fs_hz"),
        name=str(d.get("name", "")), description=str(d.get("description", "")),
        dof_names=tuple(str(x) for x in names) if isinstance(names, (list, tuple)) else ())


_DOF_RE = re.compile(r"\bDOF\s*(\d+)", re.IGNORECASE)
_K_RE = re.compile(r"^k(\d+)(?:_|$)")


def _kind_from_channel(name: str) -> str | None:
    low = name.lower()
    if low.startswith("acc") or low.endswith(("_mps2", "_m_s2", "_ms2")):
        return "acc"
    if low.startswith("vel") or low.endswith("_mps"):
        return "vel"
    if low.startswith(("disp", "dx", "x")) or low.endswith(("_m", "_mm")):
        return "disp"
    return None


def _from_declared(d: Mapping[str, Any], ctx: Ctx) -> Model:
    ctx.known(d, "", MODEL_KEYS["declared"])
    masses = ctx.nums(d["masses_kg"], "masses_kg")
    kd = d["story_stiffness_N_per_m"]
    if isinstance(kd, (list, tuple)):
        ks = ctx.nums(kd, "story_stiffness_N_per_m")
    else:
        if not isinstance(kd, Mapping):
            raise ctx.err("story_stiffness_N_per_m", "expected {k1: .., k2: ..} or a list")
        byi: dict[int, float] = {}
        for key, v in kd.items():
            g = _K_RE.match(str(key))
            if g is None:
                raise ctx.err(f"story_stiffness_N_per_m.{key}", "key must start with k<i>")
            byi[int(g.group(1))] = ctx.num(v, f"story_stiffness_N_per_m.{key}")
        want = list(range(1, len(masses) + 1))
        if sorted(byi) != want:
            raise ctx.err("story_stiffness_N_per_m", f"expected k1..k{len(masses)} (one per "
                          f"story), found k{', k'.join(str(i) for i in sorted(byi))}")
        ks = tuple(byi[i] for i in want)
    damp = _damping(ctx.get(d, "damping", ""), ctx, "damping")
    di = ctx.get(d, "input", "")
    ch = di.get("channel") if isinstance(di, Mapping) else None
    ctx.known(di, "input", MODEL_KEYS["input"])
    inp = Input("force", ctx.int_(ctx.get(di, "dof", "input"), "input.dof"),
                None if ch is None else str(ch))
    outs_raw = ctx.get(d, "outputs", "")
    if not isinstance(outs_raw, Mapping):
        raise ctx.err("outputs", "expected an object: channel name -> 'DOF<i> ...'")
    outs: dict[str, Output] = {}
    for name, desc in outs_raw.items():
        w = f"outputs.{name}"
        if isinstance(desc, Mapping):  # dynval-style entry inside a declared file
            ok = ctx.choice(ctx.get(desc, "kind", w), f"{w}.kind", OUTPUT_KINDS)
            ctx.known(desc, w, MODEL_KEYS["output"])
            outs[str(name)] = Output(ok, ctx.int_(desc.get("dof", desc.get("index", 0)), w))
            continue
        g = _DOF_RE.search(str(desc))
        if g is None:
            raise ctx.err(w, f"cannot find the DOF in {desc!r} (expected e.g. 'DOF2 floor 1')")
        kind = _kind_from_channel(str(name))
        if kind is None:
            raise ctx.err(w, f"cannot tell whether '{name}' is an acceleration, velocity or "
                          "displacement (name it acc*/vel*/disp* or with a unit suffix)")
        outs[str(name)] = Output(kind, int(g.group(1)))
    fs = d.get("fs_Hz", d.get("fs_hz"))
    names = d.get("dofs", ())
    return Model(masses_kg=masses, stiffness_n_per_m=ks, damping=damp, input=inp, outputs=outs,
                 fs_hz=None if fs is None else ctx.num(fs, "fs_Hz"),
                 name=str(d.get("name", "")), description=str(d.get("description", "")),
                 dof_names=tuple(str(x) for x in names) if isinstance(names, (list, tuple))
                 else ())



def to_dict(m: Model) -> dict[str, Any]:
    """The model in dynval's file format (see gateway/docs/model-format.md)."""
    d = m.damping
    damp: dict[str, Any] = {"type": d.type}
    if d.type == "modal":
        damp["zeta"] = list(d.zeta)
    elif d.type == "rayleigh" and d.modes:
        damp.update(modes=list(d.modes), zeta=list(d.zeta))
    elif d.type == "rayleigh":
        damp.update(alpha_per_s=d.alpha_per_s, beta_s=d.beta_s)
    else:
        damp["c_n_s_per_m"] = [list(r) for r in d.c_n_s_per_m]
    inp: dict[str, Any] = {"kind": m.input.kind}
    if m.input.kind == "force":
        inp["dof"] = m.input.dof
    if m.input.channel is not None:
        inp["channel"] = m.input.channel
    outs: dict[str, Any] = {}
    for name, o in m.outputs.items():
        key = OUTPUT_INDEX_KEY.get(o.kind)
        outs[name] = {"kind": o.kind, key: o.index} if key else {"kind": o.kind}
        if o.gain != 1.0:
            outs[name]["gain"] = o.gain
        if o.offset != 0.0:
            outs[name]["offset"] = o.offset
    elems: list[dict[str, Any]] = []
    for e in m.elements:
        ed: dict[str, Any] = {"type": e.type}
        if e.name:
            ed["name"] = e.name
        ed["between"] = ["ground" if e.dof_a == 0 else e.dof_a, e.dof_b]
        if el.spec(e).sided:
            ed["side"] = el.side_of(e)
        ed.update(el.values(e))
        elems.append(ed)
    links = [{**({"name": lk.name} if lk.name else {}), "between": [lk.dof_a, lk.dof_b],
              "k_n_per_m": lk.k_n_per_m, "c_n_s_per_m": lk.c_n_s_per_m} for lk in m.links]
    out: dict[str, Any] = {"format": FORMAT}
    if m.name:
        out["name"] = m.name
    if m.description:
        out["description"] = m.description
    if m.fs_hz is not None:
        out["fs_hz"] = m.fs_hz
    if m.dof_names:
        out["dofs"] = list(m.dof_names)
    out.update(masses_kg=list(m.masses_kg), stiffness_n_per_m=list(m.stiffness_n_per_m),
               damping=damp, input=inp, outputs=outs, elements=elems,
               **({"links": links} if links else {}),
               simulation={"substeps": m.substeps, "input_interpolation": m.interpolation,
                           "oversample": m.oversample,
                           **({"daq_filter": dataclasses.asdict(m.daq_filter)}
                              if m.daq_filter else {})})
    return out


def save(m: Model, path: Path | str) -> None:
    """Write the model in dynval's format (YAML for a .yaml/.yml suffix, else JSON)."""
    p = Path(path)
    d = to_dict(m)
    if p.suffix.lower() in (".yaml", ".yml"):
        p.write_text(_yaml().safe_dump(d, sort_keys=False), encoding="utf-8")
    else:
        p.write_text(json.dumps(d, indent=1) + "\n", encoding="utf-8")


