"""Records that do not start at rest (segments cut from a continuous run, a periodic steady
state): the initial state is estimated instead of assumed zero.

The model's prediction from rest leaves, at the start of such a record, the free motion of
the state the record began in. That free motion is linear in the initial state x0 (the core's
exact discretisation: model.free_response), so x0 is the least-squares fit of the residual
(each channel weighed by its scale) over the record. It is kept only when it explains a real
share of the residual over the first ``settle`` samples, where a start-up transient lives;
for a record that starts at rest the estimate is noise and the record stays at rest. Every
model tried is simulated from x0 (the core's dv_obs_set_state; residual.start_state), so the
transient is its own; under a model with elements x0 is refined through it over the first
samples (refined): the linear part's x0 misses what the elements do to the transient (a
friction element holds its DOF where it stopped). Once per model under apply;
every candidate is fitted and judged at its own initial states (starts_under), and an
accepted element's parameters are fitted again with the states estimated under each model
tried (fit.at_own_starts). Whether a record starts at rest is asked again under each
candidate too: the current model may be too far off to see its transient.
"""
from __future__ import annotations

import importlib
import logging
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.discover.residual import TestData, free_motion_fit, predict
from dynval.errors import ConfigError

log = logging.getLogger(__name__)
least_squares: Any = importlib.import_module("scipy.optimize").least_squares

# Levenberg-Marquardt iterations (each 2 n + 1 simulations of the start window) refining the
# initial state under a model with elements
REFINE_EVALS = 3
MIN_REDUCTION = 0.2  # share of the start window's residual energy x0 must explain
LATE_FACTOR = 2.0  # ... and this many times the energy a free motion explains later on
# a record whose every output, about its mean, is this quiet over the first quarter period of
# the lowest flexible mode (against its RMS over the record) starts at rest
QUIET = 0.1


def _late_explained(a: np.ndarray, r: np.ndarray, n: int, w: int, n_ch: int) -> float:
    """The residual energy a free motion explains (its own least squares) in a window as long
    as the start window but beginning where that one ends. Against what x0 explains over the
    start window: a residual with structure at the modes (a missing effect's, as strong later
    as at the start) is partly fitted by a free motion anywhere, a start-up transient mostly
    at the start, where most of its energy is. As energies, not shares: a lightly damped
    start-up transient still rings in the later window, where a free motion explains half of
    what is left of it (blind sweep case 20, a shake table's sweep cut from a run: 37-74 %
    of a residual 1/3000 of the start window's, so three of six records were taken as
    starting at rest and the true model read 400-700 x the noise floor). 0 when the record
    has no room for it."""
    if 2 * w > n:
        return 0.0
    head = np.concatenate([np.arange(k * n, k * n + w) for k in range(n_ch)])
    late = head + w
    x, *_ = np.linalg.lstsq(a[head], r[late], rcond=None)
    left = r[late] - a[head] @ x
    return float(r[late] @ r[late]) - float(left @ left)


