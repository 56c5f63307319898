"""One definition for the discover tests of what they share: what the project's generator
(dynval.synth) puts in every test besides the effects a test asks for (its DAQ's anti-alias
filter, 8th-order Butterworth at 0.4 fs, which discover finds beside a nonlinear element: the
daq_filter effect), and the chain on a shake table many of them start from."""
from __future__ import annotations

from typing import Any

from dynval import model as mdl


def sought(effects: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """discover's effect entries without a DAQ filter it found (the generator's own)."""
    return [e for e in effects if e["type"] != "daq_filter"]


def table_chain(masses_kg: tuple[float, ...], stiffness_n_per_m: tuple[float, ...],
                zetas: tuple[float, ...]) -> mdl.Model:
    """A chain on a shake table (modal damping) with an accelerometer at every DOF, 640 Hz."""
    return mdl.Model(masses_kg=masses_kg, stiffness_n_per_m=stiffness_n_per_m,
                     damping=mdl.Damping("modal", zetas),
                     input=mdl.Input("ground_acc", 0, "table_mps2"),
                     outputs={f"acc{j}_mps2": mdl.Output("acc", j)
                              for j in range(1, len(masses_kg) + 1)},
                     fs_hz=640.0)
