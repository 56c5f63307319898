"""Lumped-mass chain models (report Section 4.1): a declarative file, validation, and simulation
through the C core's model and observer (dv_model, dv_obs) — the code the firmware runs.

Two file layouts are read (JSON, or YAML with a .yaml/.yml suffix):

* dynval's own model file, ``"format": "dynval-model/1"`` (gateway/docs/model-format.md);
* the ``declared_model.json`` layout of the shared test data (``masses_kg``,
  ``story_stiffness_N_per_m`` {k1..kn}, ``damping``, ``input``, ``outputs``, ``fs_Hz``).

Numbering in files and in this module's API is 1-based like the report: DOF 1..n, story k1
ties DOF 1 to the ground, story ki ties DOF i-1 to DOF i, modes 1..n ascending, element i is
the i-th entry of ``elements``; DOF 0 (or "ground") is the ground.

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
import json
import logging
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynval._core import as_doubles, check, ffi, lib, ptr, status_name
from dynval.errors import ConfigError
from dynval.io.recording import Recording

log = logging.getLogger(__name__)

FORMAT = "dynval-model/1"

DAMPING_TYPES = ("modal", "rayleigh", "matrix")
INPUT_KINDS = ("force", "ground_acc", "ground_disp")
OUTPUT_KINDS = ("acc", "vel", "disp", "story_force", "contact_force", "reaction")
SIDES = ("pos", "neg", "both")
ELEMENT_TYPES = ("contact", "friction", "cubic_spring", "vv_damper", "stick_slip")
INTERPOLATIONS = ("bandlimited", "foh", "cubic")

# Limits of the compiled core (dv_config.h); the struct arrays tell their sizes.
_PROBE = ffi.new("dv_model_desc_t *")
MAX_DOF = len(_PROBE.mass_kg)
MAX_OUT = len(_PROBE.out)
MAX_ELEM = len(_PROBE.elem)
MAX_SUB = 16  # DV_MAX_SUB default; the core has the last word (DV_EINVAL)
del _PROBE

_DAMP_C = {"modal": lib.DV_DAMP_MODAL, "rayleigh": lib.DV_DAMP_RAYLEIGH,
           "matrix": lib.DV_DAMP_MATRIX}
_INPUT_C = {"force": lib.DV_INPUT_FORCE, "ground_acc": lib.DV_INPUT_GROUND_ACC,
            "ground_disp": lib.DV_INPUT_GROUND_DISP}
_OUT_C = {"acc": lib.DV_OUT_ACC, "vel": lib.DV_OUT_VEL, "disp": lib.DV_OUT_DISP,
          "story_force": lib.DV_OUT_SPRING_FORCE, "contact_force": lib.DV_OUT_ELEM_FORCE,
          "reaction": lib.DV_OUT_REACTION}
_SIDE_C = {"pos": lib.DV_SIDE_POS, "neg": lib.DV_SIDE_NEG, "both": lib.DV_SIDE_BOTH}
_STATUS_HINT = {
    "DV_EUNSTABLE": "the damping matrix is not positive semi-definite, the discretisation is "
                    "not finite, or the sample period is too long for the contact stiffness "
                    "(raise simulation.substeps or oversample)",
    "DV_EINVAL": "a value is out of the core's range",
}


# ---------------------------------------------------------------------------------------------
# The model
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Damping:
    """Damping. type 'modal': zeta per mode (ascending frequency). type 'rayleigh': C = a M + b K,
    either from two modes (1-based ``modes``) and their ratios ``zeta``, or from ``alpha_per_s``
    and ``beta_s`` directly. type 'matrix': ``c_n_s_per_m``, n x n symmetric."""

    type: str = "modal"
    zeta: tuple[float, ...] = ()
    modes: tuple[int, ...] = ()
    alpha_per_s: float | None = None
    beta_s: float | None = None
    c_n_s_per_m: tuple[tuple[float, ...], ...] = ()


@dataclass(frozen=True)
class Input:
    """The measured input: a force at ``dof`` (1-based), or a ground acceleration/displacement.
    ``channel`` names the test's column (None: the recording's only input channel)."""

    kind: str = "force"
    dof: int = 1
    channel: str | None = None


@dataclass(frozen=True)
class Output:
    """One predicted channel. ``index``: DOF (acc/vel/disp, 1-based), story (story_force: story i
    is k_i), element (contact_force: 1-based into Model.elements); ignored for reaction. ``gain``:
    the sensor's gain (1 = calibrated); the prediction is gain x the model's quantity."""

    kind: str
    index: int = 0
    gain: float = 1.0  # sensor gain: the channel reads gain x the model's quantity (< 0: reversed)


@dataclass(frozen=True)
class Contact:
    """Bumper/gap element between ``dof_a`` and ``dof_b`` (1-based, dof_a = 0: ground),
    X = x_b - x_a. Force law (dv_model.h): s = X - gap; 0 for s <= 0, kB s^2 / (2 delta) for
    0 < s < delta, kB (s - delta/2) beyond; it pushes DOF a by +g and DOF b by -g. side 'neg'
    mirrors it (X < -gap), 'both' is the sum."""

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
    """Regularised Coulomb friction between ``dof_a`` (0: ground) and ``dof_b`` on the relative
    velocity V = v_b - v_a (dv_model.h DV_ELEM_FRICTION): g = F V / sqrt(V^2 + eps^2), F =
    ``force_n`` (slip force, N), eps = ``v_eps_m_per_s`` (> 0); +g on DOF a, -g on DOF b."""

    dof_a: int
    dof_b: int
    force_n: float
    v_eps_m_per_s: float
    name: str = ""
    type: str = "friction"


@dataclass(frozen=True)
class CubicSpring:
    """Cubic spring g = k3 X^3 on X = x_b - x_a (DV_ELEM_CUBIC), k3 = ``k3_n_per_m3`` >= 0."""

    dof_a: int
    dof_b: int
    k3_n_per_m3: float
    name: str = ""
    type: str = "cubic_spring"


@dataclass(frozen=True)
class VVDamper:
    """Velocity-squared damper g = c2 V |V| on V = v_b - v_a (DV_ELEM_VV), c2 =
    ``c2_n_s2_per_m2`` >= 0."""

    dof_a: int
    dof_b: int
    c2_n_s2_per_m2: float
    name: str = ""
    type: str = "vv_damper"


@dataclass(frozen=True)
class StickSlip:
    """Elasto-plastic (Jenkins) friction on X = x_b - x_a (DV_ELEM_STICKSLIP): a stick spring
    of stiffness F / z in series with a slider at F = ``force_n`` (N), z = ``slip_m`` (> 0, the
    stick displacement before slip); rate-independent hysteresis, history kept by the core."""

    dof_a: int
    dof_b: int
    force_n: float
    slip_m: float
    name: str = ""
    type: str = "stick_slip"


Element = Contact | Friction | CubicSpring | VVDamper | StickSlip

# per element type: (parameter attribute, field of dv_elem_desc_t)
_ELEM_PARAMS: dict[str, tuple[tuple[str, str], ...]] = {
    "contact": (("gap_m", "gap_m"), ("delta_m", "delta_m"), ("kb_n_per_m", "kb_n_per_m")),
    "friction": (("force_n", "kb_n_per_m"), ("v_eps_m_per_s", "delta_m")),
    "cubic_spring": (("k3_n_per_m3", "kb_n_per_m"),),
    "vv_damper": (("c2_n_s2_per_m2", "kb_n_per_m"),),
    "stick_slip": (("force_n", "kb_n_per_m"), ("slip_m", "delta_m")),
}
_ELEM_LAW = {"contact": "DV_ELEM_CONTACT", "friction": "DV_ELEM_FRICTION",
             "cubic_spring": "DV_ELEM_CUBIC", "vv_damper": "DV_ELEM_VV",
             "stick_slip": "DV_ELEM_STICKSLIP"}


@dataclass(frozen=True)
class Model:
    """A chain of lumped masses with story springs, damping, one input, named outputs and
    nonlinear elements. Build it from a file with load(), or directly."""

    masses_kg: tuple[float, ...]
    stiffness_n_per_m: tuple[float, ...]
    damping: Damping
    input: Input
    outputs: Mapping[str, Output]
    elements: tuple[Element, ...] = ()
    substeps: int = 8
    oversample: int = 4
    interpolation: str = "bandlimited"
    fs_hz: float | None = None
    name: str = ""
    description: str = ""
    dof_names: tuple[str, ...] = ()
    source: str = field(default="", compare=False)

    @property
    def n_dof(self) -> int:
        return len(self.masses_kg)

    @property
    def channels(self) -> list[str]:
        return list(self.outputs)

    @property
    def contacts(self) -> list[Contact]:
        return [e for e in self.elements if isinstance(e, Contact)]

    def parameters(self) -> dict[str, float]:
        """The model's scalar parameters by name (see with_params)."""
        p: dict[str, float] = {}
        for i, m in enumerate(self.masses_kg, 1):
            p[f"m{i}"] = m
        for i, k in enumerate(self.stiffness_n_per_m, 1):
            p[f"k{i}"] = k
        d = self.damping
        if d.type == "modal" or (d.type == "rayleigh" and d.modes):
            for i, z in enumerate(d.zeta, 1):
                p[f"zeta{i}"] = z
        elif d.type == "rayleigh":
            p["alpha"] = float(d.alpha_per_s or 0.0)
            p["beta"] = float(d.beta_s or 0.0)
        for i, e in enumerate(self.elements, 1):
            for attr, _ in _ELEM_PARAMS[e.type]:
                p[f"e{i}.{attr}"] = float(getattr(e, attr))
        return p

    def with_params(self, params: Mapping[str, float]) -> Model:
        """A copy with parameters replaced: m<i>, k<i>, zeta<i> (modal ratio of mode i, or the
        i-th of the two Rayleigh ratios), alpha, beta (Rayleigh a, b), e<i>.<parameter> of
        element i (contact: gap_m, delta_m, kb_n_per_m; friction: force_n, v_eps_m_per_s;
        cubic_spring: k3_n_per_m3; vv_damper: c2_n_s2_per_m2). The copy is validated."""
        masses = list(self.masses_kg)
        ks = list(self.stiffness_n_per_m)
        zeta = list(self.damping.zeta)
        damp = self.damping
        elems = list(self.elements)
        for name, value in params.items():
            v = float(value)
            idx, attr = _param_target(name, self)
            if attr == "m":
                masses[idx] = v
            elif attr == "k":
                ks[idx] = v
            elif attr == "zeta":
                zeta[idx] = v
            elif attr == "alpha":
                damp = dataclasses.replace(damp, alpha_per_s=v)
            elif attr == "beta":
                damp = dataclasses.replace(damp, beta_s=v)
            else:  # an element parameter (checked against its type by _param_target)
                upd: dict[str, Any] = {attr: v}
                elems[idx] = dataclasses.replace(elems[idx], **upd)
        if zeta:
            damp = dataclasses.replace(damp, zeta=tuple(zeta))
        m = dataclasses.replace(self, masses_kg=tuple(masses), stiffness_n_per_m=tuple(ks),
                                damping=damp, elements=tuple(elems))
        validate(m)
        return m


