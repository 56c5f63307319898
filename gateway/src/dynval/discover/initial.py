"""Records that do not start at rest (segments cut from a continuous run, a periodic steady
state): the initial state is estimated instead of assumed zero.

The model's prediction from rest leaves, at the start of such a record, the free motion of
the state the record began in. That free motion is linear in the initial state x0 (the core's
exact discretisation: model.free_response), so x0 is the least-squares fit of the residual
(each channel weighed by its scale) over the record. It is kept only when it explains a real
share of the residual over the first ``settle`` samples, where a start-up transient lives;
for a record that starts at rest the estimate is noise and the record stays at rest. The
elements' part of the free motion is left out (superposition is the linear part's): the
start-up transient of a nonlinear model is approximated by its linear part's.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dynval import model as mdl
from dynval.discover.residual import TestData, free_motion_fit, predict

log = logging.getLogger(__name__)

MIN_REDUCTION = 0.2  # share of the start window's residual energy x0 must explain
LATE_FACTOR = 2.0  # ... and this many times what a free motion explains later in the record


def _late_share(a: np.ndarray, r: np.ndarray, n: int, w: int, n_ch: int) -> float:
    """The share of the residual energy a free motion explains in a window as long as the
    start window but beginning where that one ends: a residual with structure at the
    modes (a missing effect's) is partly fitted by a free motion anywhere, a start-up
    transient only at the start. 0 when the record has no room for it."""
    if 2 * w > n:
        return 0.0
    head = np.concatenate([np.arange(k * n, k * n + w) for k in range(n_ch)])
    late = head + w
    x, *_ = np.linalg.lstsq(a[head], r[late], rcond=None)
    e = float(r[late] @ r[late])
    left = r[late] - a[head] @ x
    return 1.0 - float(left @ left) / e if e > 0 else 0.0


@dataclass
class Start:
    """The estimated initial state of one record and what it explains."""

    x0: np.ndarray
    outputs: dict[str, np.ndarray]
    reduction: float  # share of the first settle samples' residual energy it explains


def estimate(m: mdl.Model, t: TestData, chans: Sequence[str], scales: dict[str, float],
             settle: int) -> Start | None:
    """The initial state of test t under model m, or None when the record starts at rest
    (or the model cannot be simulated)."""
    at_rest = TestData(t.name, t.fs_hz, t.u, t.y, demean=t.demean)
    p = predict(m, at_rest)
    if p is None:
        return None
    fm = free_motion_fit(m, t, p, {c: scales[c] for c in chans})
    if fm is None:
        return None
    a, r, x0, n = fm.a, fm.r, fm.x0, t.u.size
    w = min(settle, n)
    head = np.concatenate([np.arange(k * n, k * n + w) for k in range(len(chans))])
    before = float(r[head] @ r[head])
    left = r[head] - a[head] @ x0
    reduction = 1.0 - float(left @ left) / before if before > 0 else 0.0
    if not t.moving and (reduction < MIN_REDUCTION or
                         reduction < LATE_FACTOR * _late_share(a, r, n, w, len(chans))):
        return None
    outs = {c: fm.basis[:, j, :] @ x0 for j, c in enumerate(m.outputs)}
    return Start(x0, outs, reduction)


def apply(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
          scales: dict[str, float], settle: int) -> list[str]:
    """Estimate each record's initial state under m and set it on the test and its views
    (they share the record's arrays). Returns a note per record that does not start at
    rest."""
    notes = []
    done: dict[int, Start | None] = {}
    for t in tests:
        key = id(t.u)
        if key not in done:
            done[key] = estimate(m, t, chans, scales, settle)
            s = done[key]
            if s is not None:
                notes.append(f"{t.name.split(' [')[0]}: does not start at rest; its initial "
                             f"state is estimated (it explains {100 * s.reduction:.0f} % of "
                             f"the residual over the first {settle / t.fs_hz:.2g} s)")
                log.info(notes[-1])
        s = done[key]
        t.start = None if s is None else s.outputs
    return notes
