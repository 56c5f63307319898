"""The report's 4-DOF three-story structure as a declared model, for the discover tests: one
definition instead of one per test file."""
from __future__ import annotations

from dynval import model as mdl

MASSES = (6.54, 6.66, 6.86, 6.80)
KS = (10.0, 399790.0, 399790.0, 399790.0)
ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}


def declared() -> mdl.Model:
    """Force at DOF 1, an accelerometer on every DOF, modal damping, 640 Hz."""
    return mdl.Model(masses_kg=MASSES, stiffness_n_per_m=KS,
                     damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01)),
                     input=mdl.Input("force", 1, "force_N"), outputs=dict(ACC), fs_hz=640.0)