def quiet_start(m: mdl.Model, t: TestData, chans: Sequence[str]) -> bool:
    """Whether every output channel of t is quiet at its start: a structure moving when the
    record began shows it in its first samples, whatever the input. A ramped input (a swept
    sine's, a sine's, a hammer's pre-trigger) starts at rest, yet a level-dependent effect's
    residual concentrates at the sweep's start, where a free motion fits half of it (blind swept
    sine 4, a contact: 32-52 % of its first 0.3 s). Over the first quarter period the blind
    benches' swept sines that start at rest read 1-5 % of their RMS, records cut from a run
    55-340 %. A random force's outputs respond at once: the check mostly says nothing there."""
    flex = [float(f) for f in mdl.natural_frequencies(m) if f > 0.1]
    if not flex or not chans:
        return False
    k = int(min(max(4, round(t.fs_hz / (4.0 * min(flex)))), t.u.size // 4))
    for c in chans:
        y = t.y[c] - float(np.mean(t.y[c]))
        rms = float(np.sqrt(np.mean(y * y)))
        if rms == 0.0 or float(np.sqrt(np.mean(y[:k] * y[:k]))) > QUIET * rms:
            return False
    return True


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
    if not t.moving and quiet_start(m, t, chans):
        return None
    w = min(settle, t.u.size)
    if (not t.moving and not set(chans) & set(t.demean)
            and _head_bound(m, t, chans, scales, w) < MIN_REDUCTION):
        return None
    at_rest = TestData(t.name, t.fs_hz, t.u, t.y, demean=t.demean)
    p = predict(m, at_rest)
    if p is None:
        return None
    fm = free_motion_fit(m, t, p, {c: scales[c] for c in chans})
    if fm is None:
        return None
    a, r, x0, n = fm.a, fm.r, fm.x0, t.u.size
    head = np.concatenate([np.arange(k * n, k * n + w) for k in range(len(chans))])
    before = float(r[head] @ r[head])
    left = r[head] - a[head] @ x0
    reduction = 1.0 - float(left @ left) / before if before > 0 else 0.0
    if not t.moving and (reduction < MIN_REDUCTION or reduction * before
                         < LATE_FACTOR * _late_explained(a, r, n, w, len(chans))):
        return None
    outs = {c: fm.basis[:, j, :] @ x0 for j, c in enumerate(m.outputs)}
    return Start(x0, outs, reduction)


def _head_bound(m: mdl.Model, t: TestData, chans: Sequence[str], scales: dict[str, float],
                w: int) -> float:
    """The largest share of the first w samples' residual energy from rest that any free
    motion of m explains (their own least squares): estimate's reduction, whose state is
    fitted over the whole record, is at most this (the simulation and the free responses
    are causal: their first w samples are the whole record's), at a fraction of its cost
    (a record asked again under each candidate, starts_under). 1 where m cannot be
    simulated: no bound."""
    try:
        p = mdl.simulate(m, _head_input(t.input_for(m), w), t.fs_hz)
    except ConfigError:
        return 1.0
    basis = mdl.free_response(m, t.fs_hz, w)
    outs = list(m.outputs)
    a = np.concatenate([basis[:, outs.index(c), :] / scales[c] for c in chans])
    r = np.concatenate([(t.y[c][:w] - p[c]) / scales[c] for c in chans])
    e = float(r @ r)
    if not (np.all(np.isfinite(a)) and np.isfinite(e)) or e == 0.0:
        return 1.0
    x, *_ = np.linalg.lstsq(a, r, rcond=None)
    left = r - a @ x
    return 1.0 - float(left @ left) / e


def _head_input(u: mdl.PreparedInput | np.ndarray, w: int) -> mdl.PreparedInput | np.ndarray:
    """The first w samples of an input as simulate() takes it."""
    if isinstance(u, mdl.PreparedInput):
        return mdl.PreparedInput(u.fine[:w * u.r], u.r, u.daq)
    return u[:w]


def refined(m: mdl.Model, t: TestData, chans: Sequence[str], scales: dict[str, float],
            settle: int, x0: np.ndarray) -> np.ndarray:
    """x0 refined under a model with elements: the state whose simulation through them
    best fits the first ``settle`` samples (Levenberg-Marquardt from x0). The linear part's
    free motion misses what the elements do to a start-up transient: a friction element
    stuck where the cut left it holds its DOF there (blind sweep case 8 without its DAQ's
    noise: the true model's held-out normalised SSE 61 from the linear part's x0, 0.072 from
    this, the declared model's 8.8)."""
    w = min(settle, t.u.size)
    u = _head_input(t.input_for(m), w)
    n = m.n_dof
    # each half (displacements, velocities) in units of its largest entry: z of order one
    unit = np.repeat([max(float(np.max(np.abs(x0[:n]))), 1e-12),
                      max(float(np.max(np.abs(x0[n:]))), 1e-12)], n)

    def residual(z: np.ndarray) -> np.ndarray:
        try:
            p = mdl.simulate(m, u, t.fs_hz, x0=z * unit)
        except ConfigError:
            return np.full(w * len(chans), 1e150)
        out = []
        for c in chans:
            e = t.y[c][:w] - p[c]
            if c in t.demean:
                e = e - e.mean()
            out.append(e / scales[c])
        r = np.concatenate(out)
        return r if np.all(np.isfinite(r)) else np.full(r.size, 1e150)

    z0 = x0 / unit
    r0 = residual(z0)
    sol = least_squares(residual, z0, method="lm", max_nfev=REFINE_EVALS * (2 * n + 1))
    better = float(sol.fun @ sol.fun) < float(r0 @ r0)
    return np.asarray(sol.x * unit) if better else x0


def _own_start(m: mdl.Model, t: TestData, chans: Sequence[str], scales: dict[str, float]
               ) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
    """(x0, what the channels read of its free motion) of test t under m: the least-squares
    state of m's residual from rest (estimate's, without its test of whether the record
    starts at rest: it does not), of the size t's state has (a DOF m adds starts where its
    host does: no free state of its own). None when m cannot be simulated."""
    kept = t.start, t.start_x0
    n_state = None if t.start_x0 is None else t.start_x0.size
    t.start = t.start_x0 = None  # the test itself: its prepared inputs are kept
    try:
        p = predict(m, t)
    finally:
        t.start, t.start_x0 = kept
    fm = None if p is None else free_motion_fit(m, t, p, {c: scales[c] for c in chans},
                                                n_state)
    if fm is None:
        return None
    return fm.x0, {c: fm.basis[:, j, :] @ fm.x0 for j, c in enumerate(m.outputs)}


@contextmanager
def starts_under(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
                 scales: dict[str, float]) -> Iterator[None]:
    """Within the block, each record that does not start at rest starts where m puts it (a candidate
    is judged at its own initial states, as the current model is at its): the least-squares state of
    m's own residual, refined through m's elements, or the states as they are where m's elements are
    the ones they were refined under and m has no DOF more (a candidate that leaves the current
    model's elements as they are). A model with DOFs the states do not have (an appendage) starts
    its new DOFs where their hosts do (sized_start), the hosts' states estimated under it that way:
    its own states would give it two free parameters per record on the held-out tests themselves (a
    spurious appendage beside an encoder's zero on a position loop); the current model's, simulated
    through the appendage's, left blind free case 64's true appendage a held-out test 2 x worse. A
    record found at rest under the current model is asked again under m (estimate): under a model
    far from the truth the start-up transient is lost in the model's error (blind two-effect case
    415, story 1 11.5 % soft and a mass 9 % light, records cut from a run: every record found at
    rest, the true model's held-out error 54 x its own at its states, so the right change gained 5 %
    and a damping change won). Back to what they were after it: the next candidate starts from the
    same states whichever process fits it."""
    h = m.elements
    todo: dict[int, TestData] = {}
    at_rest: dict[int, TestData] = {}
    for t in tests:
        if t.observer is not None or t.free_start is not None:
            continue
        if (t.start_x0 is not None and t.start_x0.size <= 2 * m.n_dof
                and not (h and t.start_elements == h and t.start_x0.size == 2 * m.n_dof)):
            todo.setdefault(id(t.u), t)
        elif t.start_x0 is None and t.start_window > 0:
            at_rest.setdefault(id(t.u), t)
    new: dict[int, tuple[dict[str, np.ndarray], np.ndarray, tuple[Any, ...]]] = {}
    for k, t in todo.items():
        own = _own_start(m, t, chans, scales)
        if own is not None:
            x0 = (refined(m, t, chans, scales, t.start_window, own[0])
                  if h and t.start_window > 0 and own[0].size == 2 * m.n_dof else own[0])
            new[k] = (own[1], x0, h)
    for k, t in at_rest.items():  # found at rest under the current model: asked again
        st = estimate(m, t, chans, scales, t.start_window)
        if st is not None:
            x0 = refined(m, t, chans, scales, t.start_window, st.x0) if h else st.x0
            new[k] = (st.outputs, x0, h)
    if not new:
        yield
        return
    with kept(tests):
        for t in tests:
            if id(t.u) in new:
                t.start, t.start_x0, t.start_elements = new[id(t.u)]
        yield


@contextmanager
def kept(tests: Sequence[TestData]) -> Iterator[None]:
    """Within the block the tests' initial states may be set anew (a candidate's, each
    model's a fit tries); after it each test has the ones it had."""
    before = [(t, t.start, t.start_x0, t.start_elements, t.start_window) for t in tests]
    try:
        yield
    finally:
        for t, start, x0, elements, window in before:
            t.start, t.start_x0, t.start_elements, t.start_window = start, x0, elements, window


def apply(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
          scales: dict[str, float], settle: int, quiet: bool = False) -> list[str]:
    """Estimate each record's initial state under m and set it on the test and its views
    (they share the record's arrays); under a model with elements the linear part's estimate
    is refined through them (refined). Returns a note per record that does not
    start at rest (logged unless ``quiet``: a fit that estimates them at every model)."""
    notes = []
    done: dict[int, Start | None] = {}
    for t in tests:
        key = id(t.u)
        if key not in done:
            s = estimate(m, t, chans, scales, settle)
            if s is not None and m.elements:
                s.x0 = refined(m, t, chans, scales, settle, s.x0)
            done[key] = s
            if s is not None:
                notes.append(f"{t.name.split(' [')[0]}: does not start at rest; its initial "
                             f"state is estimated (it explains {100 * s.reduction:.0f} % of "
                             f"the residual over the first {settle / t.fs_hz:.2g} s)")
                if not quiet:
                    log.info(notes[-1])
        s = done[key]
        t.start = None if s is None else s.outputs
        t.start_x0 = None if s is None else s.x0
        t.start_elements = m.elements if s is not None else ()
        t.start_window = settle
    return notes
