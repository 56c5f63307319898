"""A swept-sine test (issue 16: other people's tests are often sweeps). At each frequency a
sweep passes once; the rest of the record there is the input sensor's noise, which the
simulations would take as force all along (noise.idle_gain takes it out). Blind sweep case 2:
a 5 % story-1 stiffness loss read through a cheap DAQ (1/f and white noise, 50 Hz hum,
offsets): with the idle noise in the simulations, the better-damped stick-slip at story 4
was added beside the right change (this test fails without idle_gain)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_discover_noise import cheap_daq

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop
from dynval.discover import residual as rs


def test_a_stiffness_loss_under_a_sweep_read_by_a_cheap_daq_is_the_only_effect() -> None:
    m = mdl.Model(masses_kg=(6.49, 4.34, 4.02, 5.33),
                  stiffness_n_per_m=(2.155e5, 1.919e5, 4.441e5, 2.909e5),
                  damping=mdl.Damping("modal", (0.038, 0.020, 0.021, 0.040)),
                  input=mdl.Input("force", 2, "force_N"),
                  outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in (1, 2, 3, 4)},
                  fs_hz=640.0)
    truth = gen.Truth(k_scale={1: 0.95})
    recs = gen.generate(m, truth, n_tests=6, n_samples=4096, seed=2, noise=0.0,
                        excitation=gen.Sweep(10.9, 227.8))
    cheap_daq(recs, np.random.default_rng(2), 0.03, 2.0)
    r = loop.discover(m, recs)
    assert [(e["type"], e["location"].get("story")) for e in r.effects] == [
        ("stiffness_change", 1)]
    dk = r.effects[0]["parameters"]["dk_n_per_m"]["value"]
    assert dk == pytest.approx(-0.05 * 2.155e5, rel=0.05)  # measured -4.97 %
    true_m = dataclasses.replace(gen.truth_model(m, truth), outputs=m.outputs,
                                 interpolation=m.interpolation, oversample=m.oversample)
    ideal, _ = rs.error_table(true_m, r.tests, r.chans, r.scales)
    assert r.after.total(r.held_names) / ideal.total(r.held_names) < 1.1