_PARAM = re.compile(r"^(?:(m|k|zeta)(\d+)|(alpha|beta)|e(\d+)\.([a-z0-9_]+))$")


def _param_target(name: str, m: Model) -> tuple[int, str]:
    g = _PARAM.match(name)
    if g is None:
        raise ConfigError(f"unknown model parameter '{name}' (known: "
                          f"{', '.join(m.parameters())})")
    if g.group(3):
        if m.damping.type != "rayleigh" or m.damping.modes:
            raise ConfigError(f"parameter '{name}' needs damping type rayleigh with "
                              "alpha_per_s/beta_s")
        return 0, g.group(3)
    if g.group(1):
        i = int(g.group(2)) - 1
        n = len(m.damping.zeta) if g.group(1) == "zeta" else m.n_dof
        if not 0 <= i < n:
            raise ConfigError(f"parameter '{name}': index out of range 1..{n}")
        return i, g.group(1)
    i = int(g.group(4)) - 1
    if not 0 <= i < len(m.elements):
        raise ConfigError(f"parameter '{name}': the model has {len(m.elements)} elements")
    known = [a for a, _ in _ELEM_PARAMS[m.elements[i].type]]
    if g.group(5) not in known:
        raise ConfigError(f"parameter '{name}': element {i + 1} ({m.elements[i].type}) has "
                          f"{', '.join(known)}")
    return i, g.group(5)


