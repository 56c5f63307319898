"""Velocity and displacement sensors (a laser vibrometer, a geophone, a proximity probe or an
LVDT instead of accelerometers): with a force input and one such sensor on every DOF, the
missing force is also reconstructed from the differentiated motions (trace.force_view with
``motions``) and its two strongest candidates are fitted beside the output view's (the
primary view there: its states are simulated, free of the sensors' noise, but first order, so
a strong element is ranked low).

Measured before the change on a single-DOF oscillator with a two-sided clearance (the
Silverbox's layout: one sensor, a force), a best-linear declared model: with a velocity sensor
"no effect" at 17.4 x the true model's held-out error, with a displacement sensor a cubic
spring at 13.8 x; after: the two-sided contact (0.51 x; 3.31 x with the displacement sensor,
where the true model's own error moves 1.64 x with the simulation's rate: it is sensitive).
On 32 single-DOF cases (softening, contact, cubic, friction; displacement or velocity) nothing
else changed; on 36 blind 3-5 DOF chains with such sensors see bench/RESULTS.blind-sensors.md."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.discover import trace as tr

F0_HZ, MASS_KG, ZETA = 60.709, 2.8762, 0.015766
BAND_HZ = (5.0, 200.0)
LEVEL_N = 12.0


def oscillator(kind: str) -> mdl.Model:
    k = MASS_KG * (2 * math.pi * F0_HZ) ** 2
    return mdl.Model(masses_kg=(MASS_KG,), stiffness_n_per_m=(k,),
                     damping=mdl.Damping("modal", (ZETA,)),
                     input=mdl.Input("force", 1, "force_N"),
                     outputs={f"{kind}1": mdl.Output(kind, 1)}, fs_hz=640.0)


def clearance(m: mdl.Model) -> mdl.Contact:
    """A two-sided clearance at 1.8 x the linear oscillator's RMS displacement, its stops four
    times as stiff as the spring."""
    u = gen.band_limited_force(np.random.default_rng(0), 8192 * 16, 640.0 * 16, LEVEL_N,
                               BAND_HZ)[::16]
    x = mdl.simulate(dataclasses.replace(m, outputs={"x": mdl.Output("disp", 1)}), u, 640.0)
    return mdl.Contact(0, 1, 1.8 * float(np.std(x["x"])), 5e-5,
                       4 * m.stiffness_n_per_m[0], "both")


def in_band(x: np.ndarray) -> np.ndarray:
    spec = np.fft.rfft(x)
    spec[np.fft.rfftfreq(x.size, 1 / 640.0) > BAND_HZ[1]] = 0.0
    return np.fft.irfft(spec, x.size)


def test_the_differentiated_view_sees_the_missing_force_the_accelerometers_see() -> None:
    both = dataclasses.replace(oscillator("acc"), outputs={
        "acc1": mdl.Output("acc", 1), "vel1": mdl.Output("vel", 1),
        "disp1": mdl.Output("disp", 1)})
    el = clearance(both)
    recs = gen.generate(both, gen.Truth(elements=(el,)), n_tests=2, seed=3, band_hz=BAND_HZ)
    acc = oscillator("acc")
    ref = tr.force_view(acc, rs.prepare(acc, recs))
    assert ref is not None
    assert tr.force_view(acc, rs.prepare(acc, recs), motions=True) is None  # the plain one
    for kind in ("vel", "disp"):
        m = oscillator(kind)
        tests = rs.prepare(m, recs)
        assert tr.force_view(m, tests) is None  # no accelerometer
        view = tr.force_view(m, tests, motions=True)
        assert view is not None
        # the same missing force in the input band (the differentiated view stops above it,
        # at 1.5 x its upper edge; the accelerometer's goes on), each sensor's noise 1 %
        a, b = (in_band(v.f_miss.ravel()) for v in (ref, view))
        assert np.corrcoef(a, b)[0, 1] > 0.95  # 0.993 (velocity), 0.968 (displacement)
        top = tr.score(view, fx.catalogue(m))[0]
        assert (top.cand.type, top.cand.location.get("side")) == ("contact", "both")


def test_a_clearance_read_by_one_velocity_sensor_is_found() -> None:
    m = oscillator("vel")
    el = clearance(m)
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=6, seed=1, band_hz=BAND_HZ,
                        levels_n_rms=(LEVEL_N, 0.6 * LEVEL_N))
    r = loop.discover(gen.best_linear(m, recs), recs)
    e = r.effects[0]
    assert (e["type"], e["location"]["between"], e["location"]["side"]) == (
        "contact", [0, 1], "both")
    assert e["parameters"]["gap_m"]["value"] == pytest.approx(el.gap_m, rel=0.1)
    ideal, _ = rs.error_table(dataclasses.replace(m, elements=(el,)), r.tests, r.chans,
                              r.scales)
    assert r.after.total(r.held_names) < 1.3 * ideal.total(r.held_names)
