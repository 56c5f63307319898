"""Sensor offsets as an effect of the library (issue 16, item 5): a constant added to one
channel is named on that channel and fitted within 3 %, and the other channels are left alone."""
from __future__ import annotations

import numpy as np
import pytest

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop

ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}


def declared() -> mdl.Model:
    return mdl.Model(masses_kg=(6.54, 6.66, 6.86, 6.80),
                     stiffness_n_per_m=(10.0, 399790.0, 399790.0, 399790.0),
                     damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01)),
                     input=mdl.Input("force", 1, "force_N"), outputs=dict(ACC), fs_hz=640.0)


@pytest.mark.parametrize("seed", [101, 102])
def test_a_sensor_offset_is_named_on_its_channel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ch = f"acc{int(rng.integers(1, 5))}_mps2"
    recs = gen.generate(declared(), gen.Truth(label="offset"), n_tests=4, seed=seed)
    rms = float(np.sqrt(np.mean(np.concatenate([r.channel(ch).data for r in recs]) ** 2)))
    b = float(rng.choice([-1, 1]) * rng.uniform(0.05, 0.15) * rms)
    for r in recs:
        r.channel(ch).data = r.channel(ch).data + b
    res = loop.discover(declared(), recs)
    assert [e["type"] for e in res.effects] == ["sensor_offset"]
    e = res.effects[0]
    assert e["location"]["channel"] == ch
    assert e["parameters"]["offset"]["value"] == pytest.approx(b, rel=0.03)
    assert res.model.outputs[ch].offset == pytest.approx(b, rel=0.03)
    assert all(res.model.outputs[c].offset == 0.0 for c in ACC if c != ch)
    # the model file keeps it
    assert mdl.from_dict(mdl.to_dict(res.model)).outputs[ch].offset == res.model.outputs[ch].offset
