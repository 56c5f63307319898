"""Hashes of the Python binding's simulations (tests/scripts/golden_hashes.sh): the report's
4-DOF model with each element law, on the ground and in a story, force and ground-motion
input, first-order and cubic hold, open loop; one sha256 per case over the exact bytes."""
from __future__ import annotations

import hashlib
import sys

import numpy as np

from dynval import model as mdl

BASE = {"format": "dynval-model/1", "masses_kg": [6.54, 6.66, 6.86, 6.80],
        "stiffness_n_per_m": [10.0, 399790.0, 399790.0, 399790.0],
        "damping": {"type": "modal", "zeta": [0.01, 0.05, 0.01, 0.01]},
        "input": {"kind": "force", "dof": 1, "channel": "u"},
        "outputs": {f"acc{i}": {"kind": "acc", "dof": i} for i in range(1, 5)}}
ELEMENTS = {
    "linear": [],
    "contact_pos": [{"type": "contact", "between": [3, 4], "side": "pos", "gap_m": 1.114e-4,
                     "delta_m": 1e-4, "kb_n_per_m": 1.925e6}],
    "contact_both_ground": [{"type": "contact", "between": [0, 2], "side": "both",
                             "gap_m": 2e-4, "delta_m": 0.0, "kb_n_per_m": 5e5}],
    "friction": [{"type": "friction", "between": [0, 1], "force_n": 2.0,
                  "v_eps_m_per_s": 1e-3}],
    "friction_story": [{"type": "friction", "between": [1, 2], "force_n": 1.0,
                        "v_eps_m_per_s": 2e-3}],
    "stick_slip": [{"type": "stick_slip", "between": [0, 1], "force_n": 2.0, "slip_m": 1e-5}],
    "cubic": [{"type": "cubic_spring", "between": [2, 3], "k3_n_per_m3": 5e12}],
    "vv": [{"type": "vv_damper", "between": [3, 4], "c2_n_s2_per_m2": 200.0}],
}


def main() -> int:
    rng = np.random.default_rng(7)
    u = np.convolve(rng.standard_normal(4096), np.ones(4) / 4, mode="same") * 60.0
    for name, els in ELEMENTS.items():
        for kind in ("force", "ground_acc"):
            for interp in ("foh", "cubic", "bandlimited"):
                d = dict(BASE, elements=els,
                         input={"kind": kind, "dof": 1, "channel": "u"} if kind == "force"
                         else {"kind": kind, "channel": "u"},
                         simulation={"input_interpolation": interp})
                m = mdl.from_dict(d)
                uu = u if kind == "force" else u / 6.0
                y = mdl.simulate(m, uu, 640.0)
                h = hashlib.sha256()
                for c in sorted(y):
                    h.update(np.ascontiguousarray(y[c], dtype=np.float64).tobytes())
                sys.stdout.write(f"{h.hexdigest()}  py/{name}/{kind}/{interp}\n")
    f, phi = mdl.modes(mdl.from_dict(BASE))
    h = hashlib.sha256(np.concatenate([f, phi.ravel()]).tobytes()).hexdigest()
    sys.stdout.write(f"{h}  py/modes\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
