"""Models whose open-loop simulation drifts: a rigid-body mode (a carriage on a guide, a
structure on rails) integrates every small force error into a displacement that grows without
bound, far beyond the effect sought. For such a model the residuals are the one-step-ahead
prediction errors of the core's observer with its steady-state Kalman gain: before each
sample the state is corrected by the measurements so far, so the drift is held by the data
while the model's dynamics over a sample interval, where the effect lives, stay in the error.

Chosen per model: the observer is used when the model has a mode below RIGID_FRACTION of the
input band's lower edge and, on some channel of the declared model, its open-loop prediction
is worse than predicting zero (NRMSE > 1) or most of its residual (DRIFT_SHARE of the energy)
lies below half the input band's lower edge, where only a drift puts it (a force offset moves
the measured position itself, so its NRMSE alone can stay below 1). The Kalman gain's noise
model: a white force of Q_REL x the input's force RMS at each DOF (small: the observer follows
the drift, not the dynamics; with a shake table the input's force is m_j a_g), raised where the
input enters to the input sensor's own noise when the data show it (the measured input's
noise drives every prediction: a cheap force sensor's), and measurement noise of R_REL x each
channel's RMS. A model whose drift no sensor observes (a free rigid-body
mode seen only through accelerations: observed()) stays open loop, with a note; so does one
whose gain the core refuses.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np

from dynval import model as mdl
from dynval.discover import noise
from dynval.discover.residual import ErrorTable, Observer, TestData
from dynval.errors import ConfigError

log = logging.getLogger(__name__)

RIGID_FRACTION = 0.05  # a mode below this x the input band's lower edge is rigid-body-like
Q_REL = 1e-4  # force noise at each DOF, relative to the input's force RMS
R_REL = 0.01  # measurement noise, relative to each channel's RMS


DRIFT_SHARE = 0.5  # share of a channel's residual energy below the band that means drift
NOISE_RATIO = 1.5  # ... when the residual stands this far above the noise floor somewhere


def low_share(res: Sequence[np.ndarray], fs_hz: float, f_hz: float) -> float:
    """The share of the energy of residual records about their means below f_hz
    (periodograms): a constant is an offset (a sensor's, or a constant force on an
    acceleration), not a drift, and an offset must not switch the tests to the observer,
    which would then track it and bias its estimate."""
    low = total = 0.0
    for r in res:
        p = np.abs(np.fft.rfft(r - np.mean(r))) ** 2
        f = np.fft.rfftfreq(r.size, 1.0 / fs_hz)
        low += float(np.sum(p[f < f_hz]))
        total += float(np.sum(p))
    return low / total if total > 0 else 0.0


def drifts(m: mdl.Model, table: ErrorTable, res: dict[str, dict[str, np.ndarray]],
           chans: Sequence[str], scales: dict[str, float], band_hz: tuple[float, float],
           fs_hz: float, noise: dict[str, float] | None = None) -> float | None:
    """The worst open-loop NRMSE when the model is one that drifts (else None); ``res``: the
    declared model's residuals per test and channel; ``noise``: each channel's noise floor
    (RMS), when known: a residual mostly below the band that stays within 1.5 x it is a DAQ's
    1/f noise, not a drift."""
    f = mdl.natural_frequencies(m)
    if not np.any(f < RIGID_FRACTION * max(band_hz[0], 1e-3)):
        return None
    pooled = table.pooled(list(res), chans)
    worst = max(pooled[c] / scales[c] for c in chans)
    if not math.isfinite(worst):
        return None
    share = max(low_share([r[c] for r in res.values()], fs_hz, 0.5 * band_hz[0])
                for c in chans)
    log.info("rigid-body-like mode: worst open-loop NRMSE %.3g, residual share below %.3g Hz "
             "%.2f", worst, 0.5 * band_hz[0], share)
    above = noise is None or any(pooled[c] > NOISE_RATIO * noise.get(c, 0.0) for c in chans)
    return worst if worst > 1.0 or (share > DRIFT_SHARE and above) else None


def observed(m: mdl.Model, band_hz: tuple[float, float]) -> bool:
    """Whether some output measures where the rigid-body-like modes are: a displacement or
    velocity of a DOF they move, or a spring force or reaction they stretch (a position loop's
    force). An accelerometer reads a mode near 0 Hz only through its omega^2, so with
    accelerometers alone an observer cannot hold the drift: the Kalman gain's equation then
    converges or not by rounding, and a gain that exists makes predictions that grow without
    bound (a free chain with four accelerometers: 6e20 x the channels' RMS)."""
    f, phi = mdl.modes(m)
    low = np.flatnonzero(f < RIGID_FRACTION * max(band_hz[0], 1e-3))
    ks = np.asarray(m.stiffness_n_per_m, dtype=float)
    prev = np.vstack([np.zeros((1, phi.shape[1])), phi[:-1]])  # the DOF below, ground 0
    for o in m.outputs.values():
        if o.kind in ("disp", "vel"):
            row = phi[o.index - 1]
        elif o.kind == "story_force":
            row = ks[o.index - 1] * (phi[o.index - 1] - prev[o.index - 1])
        elif o.kind == "reaction":
            row = ks[0] * phi[0]
        else:
            continue
        if np.any(np.abs(row[low]) > 1e-3 * float(np.max(np.abs(row)))):
            return True
    return False


def observer_for(m: mdl.Model, tests: Sequence[TestData], chans: Sequence[str],
                 scales: dict[str, float], q_rel: float = Q_REL) -> Observer:
    """The Kalman gain's noise model (the module comment): the force noise where the input
    enters is at least the input sensor's own (noise.input_noise_psd), which the measured
    input carries into every prediction; a gain that assumes less trusts the model's drift
    too far, and a wrong model that holds the drift (a spring to the ground) beats the right
    one on a cheap sensor's noise. ``q_rel``: the force noise relative to the input's RMS
    (Q_REL; larger for a gain that follows the data more: continuation.py)."""
    u = np.concatenate([t.u for t in tests])
    slack = (q_rel * float(np.std(u))) ** 2
    psd = noise.input_noise_psd(tests)
    sensor = 0.0 if psd is None else psd * tests[0].fs_hz / 2
    if m.input.kind == "force":
        q = [slack] * m.n_dof
        q[m.input.dof - 1] = max(slack, sensor)
    elif m.input.kind == "ground_acc":  # a table's force on each DOF: m_j x its acceleration
        q = [mj ** 2 * max(slack, sensor) for mj in m.masses_kg]
    else:  # a ground displacement: its noise reaches the DOFs through springs (left at slack)
        q = [mj ** 2 * slack for mj in m.masses_kg]
    r = {c: (R_REL * scales[c]) ** 2 for c in chans}
    return Observer(tuple(q), r)


def apply(m: mdl.Model, tests: Sequence[TestData], obs: Observer) -> bool:
    """Switch the tests to observer predictions; False when the core refuses the gain (the
    tests stay open loop)."""
    try:
        mdl.predict_observed(m, tests[0].u[:16], {k: v[:16] for k, v in tests[0].y.items()},
                             tests[0].fs_hz, obs.q_force_n2, obs.r_meas)
    except ConfigError as exc:
        log.warning("the model drifts but no observer can hold it: %s", exc)
        return False
    for t in tests:
        t.observer = obs
        t.start = t.start_x0 = None  # the observer finds the state itself
    return True
