"""discover's note when the held-out tests drive a found element beyond the forces of the
fitting tests (discover/extrapolation.py)."""
from __future__ import annotations

import dataclasses

import numpy as np

from dynval import model as mdl
from dynval.discover import extrapolation as xp
from dynval.discover import residual as rs
from dynval.model import elements as el

FS = 640.0


def _chain() -> mdl.Model:
    return mdl.Model(masses_kg=(2.0, 1.0), stiffness_n_per_m=(4e5, 2e5),
                     damping=mdl.Damping("modal", (0.02, 0.02)),
                     input=mdl.Input("force", 1, "force_N"),
                     outputs={"a1": mdl.Output("acc", 1), "a2": mdl.Output("acc", 2)},
                     fs_hz=FS)


def _tests(level: float, seeds: range, prefix: str) -> list[rs.TestData]:
    out = []
    for s in seeds:
        u = level * np.random.default_rng(s).standard_normal(4096)
        out.append(rs.TestData(f"{prefix}{s}", FS, u, {}))
    return out


def _peak_by_drift(m: mdl.Model, contact: el.Contact, tests: list[rs.TestData]) -> float:
    """The contact's largest force from its law on the simulated story drift (the core's
    force block, not its force output)."""
    probe = dataclasses.replace(m, outputs={"x1": mdl.Output("disp", 1),
                                            "x2": mdl.Output("disp", 2)})
    peaks = []
    for t in tests:
        p = mdl.simulate(probe, t.input_for(probe), FS)
        peaks.append(float(np.max(np.abs(el.force(contact, p["x2"] - p["x1"])))))
    return max(peaks)


def test_an_element_driven_further_in_the_held_out_tests_is_said_to_be_extrapolated() -> None:
    declared = _chain()
    contact = el.Contact(1, 2, 3e-5, 2e-5, 4e5)
    m = dataclasses.replace(declared, elements=(contact,))
    # the story drift's RMS at 20 N is ~3e-5 m: the contact closes now and then; at 40 N deep
    fit_t, held_t = _tests(20.0, range(0, 3), "f"), _tests(40.0, range(3, 6), "h")
    got = xp.notes(declared, m, fit_t, held_t)
    want = _peak_by_drift(m, contact, held_t) / _peak_by_drift(m, contact, fit_t)
    assert want > 1.6  # the case: held-out forces well beyond the fitting tests'
    assert len(got) == 1 and "contact element between DOF 1 and DOF 2" in got[0]
    assert f"{want:.2g} x its largest force in the fitting tests" in got[0]
    # the same levels both ways (other seeds): nothing to say
    assert xp.notes(declared, m, fit_t, _tests(20.0, range(3, 6), "h")) == []
    # an element of the declared model is not discover's finding
    assert xp.notes(m, m, fit_t, held_t) == []
