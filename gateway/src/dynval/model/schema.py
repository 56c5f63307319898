"""The model's data: a chain of lumped masses with story springs, linear links off the chain,
damping, one input, named outputs and nonlinear elements (model/elements.py), and its scalar
parameters by name.

Numbering is 1-based like the report: DOF 1..n, story k1 ties DOF 1 to the ground, story ki
ties DOF i-1 to DOF i, modes 1..n ascending, element i is the i-th entry of ``elements``; DOF
0 (or "ground") is the ground.
"""
from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval.errors import ConfigError
from dynval.model import elements as el
from dynval.model.elements import Element

FORMAT = "dynval-model/1"
DAMPING_TYPES = ("modal", "rayleigh", "matrix")
INPUT_KINDS = ("force", "ground_acc", "ground_disp")
OUTPUT_KINDS = ("acc", "vel", "disp", "story_force", "contact_force", "reaction")
INTERPOLATIONS = ("bandlimited", "foh", "cubic")
DAQ_FILTER_TYPES = ("butterworth", "bessel")  # analog low-passes (Bessel: -3 dB at cutoff)
MAX_DAQ_FILTER_ORDER = 12
# Every key a model file may hold, per kind of object: the one place to add a key (a key not
# listed here is an error with a "did you mean"). "declared" is the top level of the shared
# data's declared_model.json layout, whose informational keys are read and ignored.
MODEL_KEYS: dict[str, tuple[str, ...]] = {
    "model": ("format", "name", "description", "fs_hz", "dofs", "masses_kg",
              "stiffness_n_per_m", "damping", "input", "outputs", "elements", "links",
              "simulation"),
    "declared": ("name", "description", "units", "dofs", "masses_kg", "story_stiffness_N_per_m",
                 "K_matrix_N_per_m", "M_matrix_kg", "damping", "damping_alternative_in_report",
                 "natural_frequencies_Hz", "input", "outputs", "csv_columns", "fs_Hz", "fs_hz",
                 "n_samples"),
    "damping": ("type", "zeta", "modes", "mode", "alpha_per_s", "beta_s", "c_n_s_per_m",
                "C_matrix_N_s_per_m", "fitted_to", "definition", "note"),
    "fitted_to": ("modes", "mode", "zeta"),
    "input": ("kind", "dof", "channel", "sensor"),
    "output": ("kind", "dof", "story", "element", "index", "gain", "offset"),
    "element": ("type", "name", "between", "side"),  # + the parameters of its type
    "link": ("name", "between", "k_n_per_m", "c_n_s_per_m"),
    "simulation": ("substeps", "oversample", "input_interpolation", "daq_filter"),
    "daq_filter": ("type", "order", "cutoff_hz"),
}
# the file key that holds an output's index, per output kind (none for the reaction)
OUTPUT_INDEX_KEY = {"acc": "dof", "vel": "dof", "disp": "dof", "story_force": "story",
                    "contact_force": "element"}


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

    @property
    def explicit_rayleigh(self) -> bool:
        """Rayleigh from alpha_per_s and beta_s (the core does not build it itself)."""
        return self.type == "rayleigh" and not self.modes


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
    the sensor's gain (1 = calibrated) and ``offset`` (channel units): the prediction is
    gain x the model's quantity + offset."""

    kind: str
    index: int = 0
    gain: float = 1.0  # sensor gain: the channel reads gain x the model's quantity (< 0: reversed)
    offset: float = 0.0  # sensor offset, channel units: the channel reads gain x quantity + offset


@dataclass(frozen=True)
class Link:
    """A linear spring and dashpot between two DOFs off the chain (1-based, neither the
    ground): an appendage on its own DOF, a coupling of DOFs that are not neighbours."""

    dof_a: int
    dof_b: int
    k_n_per_m: float
    c_n_s_per_m: float = 0.0
    name: str = ""


LINK_PARAMS = {"k_n_per_m": "N/m", "c_n_s_per_m": "N s/m"}


