"""Channel maps: which file columns become which channels, with name, unit, scale (file units
to channel units), role (input/output) and DOF (1-based, or none).

File (JSON or YAML)::

    {"channels": [
      {"column": "force_N", "name": "force", "unit": "N", "scale": 1.0, "role": "input", "dof": 1},
      {"column": "acc1", "unit": "m/s^2", "dof": 1}, ...]}

``column`` is a column name of the test or a 0-based column index; only listed columns are
kept (the others are reported). Without a map every column is kept with the reader's names,
units and roles, and DOF i for the i-th output (the three-story layout)."""
from __future__ import annotations

import dataclasses
import logging
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dynval.errors import ConfigError, InputFileError
from dynval.io.arrays import checked_unit
from dynval.io.jsonfile import read_mapping_file
from dynval.io.recording import Channel, Recording

log = logging.getLogger(__name__)

ROLES = ("input", "output")


@dataclass(frozen=True)
class ChannelSpec:
    column: str | int
    name: str | None = None
    unit: str | None = None
    scale: float = 1.0
    role: str | None = None
    dof: int | None = None


@dataclass(frozen=True)
class ChannelMap:
    channels: tuple[ChannelSpec, ...]
    source: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"channels": [dataclasses.asdict(c) for c in self.channels],
                "source": self.source}


def load_channel_map(path: Path | str) -> ChannelMap:
    p = Path(path)
    try:
        d = read_mapping_file(p)
    except InputFileError as exc:  # a channel map is configuration: the same line, ConfigError
        raise ConfigError(f"{exc} (channel map)") from None
    return channel_map_from_dict(d, str(p))


def channel_map_from_dict(d: Any, source: str = "") -> ChannelMap:
    where = source or "channel map"
    if not isinstance(d, dict) or not isinstance(d.get("channels"), list) or not d["channels"]:
        raise ConfigError(f"{where}: expected {{'channels': [ {{'column': ...}}, ... ]}}")
    specs = []
    for i, c in enumerate(d["channels"]):
        w = f"{where}: channels[{i}]"
        if not isinstance(c, dict) or "column" not in c:
            raise ConfigError(f"{w}: needs 'column' (a name or a 0-based index)")
        col = c["column"]
        if not isinstance(col, (str, int)) or isinstance(col, bool):
            raise ConfigError(f"{w}.column: a name or a 0-based index, got {col!r}")
        scale = c.get("scale", 1.0)
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or \
                not math.isfinite(scale) or scale == 0:
            raise ConfigError(f"{w}.scale: a finite non-zero number, got {scale!r}")
        role = c.get("role")
        if role is not None and role not in ROLES:
            raise ConfigError(f"{w}.role: one of {', '.join(ROLES)}, got {role!r}")
        dof = c.get("dof")
        if dof is not None and (isinstance(dof, bool) or not isinstance(dof, int) or dof < 1):
            raise ConfigError(f"{w}.dof: an integer >= 1, got {dof!r}")
        for key in ("name", "unit"):  # a number or a list would be a channel's name or unit
            v = c.get(key)
            if v is not None and (not isinstance(v, str) or (key == "name" and not v)):
                raise ConfigError(f"{w}.{key}: a{' non-empty' if key == 'name' else ''} "
                                  f"string, got {v!r}")
        unknown = set(c) - {"column", "name", "unit", "scale", "role", "dof"}
        if unknown:
            raise ConfigError(f"{w}: unknown key(s) {', '.join(sorted(unknown))}")
        specs.append(ChannelSpec(col, c.get("name"), c.get("unit"), float(scale), role, dof))
    return ChannelMap(tuple(specs), source)


def default_dofs(rec: Recording) -> Recording:
    """DOF i for the i-th output without one (1-based), the DOF 1 for a lone input."""
    k = 0
    for ch in rec.channels:
        if ch.role == "output" and ch.dof is None:
            k += 1
            ch.dof = k
    ins = [c for c in rec.channels if c.role == "input"]
    if len(ins) == 1 and ins[0].dof is None:
        ins[0].dof = 1
    return rec


def apply_channel_map(rec: Recording, cmap: ChannelMap | None) -> Recording:
    """A recording with the map's channels (selected, renamed, scaled: data * scale)."""
    if cmap is None:
        return default_dofs(rec)
    out: list[Channel] = []
    warnings = list(rec.warnings)
    for i, s in enumerate(cmap.channels):
        if isinstance(s.column, int):
            if not 0 <= s.column < len(rec.channels):
                raise ConfigError(f"{cmap.source}: column {s.column} out of range "
                                  f"({len(rec.channels)} channels in {rec.name})")
            src = rec.channels[s.column]
        else:
            try:
                src = rec.channel(s.column)
            except KeyError as exc:
                raise ConfigError(f"{cmap.source}: {exc.args[0]}") from None
        name = s.name or src.name
        out.append(Channel(name=name, data=_scaled(cmap, i, src, s.scale),
                           unit=src.unit if s.unit is None else
                           checked_unit(cmap.source, name, s.unit, warnings),
                           role=s.role or src.role, dof=s.dof if s.dof is not None else src.dof,
                           scale=s.scale))
    twice = [n for n, k in Counter(c.name for c in out).items() if k > 1]
    if twice:  # the second would be shadowed: a model's channel of the name gets the first
        raise ConfigError(f"{cmap.source}: two channels named {twice[0]!r} (the map's 'name', "
                          "or the column's where it gives none)")
    picked = {s.column if isinstance(s.column, str) else rec.channels[s.column].name
              for s in cmap.channels}
    left = [c.name for c in rec.channels if c.name not in picked]
    if left:
        log.info("%s: channel map leaves out %s", rec.name, ", ".join(left))
    return default_dofs(dataclasses.replace(rec, channels=out, warnings=warnings))


def _scaled(cmap: ChannelMap, i: int, src: Channel, scale: float) -> np.ndarray:
    """src's samples times the map's scale; a sample that the scale takes beyond the float
    range is an error (numpy would make it inf with a RuntimeWarning on stderr)."""
    if scale == 1.0:
        return src.data
    with np.errstate(over="ignore"):
        x = src.data * scale
    over = np.flatnonzero(np.isinf(x) & np.isfinite(src.data))
    if over.size:
        k = int(over[0])
        raise ConfigError(f"{cmap.source}: channels[{i}].scale {scale:g} takes {src.name}'s "
                          f"sample {k} ({float(src.data[k]):g}) beyond the float range")
    return x