# ---------------------------------------------------------------------------------------------
# Reading, validating, writing
# ---------------------------------------------------------------------------------------------
class _Ctx:
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
            raise self.err(where, f"expected a number, got {v!r}")
        x = float(v)
        if not math.isfinite(x):
            raise self.err(where, f"must be finite, got {v!r}")
        return x

    def int_(self, v: Any, where: str) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            if isinstance(v, float) and v.is_integer():
                return int(v)
            raise self.err(where, f"expected an integer, got {v!r}")
        return int(v)

    def nums(self, v: Any, where: str) -> tuple[float, ...]:
        if not isinstance(v, (list, tuple)):
            raise self.err(where, f"expected a list of numbers, got {type(v).__name__}")
        return tuple(self.num(x, f"{where}[{i}]") for i, x in enumerate(v))

    def choice(self, v: Any, where: str, options: Sequence[str]) -> str:
        if v not in options:
            raise self.err(where, f"{v!r} is not one of {', '.join(options)}")
        return str(v)


def _yaml() -> Any:
    return importlib.import_module("yaml")  # PyYAML


def _read_mapping(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the model file: {exc.strerror or exc}") from exc
    if path.suffix.lower() in (".yaml", ".yml"):
        yaml = _yaml()
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a model file holds one object, found {type(data).__name__}")
    return data


def load(path: Path | str) -> Model:
    """Read a model file (dynval's format or the declared_model.json layout) and validate it."""
    p = Path(path)
    return from_dict(_read_mapping(p), source=str(p))


def from_dict(d: Mapping[str, Any], source: str = "") -> Model:
    """Build and validate a model from a parsed file (either layout)."""
    ctx = _Ctx(source)
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


def _damping(d: Any, ctx: _Ctx, where: str) -> Damping:
    t = ctx.choice(ctx.get(d, "type", where), f"{where}.type", DAMPING_TYPES)
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
    modes = ctx.get(src, "modes", w) if "modes" in src else ctx.get(src, "mode", w)
    if not isinstance(modes, (list, tuple)):
        raise ctx.err(f"{w}.modes", "expected two mode numbers")
    mm = tuple(ctx.int_(x, f"{w}.modes[{i}]") for i, x in enumerate(modes))
    return Damping("rayleigh", modes=mm, zeta=ctx.nums(ctx.get(src, "zeta", w), f"{w}.zeta"))


def _dof(v: Any, ctx: _Ctx, where: str) -> int:
    if v == "ground":
        return 0
    return ctx.int_(v, where)


def _from_dynval(d: Mapping[str, Any], ctx: _Ctx) -> Model:
    masses = ctx.nums(ctx.get(d, "masses_kg", ""), "masses_kg")
    ks = ctx.nums(ctx.get(d, "stiffness_n_per_m", ""), "stiffness_n_per_m")
    damp = _damping(ctx.get(d, "damping", ""), ctx, "damping")
    di = ctx.get(d, "input", "")
    kind = ctx.choice(ctx.get(di, "kind", "input"), "input.kind", INPUT_KINDS)
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
        key = {"acc": "dof", "vel": "dof", "disp": "dof", "story_force": "story",
               "contact_force": "element"}.get(ok)
        outs[str(name)] = Output(ok, ctx.int_(ctx.get(o, key, w), f"{w}.{key}") if key else 0,
                                 gain=ctx.num(o.get("gain", 1.0), f"{w}.gain"))
    elems: list[Element] = []
    er = d.get("elements", [])
    if not isinstance(er, (list, tuple)):
        raise ctx.err("elements", "expected a list of elements")
    for i, e in enumerate(er):
        w = f"elements[{i}]"
        t = ctx.choice(ctx.get(e, "type", w), f"{w}.type", ELEMENT_TYPES)
        if t == "contact":
            btw = ctx.get(e, "between", w)
            if not isinstance(btw, (list, tuple)) or len(btw) != 2:
                raise ctx.err(f"{w}.between", "expected two DOFs [a, b] (a may be \"ground\")")
            elems.append(Contact(
                dof_a=_dof(btw[0], ctx, f"{w}.between[0]"),
                dof_b=_dof(btw[1], ctx, f"{w}.between[1]"),
                gap_m=ctx.num(ctx.get(e, "gap_m", w), f"{w}.gap_m"),
                delta_m=ctx.num(e.get("delta_m", 0.0), f"{w}.delta_m"),
                kb_n_per_m=ctx.num(ctx.get(e, "kb_n_per_m", w), f"{w}.kb_n_per_m"),
                side=ctx.choice(e.get("side", "pos"), f"{w}.side", SIDES),
                name=str(e.get("name", ""))))
        else:
            btw = ctx.get(e, "between", w)
            if not isinstance(btw, (list, tuple)) or len(btw) != 2:
                raise ctx.err(f"{w}.between", "expected two DOFs [a, b] (a may be \"ground\")")
            a_, b_ = _dof(btw[0], ctx, f"{w}.between[0]"), _dof(btw[1], ctx, f"{w}.between[1]")
            vals = {attr: ctx.num(ctx.get(e, attr, w), f"{w}.{attr}")
                    for attr, _ in _ELEM_PARAMS[t]}
            nm = str(e.get("name", ""))
            if t == "friction":
                elems.append(Friction(a_, b_, vals["force_n"], vals["v_eps_m_per_s"], nm))
            elif t == "cubic_spring":
                elems.append(CubicSpring(a_, b_, vals["k3_n_per_m3"], nm))
            elif t == "stick_slip":
                elems.append(StickSlip(a_, b_, vals["force_n"], vals["slip_m"], nm))
            else:
                elems.append(VVDamper(a_, b_, vals["c2_n_s2_per_m2"], nm))
    sim = d.get("simulation", {})
    if not isinstance(sim, Mapping):
        raise ctx.err("simulation", "expected an object")
    fs = d.get("fs_hz")
    names = d.get("dofs", ())
    return Model(
        masses_kg=masses, stiffness_n_per_m=ks, damping=damp,
        input=Input(kind, dof, ch), outputs=outs, elements=tuple(elems),
        substeps=ctx.int_(sim.get("substeps", 8), "simulation.substeps"),
        oversample=ctx.int_(sim.get("oversample", 4), "simulation.oversample"),
        interpolation=ctx.choice(sim.get("input_interpolation", "bandlimited"),
                                 "simulation.input_interpolation", INTERPOLATIONS),
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


def _from_declared(d: Mapping[str, Any], ctx: _Ctx) -> Model:
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


def validate(m: Model, ctx: _Ctx | None = None) -> None:
    """Check a model for physical sense and the core's limits; ConfigError names the field."""
    c = ctx or _Ctx(m.source)
    n = m.n_dof
    if not 1 <= n <= MAX_DOF:
        raise c.err("masses_kg", f"{n} DOFs; this core supports 1..{MAX_DOF}")
    for i, v in enumerate(m.masses_kg):
        if not (math.isfinite(v) and v > 0):
            raise c.err(f"masses_kg[{i}]", f"mass of DOF {i + 1} must be > 0 kg, got {v!r}")
    if len(m.stiffness_n_per_m) != n:
        raise c.err("stiffness_n_per_m", f"expected {n} story stiffnesses (k1 ground-DOF1, "
                    f"k2 DOF1-DOF2, ...), got {len(m.stiffness_n_per_m)}")
    for i, v in enumerate(m.stiffness_n_per_m):
        if not (math.isfinite(v) and v >= 0):
            raise c.err(f"stiffness_n_per_m[{i}]", f"k{i + 1} must be >= 0 N/m, got {v!r}")
    if any(k == 0 for k in m.stiffness_n_per_m[1:]):
        log.warning("%s: a story stiffness k2..kn is 0: the chain falls apart", c.source)
    d = m.damping
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
        cm = np.asarray(d.c_n_s_per_m, dtype=float) if d.c_n_s_per_m else np.zeros((0, 0))
        if cm.shape != (n, n):
            raise c.err("damping.c_n_s_per_m", f"expected {n} x {n}, got {cm.shape}")
        if not np.allclose(cm, cm.T, rtol=1e-12, atol=0.0):
            raise c.err("damping.c_n_s_per_m", "must be symmetric")
    else:
        raise c.err("damping.type", f"{d.type!r} is not one of {', '.join(DAMPING_TYPES)}")
    if m.input.kind not in INPUT_KINDS:
        raise c.err("input.kind", f"{m.input.kind!r} is not one of {', '.join(INPUT_KINDS)}")
    if m.input.kind == "force" and not 1 <= m.input.dof <= n:
        raise c.err("input.dof", f"DOF {m.input.dof} out of range 1..{n}")
    if not 1 <= len(m.outputs) <= MAX_OUT:
        raise c.err("outputs", f"{len(m.outputs)} outputs; need 1..{MAX_OUT}")
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
    if len(m.elements) > MAX_ELEM:
        raise c.err("elements", f"{len(m.elements)} elements; this core supports {MAX_ELEM}")
    for i, e in enumerate(m.elements):
        w = f"elements[{i}]"
        if not isinstance(e, Contact):
            if not 0 <= e.dof_a <= n or not 1 <= e.dof_b <= n or e.dof_a == e.dof_b:
                raise c.err(f"{w}.between", f"[{e.dof_a}, {e.dof_b}]: DOFs in 1..{n} (the first "
                            "may be 0 = ground), different")
            for attr, _ in _ELEM_PARAMS[e.type]:
                v = float(getattr(e, attr))
                if not (math.isfinite(v) and v >= 0):
                    raise c.err(f"{w}.{attr}", f"must be >= 0, got {v!r}")
            if isinstance(e, Friction) and not e.v_eps_m_per_s > 0:
                raise c.err(f"{w}.v_eps_m_per_s", "must be > 0 (the regularisation)")
            if isinstance(e, StickSlip) and not e.slip_m > 0:
                raise c.err(f"{w}.slip_m", "must be > 0 (the stick displacement)")
        if isinstance(e, Contact):
            if not 0 <= e.dof_a <= n or not 1 <= e.dof_b <= n or e.dof_a == e.dof_b:
                raise c.err(f"{w}.between", f"[{e.dof_a}, {e.dof_b}]: DOFs in 1..{n} (the first "
                            "may be 0 = ground), different")
            for attr in ("gap_m", "delta_m", "kb_n_per_m"):
                v = getattr(e, attr)
                if not (math.isfinite(v) and v >= 0):
                    raise c.err(f"{w}.{attr}", f"must be >= 0, got {v!r}")
            if e.side not in SIDES:
                raise c.err(f"{w}.side", f"{e.side!r} is not one of {', '.join(SIDES)}")
    if not 1 <= m.substeps <= MAX_SUB:
        raise c.err("simulation.substeps", f"must be 1..{MAX_SUB}, got {m.substeps}")
    if not 1 <= m.oversample <= 64:
        raise c.err("simulation.oversample", f"must be 1..64, got {m.oversample}")
    if m.interpolation not in INTERPOLATIONS:
        raise c.err("simulation.input_interpolation", f"{m.interpolation!r} is not one of "
                    f"{', '.join(INTERPOLATIONS)}")
    if m.fs_hz is not None and not m.fs_hz > 0:
        raise c.err("fs_hz", f"must be > 0, got {m.fs_hz!r}")


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
        key = {"acc": "dof", "vel": "dof", "disp": "dof", "story_force": "story",
               "contact_force": "element"}.get(o.kind)
        outs[name] = {"kind": o.kind, key: o.index} if key else {"kind": o.kind}
        if o.gain != 1.0:
            outs[name]["gain"] = o.gain
    elems: list[dict[str, Any]] = []
    for e in m.elements:
        ed: dict[str, Any] = {"type": e.type}
        if e.name:
            ed["name"] = e.name
        ed["between"] = ["ground" if e.dof_a == 0 else e.dof_a, e.dof_b]
        if isinstance(e, Contact):
            ed["side"] = e.side
        for attr, _ in _ELEM_PARAMS[e.type]:
            ed[attr] = getattr(e, attr)
        elems.append(ed)
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
               simulation={"substeps": m.substeps, "input_interpolation": m.interpolation,
                           "oversample": m.oversample})
    return out


def save(m: Model, path: Path | str) -> None:
    """Write the model in dynval's format (YAML for a .yaml/.yml suffix, else JSON)."""
    p = Path(path)
    d = to_dict(m)
    if p.suffix.lower() in (".yaml", ".yml"):
        p.write_text(_yaml().safe_dump(d, sort_keys=False), encoding="utf-8")
    else:
        p.write_text(json.dumps(d, indent=1) + "\n", encoding="utf-8")


# ---------------------------------------------------------------------------------------------
# The C model
# ---------------------------------------------------------------------------------------------
def _fill_desc(desc: Any, m: Model) -> None:
    """Write m into a dv_model_desc_t (0-based indices)."""
    check(lib.dv_model_desc_default(desc), "dv_model_desc_default")
    n = m.n_dof
    desc.n_dof = n
    for i in range(n):
        desc.mass_kg[i] = m.masses_kg[i]
        desc.k_n_per_m[i] = m.stiffness_n_per_m[i]
    d = m.damping
    if d.type == "modal":
        desc.damp_kind = lib.DV_DAMP_MODAL
        for i in range(n):
            desc.zeta[i] = d.zeta[i]
    elif d.type == "rayleigh" and d.modes:
        desc.damp_kind = lib.DV_DAMP_RAYLEIGH
        for j in range(2):
            desc.rayleigh_mode[j] = d.modes[j] - 1
            desc.rayleigh_zeta[j] = d.zeta[j]
    else:
        desc.damp_kind = lib.DV_DAMP_MATRIX
        cm = damping_matrix_explicit(m)
        for i in range(n):
            for j in range(n):
                desc.c_n_s_per_m[i * n + j] = float(cm[i, j])
    desc.input_kind = _INPUT_C[m.input.kind]
    desc.input_dof = max(m.input.dof - 1, 0)
    cs = list(m.elements)
    desc.n_elem = len(cs)
    for i, e in enumerate(cs):
        c = desc.elem[i]
        c.dof_a = lib.DV_GROUND if e.dof_a == 0 else e.dof_a - 1
        c.dof_b = e.dof_b - 1
        c.side = _SIDE_C[e.side] if isinstance(e, Contact) else lib.DV_SIDE_POS
        c.gap_m = 0.0
        c.delta_m = 0.0
        c.law = getattr(lib, _ELEM_LAW[e.type])
        for attr, fld in _ELEM_PARAMS[e.type]:
            setattr(c, fld, float(getattr(e, attr)))
    desc.n_sub = m.substeps if cs else 1
    desc.input_hold = lib.DV_HOLD_CUBIC if m.interpolation == "cubic" else lib.DV_HOLD_FOH
    cidx = {id(e): i for i, e in enumerate(cs)}
    desc.n_out = len(m.outputs)
    for j, o in enumerate(m.outputs.values()):
        desc.out[j].kind = _OUT_C[o.kind]
        if o.kind == "contact_force":
            desc.out[j].index = cidx[id(m.elements[o.index - 1])]
        elif o.kind == "reaction":
            desc.out[j].index = 0
        else:
            desc.out[j].index = o.index - 1


def damping_matrix_explicit(m: Model) -> np.ndarray:
    """C for the types the core does not build itself (matrix; Rayleigh from alpha, beta)."""
    d = m.damping
    if d.type == "matrix":
        return np.asarray(d.c_n_s_per_m, dtype=np.float64)
    if d.type == "rayleigh" and not d.modes:
        return float(d.alpha_per_s or 0.0) * np.diag(m.masses_kg) + float(
            d.beta_s or 0.0) * stiffness_matrix(m)
    raise ConfigError("the core builds modal and mode-based Rayleigh damping itself")


def stiffness_matrix(m: Model) -> np.ndarray:
    """K of the chain (eq. 2), N/m."""
    n = m.n_dof
    k = np.zeros((n, n))
    ks = m.stiffness_n_per_m
    for i in range(n):
        k[i, i] += ks[i]
        if i + 1 < n:
            k[i, i] += ks[i + 1]
            k[i, i + 1] = k[i + 1, i] = -ks[i + 1]
    return k


class _Core:
    """A C model + open-loop observer with their buffers, reusable for many parameter sets."""

    def __init__(self, m: Model, dt_s: float) -> None:
        self.dt = dt_s
        self.desc = ffi.new("dv_model_desc_t *")
        self.cm = ffi.new("dv_model_t *")
        self.obs = ffi.new("dv_obs_t *")
        self.no = len(m.outputs)
        _fill_desc(self.desc, m)
        self.mlen = int(lib.dv_model_buf_len(self.desc))
        if self.mlen == 0:
            raise ConfigError(f"{m.source or '<model>'}: the core refused the model's sizes")
        self.mbuf = np.zeros(self.mlen)
        self.mptr = ptr(self.mbuf)
        self.olen = 0
        self.obuf = np.zeros(0)
        self.optr: Any = None

    def build(self, m: Model, refill: bool = True) -> None:
        if refill:
            _fill_desc(self.desc, m)
        st = lib.dv_model_init(self.cm, self.desc, self.dt, self.mptr, self.mlen)
        if st < 0:
            raise _refused(m, "dv_model_init", st, self.dt)
        olen = int(lib.dv_obs_buf_len(self.cm))
        if olen > self.olen:
            self.olen = olen
            self.obuf = np.zeros(olen)
            self.optr = ptr(self.obuf)
        st = lib.dv_obs_init(self.obs, self.cm, ffi.NULL, self.optr, self.olen)
        if st < 0:
            raise _refused(m, "dv_obs_init", st, self.dt)

    def run(self, u: np.ndarray, y: np.ndarray) -> int:
        """Simulate from rest into y (n x no, C-contiguous); returns the core's status."""
        return int(lib.dv_obs_simulate(self.obs, ptr(u), u.size, ptr(y)))


def _refused(m: Model, func: str, status: int, dt: float) -> ConfigError:
    name = status_name(status)
    hint = _STATUS_HINT.get(name, "")
    return ConfigError(f"{m.source or '<model>'}: the core refused the model ({func}: {name}"
                       f"{'; ' + hint if hint else ''}; sample period {dt:g} s)")


def modes(m: Model) -> tuple[np.ndarray, np.ndarray]:
    """Undamped natural frequencies (Hz, ascending) and mass-normalised mode shapes
    (column k = mode k+1), by the C core's eigen-solution."""
    lin = dataclasses.replace(m, elements=(), outputs={"a": Output("acc", 1)})
    core = _Core(lin, 1e-4)
    st = lib.dv_model_init(core.cm, core.desc, core.dt, core.mptr, core.mlen)
    if st < 0:
        raise _refused(m, "dv_model_init", st, core.dt)
    n = m.n_dof
    f = np.zeros(n)
    phi = np.zeros(n * n)
    check(lib.dv_model_get_modes(core.cm, ptr(f), ptr(phi), n * n), "dv_model_get_modes")
    return f, phi.reshape(n, n)


def natural_frequencies(m: Model) -> np.ndarray:
    """Undamped natural frequencies of the linear chain, Hz, ascending (contacts open)."""
    return modes(m)[0]


def _resolve_oversample(m: Model, oversample: int | None) -> int:
    r = m.oversample if oversample is None else int(oversample)
    if m.interpolation in ("foh", "cubic") and oversample is None:
        r = 1
    if not 1 <= r <= 64:
        raise ConfigError(f"oversample must be 1..64, got {r}")
    return r


def interpolate_input(u: np.ndarray, r: int) -> np.ndarray:
    """Band-limited interpolation by r (zeros before the first sample: the structure starts at
    rest; zeros padded after the last so its tail is not cut by the filter)."""
    if r == 1:
        return as_doubles(u)
    pad = np.concatenate([as_doubles(u), np.zeros(32)])
    resample_poly = importlib.import_module("scipy.signal").resample_poly
    return np.ascontiguousarray(resample_poly(pad, r, 1)[: u.size * r])


def _prepare_input(u: Any, r: int) -> np.ndarray:
    a = as_doubles(u)
    if a.size == 0:
        raise ConfigError("the input record is empty")
    if r > 1 and not np.all(np.isfinite(a)):
        bad = int(np.count_nonzero(~np.isfinite(a)))
        raise ConfigError(f"the input has {bad} non-finite samples: band-limited interpolation "
                          "needs a complete record (use oversample=1 to let the core hold)")
    return interpolate_input(a, r)


def simulate(m: Model, force_or_motion: Any, fs_hz: float, *,
             oversample: int | None = None) -> dict[str, np.ndarray]:
    """Predicted outputs (channel -> array) of the model driven from rest by the sampled input,
    through the C core (dv_model_init, dv_obs_init open loop, dv_obs_simulate). oversample:
    band-limited interpolation factor (None: the model's; 1: the samples as they are)."""
    if not fs_hz > 0:
        raise ConfigError(f"fs_hz must be > 0, got {fs_hz!r}")
    r = _resolve_oversample(m, oversample)
    u = _prepare_input(force_or_motion, r)
    core = _Core(m, 1.0 / (fs_hz * r))
    core.build(m, refill=False)
    y = np.empty((u.size, core.no))
    st = core.run(u, y)
    if st < 0:
        bad = int(core.obs.n_bad_input)
        if st == lib.DV_ENUMERIC:
            log.warning("%d non-finite input samples: the core held the state there", bad)
        else:
            check(st, "dv_obs_simulate")
    y = y[::r]
    return {name: np.ascontiguousarray(y[:, j]) * o.gain if o.gain != 1.0 else
            np.ascontiguousarray(y[:, j]) for j, (name, o) in enumerate(m.outputs.items())}


def simulate_batch(m: Model, force_or_motion: Any, fs_hz: float,
                   param_sets: Sequence[Mapping[str, float]], *, oversample: int | None = None,
                   on_progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Simulate many parameter variants (Model.with_params names: m1, k2, zeta3, e1.gap_m, ...)
    of one model for one input. Returns an array (n_sets, n_samples, n_outputs), outputs in
    the order of m.channels. The input is interpolated once; each run rebuilds only the C
    model and observer in preallocated buffers."""
    if not fs_hz > 0:
        raise ConfigError(f"fs_hz must be > 0, got {fs_hz!r}")
    r = _resolve_oversample(m, oversample)
    u = _prepare_input(force_or_motion, r)
    n = u.size // r
    core = _Core(m, 1.0 / (fs_hz * r))
    base = ffi.new("dv_model_desc_t *")
    _fill_desc(base, m)
    size = ffi.sizeof("dv_model_desc_t")
    setters = _desc_setters(m)
    out = np.empty((len(param_sets), n, core.no))
    work = np.empty((u.size, core.no)) if r > 1 else None
    for i, ps in enumerate(param_sets):
        ffi.memmove(core.desc, base, size)
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
        if work is None:
            y = out[i]
            st = core.run(u, y)
        else:
            st = core.run(u, work)
            out[i] = work[::r]
        if st < 0 and st != lib.DV_ENUMERIC:
            check(st, "dv_obs_simulate")
        if on_progress is not None:
            on_progress(i + 1, len(param_sets))
    gains = np.array([o.gain for o in m.outputs.values()])
    if np.any(gains != 1.0):
        out *= gains
    return out


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
    for i, e in enumerate(m.elements):
        for attr, fld in _ELEM_PARAMS[e.type]:
            s[f"e{i + 1}.{attr}"] = con(i, fld)
    if m.damping.type == "rayleigh" and not m.damping.modes:
        # masses and stiffnesses also enter C = a M + b K: recompute C in Python for them
        s = {k: v for k, v in s.items() if not re.match(r"^[mk]\d+$", k)}
    return s


# ---------------------------------------------------------------------------------------------
# Residuals
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ChannelResidual:
    """measured - predicted of one channel; rmse over finite samples; nrmse = rmse / rms of
    the measured channel (NaN when that is 0)."""

    residual: np.ndarray
    rmse: float
    nrmse: float
    rms_measured: float


@dataclass(frozen=True)
class ResidualResult:
    test: str
    fs_hz: float
    n_samples: int
    channels: dict[str, ChannelResidual]
    predicted: dict[str, np.ndarray]

    def summary(self) -> dict[str, Any]:
        return {"test": self.test, "fs_hz": self.fs_hz, "n_samples": self.n_samples,
                "channels": {k: {"rmse": c.rmse, "nrmse": c.nrmse, "rms_measured": c.rms_measured}
                             for k, c in self.channels.items()}}


def input_channel(m: Model, rec: Recording) -> str:
    """The recording's column that drives the model."""
    if m.input.channel is not None:
        if m.input.channel not in rec.names:
            raise ConfigError(f"{rec.source or rec.name}: no input column '{m.input.channel}' "
                              f"required by the model {m.source} (columns: "
                              f"{', '.join(rec.names)})")
        return m.input.channel
    ins = [c.name for c in rec.channels if c.role == "input"]
    if len(ins) != 1:
        raise ConfigError(f"{rec.source or rec.name}: cannot tell the input column (candidates: "
                          f"{', '.join(ins) or 'none'}); name it in the model's input.channel")
    return ins[0]


def _check_fs(m: Model, rec: Recording) -> None:
    if m.fs_hz is not None and abs(m.fs_hz - rec.fs_hz) > 1e-6 * m.fs_hz:
        log.warning("%s: sampled at %g Hz, the model %s declares %g Hz; simulating at the "
                    "test's rate", rec.name, rec.fs_hz, m.source, m.fs_hz)


def simulate_recording(m: Model, rec: Recording, *,
                       oversample: int | None = None) -> dict[str, np.ndarray]:
    """The model's prediction for a recorded test's measured input."""
    _check_fs(m, rec)
    return simulate(m, rec.channel(input_channel(m, rec)).data, rec.fs_hz, oversample=oversample)


def residual(m: Model, rec: Recording, *, oversample: int | None = None) -> ResidualResult:
    """measured - predicted for every model output the recording also has, with RMSE and
    NRMSE (RMSE / RMS of the measured channel)."""
    common = [c for c in m.outputs if c in rec.names]
    if not common:
        raise ConfigError(f"{rec.source or rec.name}: none of the model's outputs "
                          f"({', '.join(m.outputs)}) is a column of the test "
                          f"({', '.join(rec.names)})")
    missing = [c for c in m.outputs if c not in rec.names]
    if missing:
        log.info("%s: the test lacks the model outputs %s", rec.name, ", ".join(missing))
    pred = simulate_recording(m, rec, oversample=oversample)
    chans: dict[str, ChannelResidual] = {}
    for c in common:
        y = rec.channel(c).data
        e = y - pred[c]
        ok = np.isfinite(e)
        rmse = float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else math.nan
        rms = float(np.sqrt(np.mean(y[ok] ** 2))) if ok.any() else math.nan
        chans[c] = ChannelResidual(e, rmse, rmse / rms if rms > 0 else math.nan, rms)
    return ResidualResult(rec.name, rec.fs_hz, rec.n_samples, chans, pred)