@dataclass(frozen=True)
class DaqFilter:
    """The DAQ's analog anti-alias low-pass, the same on every channel (input and outputs):
    ``type`` butterworth or bessel, ``order`` 1..MAX_DAQ_FILTER_ORDER, ``cutoff_hz`` its -3 dB
    frequency. A model with a nonlinear element that declares it is driven by the measured
    input with the filter divided out in band and read through it (model/daq.py): the
    element's harmonics pass the filter on the rig, not in a simulation driven by the
    filtered input."""

    type: str
    order: int
    cutoff_hz: float


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
    links: tuple[Link, ...] = ()
    substeps: int = 8
    oversample: int = 4
    interpolation: str = "bandlimited"
    daq_filter: DaqFilter | None = None
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
        elif d.type == "matrix":
            for i, z in enumerate(matrix_ratios(self), 1):
                p[f"zeta{i}"] = z
        elif d.type == "rayleigh":
            p["alpha"] = float(d.alpha_per_s or 0.0)
            p["beta"] = float(d.beta_s or 0.0)
        for i, e in enumerate(self.elements, 1):
            for name, v in el.values(e).items():
                p[f"e{i}.{name}"] = v
        for i, lk in enumerate(self.links, 1):
            for name in LINK_PARAMS:
                p[f"l{i}.{name}"] = float(getattr(lk, name))
        if self.daq_filter is not None:
            p[DAQ_CUTOFF] = self.daq_filter.cutoff_hz
        return p

    def with_params(self, params: Mapping[str, float]) -> Model:
        """A copy with parameters replaced: m<i>, k<i>, zeta<i> (modal ratio of mode i, the
        i-th of the two Rayleigh ratios, or for a damping matrix mode i's ratio in it,
        matrix_ratios), alpha, beta (Rayleigh a, b), e<i>.<parameter> of
        element i (its registry parameters, model/elements.py), l<i>.k_n_per_m and
        l<i>.c_n_s_per_m of link i, daq.cutoff_hz of the DAQ filter. The copy is
        validated."""
        from dynval.model.validation import validate  # validation reads this schema

        lists: dict[str, list[Any]] = {"m": list(self.masses_kg),
                                       "k": list(self.stiffness_n_per_m),
                                       "zeta": list(self.damping.zeta), "e": list(self.elements),
                                       "l": list(self.links)}
        damp, daq = self.damping, self.daq_filter
        ratios: dict[int, float] = {}  # of a damping matrix: set on the new modes below
        for name, value in params.items():
            v = float(value)
            idx, attr = param_target(name, self)
            if attr == "zeta" and damp.type == "matrix":
                ratios[idx] = v
                continue
            if attr in ("m", "k", "zeta"):
                lists[attr][idx] = v
            elif attr == "alpha":
                damp = dataclasses.replace(damp, alpha_per_s=v)
            elif attr == "beta":
                damp = dataclasses.replace(damp, beta_s=v)
            elif attr.startswith("link."):
                lists["l"][idx] = dataclasses.replace(lists["l"][idx], **{attr[5:]: v})
            elif attr == DAQ_CUTOFF and daq is not None:  # (param_target: it is)
                daq = dataclasses.replace(daq, cutoff_hz=v)
            else:  # an element parameter (checked against its type by param_target)
                upd: dict[str, Any] = {attr: v}
                lists["e"][idx] = dataclasses.replace(lists["e"][idx], **upd)
        if lists["zeta"]:
            damp = dataclasses.replace(damp, zeta=tuple(lists["zeta"]))
        m = dataclasses.replace(self, masses_kg=tuple(lists["m"]),
                                stiffness_n_per_m=tuple(lists["k"]), damping=damp,
                                elements=tuple(lists["e"]), links=tuple(lists["l"]),
                                daq_filter=daq)
        if ratios:  # on the modes of the new masses and stiffnesses (and links)
            m = dataclasses.replace(m, damping=with_matrix_ratios(m, ratios))
        validate(m)
        return m


_PARAM = re.compile(r"^(?:(m|k|zeta)(\d+)|(alpha|beta)|e(\d+)\.([a-z0-9_]+)|"
                    r"l(\d+)\.(k_n_per_m|c_n_s_per_m)|(daq\.cutoff_hz))$")
DAQ_CUTOFF = "daq.cutoff_hz"  # the declared DAQ filter's cutoff, Hz


