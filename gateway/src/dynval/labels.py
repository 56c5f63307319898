"""Readable channel labels with units, for the reports' tables and plot axes.

A channel's unit is the one its recording declares (a unit suffix such as ``acc3_mps2``, a
file's unit field, a channel map); a channel without one gets the SI unit of what the model
predicts there (dynval models are SI: kg, N/m, so accelerations are m/s^2). What a channel
measures comes from the model's output (or input) entry: "DOF3 floor 2 acceleration" reads
better on an axis than ``acc3_mps2``.
"""
from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from dynval.io.recording import Recording, base_name, split_unit

SI_UNIT = {"acc": "m/s^2", "vel": "m/s", "disp": "m", "story_force": "N",
           "contact_force": "N", "reaction": "N", "force": "N", "ground_acc": "m/s^2",
           "ground_disp": "m"}
QUANTITY = {"acc": "acceleration", "vel": "velocity", "disp": "displacement",
            "story_force": "story force", "contact_force": "contact force",
            "reaction": "reaction force", "force": "input force",
            "ground_acc": "ground acceleration", "ground_disp": "ground displacement"}
# ASCII spellings in files and unit suffixes -> typeset (superscripts, micro sign)
_TYPESET = (("^2", "\u00b2"), ("^3", "\u00b3"), ("um", "\u00b5m"), ("ue", "\u00b5\u03b5"),
            ("microstrain", "\u00b5\u03b5"))
_NO_UNIT = "no unit declared"


def pretty_unit(unit: str) -> str:
    """'m/s^2' -> 'm/s²', 'um' -> 'µm'; '1' (dimensionless) -> ''."""
    u = unit.strip()
    if u == "1":
        return ""
    for ascii_, typeset in _TYPESET:
        u = u.replace(ascii_, typeset)
    return u


def _compound(unit: str) -> bool:
    """A unit that needs brackets before an exponent: m/s² -> (m/s²)², N -> N²."""
    return bool(re.search(r"[/ *\u00b7]|\u00b2|\u00b3", unit))


def squared(unit: str) -> str:
    """The unit squared, typeset: 'm/s^2' -> '(m/s²)²', 'N' -> 'N²'."""
    u = pretty_unit(unit)
    if not u:
        return ""
    return f"({u})\u00b2" if _compound(u) else f"{u}\u00b2"


def psd_unit(unit: str) -> str:
    """The unit of a power spectral density of a channel in ``unit``: '(m/s²)²/Hz'."""
    sq = squared(unit)
    return f"{sq}/Hz" if sq else f"unit\u00b2/Hz, {_NO_UNIT}"


@dataclass(frozen=True)
class ChannelLabel:
    """How a report names one channel: its column, what it measures where, its unit."""

    name: str
    unit: str = ""  # as declared (ASCII), '' when neither the recording nor the model says
    what: str = ""  # e.g. 'DOF3 floor 2 acceleration'; '' when the model does not say

    @property
    def unit_text(self) -> str:
        return pretty_unit(self.unit) or _NO_UNIT

    @property
    def short(self) -> str:
        """The column without its unit suffix: 'acc3_mps2' -> 'acc3'."""
        return base_name(self.name)

    @property
    def title(self) -> str:
        """'DOF3 floor 2 acceleration (acc3)': what, with the column for cross-reference."""
        return f"{self.what} ({self.short})" if self.what else self.name

    def axis(self, quantity: str = "", *, newline: bool = False) -> str:
        """An axis label: '<what> <quantity> (<unit>)', e.g. 'DOF3 floor 2 acceleration
        residual (m/s²)'; newline puts the unit on a line of its own (narrow panels)."""
        head = " ".join(x for x in (self.what or self.short, quantity) if x)
        return f"{head}{chr(10) if newline else ' '}({self.unit_text})"

    def psd_axis(self) -> str:
        return f"PSD ({psd_unit(self.unit)})"

    def value(self, x: float | None, fmt: str = ".4g") -> str:
        """A number with the channel's unit: '0.0359 m/s²'."""
        if x is None:
            return "-"
        u = pretty_unit(self.unit)
        return f"{x:{fmt}} {u}" if u else f"{x:{fmt}}"


def _where(model: Any, dof: int) -> str:
    names = getattr(model, "dof_names", ()) or ()
    return names[dof - 1] if 0 < dof <= len(names) else f"DOF {dof}"


def _model_side(model: Any, name: str) -> tuple[str, str]:
    """(SI unit, description) of a channel from the model's outputs or input; ('', '')."""
    if model is None:
        return "", ""
    out = getattr(model, "outputs", {}).get(name)
    if out is not None:
        kind, i = out.kind, out.index
        if kind in ("acc", "vel", "disp"):
            where = _where(model, i)
        elif kind == "story_force":
            where = f"story {i}"
        elif kind == "contact_force":
            where = f"element {i}"
        else:
            where = ""
        return SI_UNIT.get(kind, ""), " ".join(x for x in (where, QUANTITY.get(kind, kind)) if x)
    inp = getattr(model, "input", None)
    if inp is not None and inp.channel == name:
        where = _where(model, inp.dof) if inp.kind == "force" else ""
        return SI_UNIT.get(inp.kind, ""), " ".join(x for x in (where, QUANTITY[inp.kind]) if x)
    return "", ""


def channel_labels(names: Iterable[str], model: Any = None,
                   recordings: Iterable[Recording] = (),
                   units: Mapping[str, str] | None = None) -> dict[str, ChannelLabel]:
    """Labels of the named channels. The unit: ``units`` (e.g. from a report's JSON), else the
    first recording that declares one, else the unit suffix of the name, else the SI unit of
    what the model predicts there."""
    declared: dict[str, str] = dict(units or {})
    for rec in recordings:
        for c in rec.channels:
            if c.unit and not declared.get(c.name):
                declared[c.name] = c.unit
    out = {}
    for n in names:
        si, what = _model_side(model, n)
        unit = declared.get(n) or split_unit(n)[1] or si
        out[n] = ChannelLabel(n, unit, what)
    return out


def common_unit(labels: Iterable[ChannelLabel]) -> str | None:
    """The one unit the labels share (typeset), or None when they differ."""
    units = {lab.unit_text for lab in labels}
    return units.pop() if len(units) == 1 else None
