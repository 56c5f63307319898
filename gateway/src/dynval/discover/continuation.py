"""A joint re-adjustment of the declared parameters that does not stop in the nearest local
minimum. The output-error fit of a lightly damped model is multimodal in its frequencies: a
mode several bandwidths off (a best-linear declared model with its top mode 9 % high at 1 %
damping) leaves the simulation out of phase after a few cycles, and every small step makes
the error worse. The observer's one-step-ahead prediction errors with a Kalman gain that
follows the data keep the simulation in phase, so their error falls smoothly toward the
right frequencies (the prediction-error method), but their gain also biases the damping and
the elements. So the fit goes through a sequence of gains, each following the data less
than the one before (Q_STEPS: the force noise relative to the input's RMS, drift.py's noise
model), each fit starting where the previous one stopped, and ends with the output-error fit
that is what discover reports.
"""
from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence

from dynval import model as mdl
from dynval.discover import drift as dr
from dynval.discover import effects as fx
from dynval.discover import fit as ft
from dynval.discover.residual import TestData
from dynval.errors import ConfigError

log = logging.getLogger(__name__)

# each step's gain follows the data less (q_rel of drift.observer_for); the last is still
# ten times drift's own, which only holds a drift
Q_STEPS = (0.03, 0.01, 0.003, 0.001)


def fit(m: mdl.Model, names: Sequence[str], tests: Sequence[TestData], chans: Sequence[str],
        scales: dict[str, float], max_nfev: int, workers: int = 1) -> ft.FitResult | None:
    """The declared parameters ``names`` (and any element parameters among them) fitted
    through the observer's gains Q_STEPS, then open loop (the module comment): the final
    output-error fit, or None when the tests already use an observer (a drifting model) or
    the core refuses a gain or a fit."""
    return fit_candidate(m, fx.NONE.candidates(m)[0], [], names, tests, chans, scales,
                         max_nfev, workers)


def fit_candidate(m: mdl.Model, cand: fx.Candidate, init: Sequence[float],
                  names: Sequence[str], tests: Sequence[TestData], chans: Sequence[str],
                  scales: dict[str, float], max_nfev: int, workers: int = 1
                  ) -> ft.FitResult | None:
    """A candidate's fit (fit.fit from ``init``, with ``names`` re-adjusted) through the
    observer's gains Q_STEPS, each step starting from the effect's values and the
    re-adjusted parameters the previous one reached, then open loop; None as for fit. An
    element that makes the response jump (a hardening spring under a sweep) has an
    output-error objective with many basins: 6-DOF blind sweep case 1's cubic spring
    stopped at 10 x its coefficient from a start at half of it, and through the gains it
    reached it."""
    if any(t.observer is not None for t in tests):
        return None
    base, own = m, list(init)
    try:
        for q in Q_STEPS:
            obs = dr.observer_for(base, tests, chans, scales, q)
            seen = [dataclasses.replace(t, observer=obs, start=None) for t in tests]
            res = ft.fit(base, cand, own, seen, chans, scales, max_nfev, names, workers)
            own = res.values[:len(own)]
            base = m.with_params(res.readjusted())
        return ft.fit(base, cand, own, tests, chans, scales, max_nfev, names, workers)
    except ConfigError as exc:
        log.info("%s through the observer's gains failed: %s", cand.label, exc)
        return None