def param_target(name: str, m: Model) -> tuple[int, str]:
    """(0-based index, attribute) a parameter name addresses: ('m'|'k'|'zeta', i),
    (0, 'alpha'|'beta'), (element index, its parameter name), (link index,
    'link.<parameter>') or (0, DAQ_CUTOFF); ConfigError otherwise."""
    g = _PARAM.match(name)
    if g is None:
        raise ConfigError(f"unknown model parameter '{name}' (known: "
                          f"{', '.join(m.parameters())})")
    if g.group(8):
        if m.daq_filter is None:
            raise ConfigError(f"parameter '{name}' needs a DAQ filter (simulation.daq_filter)")
        return 0, DAQ_CUTOFF
    if g.group(3):
        if not m.damping.explicit_rayleigh:
            raise ConfigError(f"parameter '{name}' needs damping type rayleigh with "
                              "alpha_per_s/beta_s")
        return 0, g.group(3)
    if g.group(1):
        i = int(g.group(2)) - 1
        n = len(m.damping.zeta) if g.group(1) == "zeta" and m.damping.type != "matrix" \
            else m.n_dof
        if not 0 <= i < n:
            raise ConfigError(f"parameter '{name}': index out of range 1..{n}")
        return i, g.group(1)
    if g.group(6):
        i = int(g.group(6)) - 1
        if not 0 <= i < len(m.links):
            raise ConfigError(f"parameter '{name}': the model has {len(m.links)} links")
        return i, "link." + g.group(7)
    i = int(g.group(4)) - 1
    if not 0 <= i < len(m.elements):
        raise ConfigError(f"parameter '{name}': the model has {len(m.elements)} elements")
    try:
        el.spec(m.elements[i]).param(g.group(5))
    except ConfigError as exc:
        raise ConfigError(f"parameter '{name}': element {i + 1}: {exc}") from None
    return i, g.group(5)


def matrix_ratios(m: Model) -> list[float]:
    """The damping ratio of each mode in a damping matrix C (type 'matrix'): phi' C phi /
    (2 w) on m's undamped modes (mass-normalised, links included; the links' own dashpots
    are theirs). A matrix kept fixed while the masses or stiffnesses change (an added mode,
    a stiffness loss) keeps its dissipation; these ratios let a later fit re-adjust it mode
    by mode. A rigid-body mode's ratio reads 0."""
    from dynval.model.simulation import linear  # the simulation reads this schema

    lin = linear(m)
    c = np.asarray(m.damping.c_n_s_per_m, dtype=float)
    return [float(ph @ c @ ph / (2 * w)) if w > 1e-6 else 0.0
            for w, ph in zip(lin.w, lin.phi.T, strict=True)]


def with_matrix_ratios(m: Model, ratios: Mapping[int, float]) -> Damping:
    """m's damping matrix with mode i's ratio (0-based keys, matrix_ratios) set: C + 2 dz w
    (M phi)(M phi)' per mode, which leaves the other modes' ratios as they are (the shapes
    are M-orthogonal). ConfigError for a rigid-body mode."""
    from dynval.model.simulation import linear  # the simulation reads this schema

    lin = linear(m)
    c = np.array(m.damping.c_n_s_per_m, dtype=float)
    for i, z in ratios.items():
        w, ph = float(lin.w[i]), lin.phi[:, i]
        if not w > 1e-6:
            raise ConfigError(f"zeta{i + 1}: mode {i + 1} is a rigid-body mode (no ratio)")
        mp = lin.mass * ph
        c = c + 2 * (z - float(ph @ c @ ph) / (2 * w)) * w * np.outer(mp, mp)
    return Damping("matrix", c_n_s_per_m=tuple(tuple(float(v) for v in row) for row in c))


_UNITS = {"m": "kg", "k": "N/m", "zeta": "1", "alpha": "1/s", "beta": "s", DAQ_CUTOFF: "Hz"}


def param_unit(name: str, m: Model) -> str:
    """The unit of a parameter name (element parameters: their registry unit)."""
    i, attr = param_target(name, m)
    if attr in _UNITS:
        return _UNITS[attr]
    if attr.startswith("link."):
        return LINK_PARAMS[attr[5:]]
    return el.spec(m.elements[i]).param(attr).unit
