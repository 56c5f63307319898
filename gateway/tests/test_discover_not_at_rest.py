"""Records that do not start at rest (issue 16, item 3): segments cut from the middle of a
longer run. Assuming rest left 7-10x the noise floor on a right model and 9x after the right
contact (the start-up transient); with the initial state estimated both end within 1.35x,
and records that do start at rest are left alone."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from lanl4dof import declared

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import loop
from dynval.io.recording import Recording

N = 8192


def cut_from_a_run(truth: gen.Truth, seed: int) -> list[Recording]:
    """The second half of longer runs: the structure is moving when each record starts."""
    runs = gen.generate(declared(), truth, n_tests=4, n_samples=2 * N, seed=seed)
    return [Recording(r.name, r.fs_hz, [dataclasses.replace(
        c, data=np.ascontiguousarray(c.data[N:])) for c in r.channels]) for r in runs]


@pytest.mark.parametrize("with_contact", [False, True])
def test_records_cut_from_a_run_are_not_taken_for_an_effect(with_contact: bool) -> None:
    els = (mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),) if with_contact else ()
    recs = cut_from_a_run(gen.Truth(elements=els, label="cut"), seed=5)
    r = loop.discover(declared(), recs)
    assert sum("does not start at rest" in n for n in r.notes) == len(recs)
    assert [e["type"] for e in r.effects] == (["contact"] if with_contact else [])
    held = r.after.pooled(r.held_names, r.chans)
    assert all(held[c] < 1.5 * r.noise[c] for c in r.chans), (held, r.noise)


def test_records_that_start_at_rest_stay_at_rest() -> None:
    recs = gen.generate(declared(), gen.Truth(label="rest"), n_tests=4, seed=6)
    r = loop.discover(declared(), recs)
    assert not any("does not start at rest" in n for n in r.notes)
    assert all(t.start is None for t in r.tests)
