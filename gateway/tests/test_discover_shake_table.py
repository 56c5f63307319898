"""A shake-table input gets the same evidence view as a force input (issue 16, item 7): the
states relative to the table from the measured absolute accelerations minus the table's, the
missing force from -M 1 a_g. Before, the view was refused, every candidate was fitted and a
friction joint was put in the wrong place."""
from __future__ import annotations

import pytest

from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import loop
from dynval.discover import residual as rs
from dynval.discover import trace as tr

ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}


def on_a_table() -> mdl.Model:
    return mdl.Model(masses_kg=(6.54, 6.66, 6.86, 6.80), stiffness_n_per_m=(399790.0,) * 4,
                     damping=mdl.Damping("modal", (0.01, 0.02, 0.01, 0.01)),
                     input=mdl.Input("ground_acc", 0, "table_mps2"), outputs=dict(ACC),
                     fs_hz=640.0)


@pytest.mark.parametrize(("el", "want"), [
    (mdl.Friction(1, 2, 2.0, 1e-4), ("friction", [1, 2])),
    (mdl.Contact(2, 3, 0.5e-4, 1e-4, 1.925e6), ("contact", [2, 3])),
    (mdl.CubicSpring(3, 4, 3e12), ("cubic_stiffness", [3, 4])),
])
def test_shake_table_evidence_ranks_the_element_first(el: mdl.Element,
                                                      want: tuple[str, list[int]]) -> None:
    m = on_a_table()
    recs = gen.generate(m, gen.Truth(elements=(el,)), n_tests=3, seed=3, levels_n_rms=(3.0, 1.8))
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None
    top = tr.score(view, fx.catalogue(m))[0]
    assert (top.cand.type, top.cand.location["between"]) == want


def test_shake_table_friction_joint_is_found_and_fitted() -> None:
    m = on_a_table()
    recs = gen.generate(m, gen.Truth(elements=(mdl.Friction(1, 2, 2.0, 1e-4),)), n_tests=6,
                        seed=3, levels_n_rms=(3.0, 1.8))
    r = loop.discover(m, recs)
    assert [(e["type"], e["location"]["between"]) for e in r.effects] == [("friction", [1, 2])]
    assert r.effects[0]["parameters"]["force_n"]["value"] == pytest.approx(2.0, rel=0.1)
    assert r.after.total(r.held_names) < 0.05 * r.before.total(r.held_names)
