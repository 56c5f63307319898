"""Whether the held-out tests ask an element found by discover to act beyond the range its
parameters were fitted on. The split deals the loudest test to the held-out set (there an
element acts most, which is what lets the held-out tests judge it), so a level-dependent
law can be driven further there than in any fitting test: a contact's transition length
delta and its stiffness kB are told apart only by penetrations deeper than delta, which
the fitting tests may never reach (blind two-effect case 409: the fitting error flat to
0.1 % for delta from 2.7e-5 to 8e-5 m along kB / delta, the held-out error 1.03 -> 0.74 x
over the same range). The report then says so, with the figures."""
from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence

import numpy as np

from dynval import model as mdl
from dynval.discover import residual as rs
from dynval.errors import DynvalError

log = logging.getLogger(__name__)

# an element whose largest force in the held-out tests is over this many times its largest in
# the fitting tests works there beyond the range it was fitted on
EXTRAPOLATED = 1.5


def _peak_forces(m: mdl.Model, elements: Sequence[int], tests: Sequence[rs.TestData]
                 ) -> list[float] | None:
    """The largest |force| of each element (1-based into m.elements) over the samples of
    ``tests`` that count, from m's open-loop simulation; None where a test is predicted by
    the observer or the core refuses the model."""
    probe = dataclasses.replace(m, outputs={f"e{i}": mdl.Output("contact_force", i)
                                            for i in elements})
    peaks = [0.0] * len(elements)
    for t in tests:
        if t.observer is not None:
            return None
        try:
            p = mdl.simulate(probe, t.input_for(probe), t.fs_hz, x0=rs.start_state(m, t))
        except DynvalError as exc:
            log.debug("%s: the elements' forces not simulated: %s", t.name, exc)
            return None
        for k, i in enumerate(elements):
            peaks[k] = max(peaks[k], float(np.max(np.abs(t.counted(p[f"e{i}"])))))
    return peaks


def notes(declared: mdl.Model, m: mdl.Model, fit_t: Sequence[rs.TestData],
          held_t: Sequence[rs.TestData]) -> list[str]:
    """A note for each element m has beyond the declared model's whose largest force in the
    held-out tests exceeds its largest in the fitting tests by over EXTRAPOLATED."""
    added = list(range(len(declared.elements) + 1, len(m.elements) + 1))
    if not added:
        return []
    fit, held = _peak_forces(m, added, fit_t), _peak_forces(m, added, held_t)
    if fit is None or held is None:
        return []
    out = []
    for i, f, h in zip(added, fit, held, strict=True):
        if f > 0 and h > EXTRAPOLATED * f:
            e = m.elements[i - 1]
            where = (f"between DOF {e.dof_a} and DOF {e.dof_b}" if e.dof_a > 0
                     else f"at DOF {e.dof_b} (to the ground)")
            out.append(f"the {e.type.replace('_', ' ')} element {where} reaches {h:.3g} N in "
                       f"the held-out tests, {h / f:.2g} x its largest force in the fitting "
                       f"tests ({f:.3g} N): its law there is extrapolated from what they "
                       "showed, and the held-out error judges that extrapolation too")
            log.info(out[-1])
    return out
