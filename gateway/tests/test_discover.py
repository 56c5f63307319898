"""dynval discover on generated "measured" tests with an undeclared effect (dynval.synth: the
truth simulated by the core at 16x, DAQ anti-alias filter, decimation, 1 % sensor noise, two
excitation levels), random locations and sizes per effect type (fixed seeds), clean data, and
the shared lanl4dof-bumper data through the CLI.

Tolerances (stated): stiffness change within 3 % of the true change, mass change within 5 %,
sensor gain within 0.005, friction force within 10 %, cubic and v|v| coefficients within 5 %,
contact gap within 15 % (delta and kB trade off against each other
— the report's Section 6 says so — and are not asserted); held-out normalised SSE reduction
>= 90 % for stiffness and mass changes, >= 50 % for contacts, and for a sensor gain the
channel's held-out RMSE halves and ends within 1.5 x its noise floor."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from generated import sought

from dynval import cli
from dynval import model as mdl
from dynval import synth as gen
from dynval.discover import effects as fx
from dynval.discover import loop, report
from dynval.discover import noise as nz
from dynval.discover import residual as rs
from dynval.discover import trace as tr
from dynval.io import read_test

MASSES = (6.54, 6.66, 6.86, 6.80)
KS = (10.0, 399790.0, 399790.0, 399790.0)
ZETA = (0.01, 0.05, 0.01, 0.01)
ACC = {f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)}
N_TESTS = 6
# half the generator's 8192 samples: CI time (the full size runs in bench_discover_blind)
N_SAMPLES = 4096


def declared() -> mdl.Model:
    return mdl.Model(masses_kg=MASSES, stiffness_n_per_m=KS, damping=mdl.Damping("modal", ZETA),
                     input=mdl.Input("force", 1, "force_N"), outputs=dict(ACC), fs_hz=640.0)


def run(truth: gen.Truth, seed: int, n_samples: int = N_SAMPLES) -> loop.DiscoverResult:
    recs = gen.generate(declared(), truth, n_tests=N_TESTS, n_samples=n_samples, seed=seed)
    return loop.discover(declared(), recs)


def only_effect(r: loop.DiscoverResult) -> dict[str, Any]:
    found = sought(r.effects)
    assert len(found) == 1, [e["label"] for e in r.effects]
    return found[0]


def held_reduction(r: loop.DiscoverResult) -> float:
    return 1.0 - r.after.total(r.held_names) / r.before.total(r.held_names)


# ---- the generator ------------------------------------------------------------------------
def test_generator_clean_matches_declared_model_to_noise_floor() -> None:
    recs = gen.generate(declared(), gen.Truth(), n_tests=2, seed=1)
    for rec in recs:
        assert rec.n_samples == 8192 and rec.fs_hz == 640.0
        res = mdl.residual(declared(), rec)
        for c in res.channels.values():  # 1 % sensor noise + the input's 1 % noise
            assert 0.009 < c.nrmse < 0.02


def test_generator_truth_differs_from_the_c_model_only_by_the_effect() -> None:
    """The bumper truth from the generator (the core at 16 x fs), predicted by the C model WITH
    the bumper at fs, is at the noise floor; without it, far above."""
    truth = gen.Truth(elements=(mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),))
    rec = gen.generate(declared(), truth, n_tests=1, seed=2)[0]
    with_b = mdl.Model(**{**declared().__dict__, "elements": (
        mdl.Contact(3, 4, 1.114e-4, 1e-4, 1.925e6),)})
    assert max(c.nrmse for c in mdl.residual(with_b, rec).channels.values()) < 0.02
    assert min(c.nrmse for c in mdl.residual(declared(), rec).channels.values()) > 0.03


# ---- the loop on each available effect type ------------------------------------------------
@pytest.mark.parametrize("seed", [11])  # more seeds: bench_discover_blind (CI time)
def test_discover_stiffness_loss(seed: int) -> None:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    loss = float(rng.uniform(0.03, 0.15))
    r = run(gen.Truth(k_scale={story: 1 - loss}, label="kloss"), seed)
    e = only_effect(r)
    assert e["type"] == "stiffness_change" and e["location"]["story"] == story
    want = -loss * KS[story - 1]
    assert e["parameters"]["dk_n_per_m"]["value"] == pytest.approx(want, rel=0.03)
    assert held_reduction(r) > 0.9


@pytest.mark.parametrize("seed", [21])  # more seeds: bench_discover_blind (CI time)
def test_discover_added_mass(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dof = int(rng.integers(1, 5))
    dm = float(rng.uniform(0.2, 1.0))
    r = run(gen.Truth(m_add_kg={dof: dm}, label="mass"), seed)
    e = only_effect(r)
    assert e["type"] == "mass_change" and e["location"]["dof"] == dof
    assert e["parameters"]["dm_kg"]["value"] == pytest.approx(dm, rel=0.05)
    assert held_reduction(r) > 0.9


@pytest.mark.parametrize("seed", [31])  # seed 32 (found too): dropped for CI time
def test_discover_sensor_gain(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ch = f"acc{int(rng.integers(1, 5))}_mps2"
    g = float(rng.choice([-1, 1]) * rng.uniform(0.03, 0.08) + 1.0)
    r = run(gen.Truth(gains={ch: g}, label="gain"), seed)
    e = only_effect(r)
    assert e["type"] == "sensor_gain" and e["location"]["channel"] == ch
    assert abs(e["parameters"]["gain"]["value"] - g) < 0.005
    # only that channel was wrong: its held-out error falls to the floor, the others stay
    before = r.before.pooled(r.held_names, r.chans)
    after = r.after.pooled(r.held_names, r.chans)
    assert after[ch] < 0.5 * before[ch]
    assert after[ch] < 1.5 * r.noise[ch]
    assert r.model.outputs[ch].gain == pytest.approx(g, abs=0.005)


# seed 41's gap closes rarely: at 4096 samples its held-out gain fell to 13 %; at 8192, > 50 %
@pytest.mark.parametrize(("seed", "n_samples"), [(41, 8192), (42, N_SAMPLES)])
def test_discover_contact(seed: int, n_samples: int) -> None:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    side = str(rng.choice(["pos", "neg"]))
    gap = float(rng.uniform(0.7e-4, 1.1e-4))
    delta = float(rng.uniform(0.5e-4, 1.5e-4))
    kb = float(rng.uniform(1.0e6, 2.5e6))
    truth = gen.Truth(elements=(mdl.Contact(story - 1, story, gap, delta, kb, side),),
                      label="contact")
    r = run(truth, seed, n_samples)
    e = only_effect(r)
    assert e["type"] == "contact"
    assert (e["location"]["story"], e["location"]["side"]) == (story, side)
    assert e["parameters"]["gap_m"]["value"] == pytest.approx(gap, rel=0.15)
    assert held_reduction(r) > 0.5


@pytest.mark.parametrize("seed", [51])  # more: bench_discover_blind --effects 0 (CI time)
def test_discover_clean_data_reports_no_effect(seed: int) -> None:
    r = run(gen.Truth(), seed)
    assert r.effects == []
    doc = report.to_json(r)
    assert doc["verdict"].startswith("no effect: the declared model explains")
    # how far under the significance ratio the worst channel is, said with the verdict
    worst = max(r.rounds[-1].ratio.values())
    assert 0.8 < worst <= rs.SIGNIFICANCE_RATIO
    assert f"(worst channel {worst:.3g} x its floor" in doc["verdict"]
    assert doc["rmse_after"] == doc["rmse_before"]


# ---- the element effects (friction, cubic, v|v|: dv_model element laws) --------------------
@pytest.mark.parametrize(("truth", "want"), [
    (gen.Truth(elements=(mdl.Friction(0, 1, 0.8, 1e-4),)), ("friction", 1)),
    (gen.Truth(elements=(mdl.Friction(0, 3, 0.5, 1e-4),)), ("friction", 3)),
    (gen.Truth(elements=(mdl.CubicSpring(1, 2, 3e12),)), ("cubic_stiffness", 2)),
    (gen.Truth(elements=(mdl.CubicSpring(3, 4, 5e12),)), ("cubic_stiffness", 4)),
    (gen.Truth(elements=(mdl.VVDamper(2, 3, 5e3),)), ("vv_damping", 3)),
])
def test_trace_ranks_element_effects_first(truth: gen.Truth, want: tuple[str, int]) -> None:
    m = declared()
    recs = gen.generate(m, truth, n_tests=3, seed=7)
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None
    top = tr.score(view, fx.catalogue(m))[0]
    loc = top.cand.location.get("dof", top.cand.location.get("story"))
    assert (top.cand.type, loc) == want
    assert top.cand.available


@pytest.mark.parametrize("seed", [61])  # more seeds: bench_discover_blind (CI time)
def test_discover_friction(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dof = int(rng.integers(1, 5))
    force = float(rng.uniform(0.3, 1.0))
    r = run(gen.Truth(elements=(mdl.Friction(0, dof, force, 1e-4),),
                      label="friction"), seed)
    e = only_effect(r)
    assert e["type"] == "friction" and e["location"]["dof"] == dof
    assert e["parameters"]["force_n"]["value"] == pytest.approx(force, rel=0.1)
    assert held_reduction(r) > 0.8


@pytest.mark.parametrize("seed", [71])  # more seeds: bench_discover_blind (CI time)
def test_discover_cubic_stiffness(seed: int) -> None:
    rng = np.random.default_rng(seed)
    story = int(rng.integers(2, 5))
    k3 = float(10 ** rng.uniform(12.0, 12.8))
    r = run(gen.Truth(elements=(mdl.CubicSpring(story - 1, story, k3),),
                      label="cubic"), seed)
    e = only_effect(r)
    assert e["type"] == "cubic_stiffness" and e["location"]["story"] == story
    assert e["parameters"]["k3_n_per_m3"]["value"] == pytest.approx(k3, rel=0.05)
    assert held_reduction(r) > 0.9


def test_discover_vv_damping() -> None:
    r = run(gen.Truth(elements=(mdl.VVDamper(1, 2, 8e3),), label="vv"), 81)
    e = only_effect(r)
    assert e["type"] == "vv_damping" and e["location"]["story"] == 2
    assert e["parameters"]["c2_n_s2_per_m2"]["value"] == pytest.approx(8e3, rel=0.05)
    assert held_reduction(r) > 0.9


def test_library_is_documented() -> None:
    types = {d["type"]: d for d in fx.describe()}
    for t in ("contact", "stiffness_change", "mass_change", "damping_change", "sensor_gain",
              "none", "friction", "cubic_stiffness", "vv_damping"):
        assert types[t]["law"]
    assert types["friction"]["available"] and types["contact"]["available"]


# ---- the CLI on the shared bumper data -----------------------------------------------------
def test_cli_discover_shared_bumper(shared_data: Path, tmp_path: Path) -> None:
    folder = shared_data / "synthetic" / "lanl4dof-bumper"
    out_json, out_html, out_model = tmp_path / "d.json", tmp_path / "d.html", tmp_path / "m.json"
    # (its time is a benchmark's: bench/bench_discover.py)
    rc = cli.main(["-q", "discover", str(folder / "declared_model.json"), str(folder),
                   "--json", str(out_json), "--html", str(out_html), "--model-out",
                   str(out_model)])
    assert rc == 1  # the declared model lacks the bumper
    doc = json.loads(out_json.read_text())
    assert doc["format"] == "dynval-discover/1"
    (e,) = doc["effects"]
    assert e["type"] == "contact"
    assert (e["location"]["story"], e["location"]["between"], e["location"]["side"]) == (
        4, [3, 4], "pos")
    assert e["parameters"]["gap_m"]["value"] == pytest.approx(1.114e-4, rel=0.1)
    for c in doc["channels"]:
        assert doc["rmse_after"]["held_out"][c] < 0.5 * doc["rmse_before"]["held_out"][c]
    page = out_html.read_text()
    assert "data:image/png;base64," in page
    # the features' paired distance falls with the error (it once read 2.04 before and after
    # a 94 % error reduction); a paired test still rejecting the updated model is explained
    mah = doc["mahalanobis"]
    assert mah["after"] < 0.5 * mah["before"] and mah["p_before"] < 0.05
    assert ("class=\"note\"" in page) == (mah["p_after"] < report.LEVEL)
    # the updated model reproduces the after-error through the ordinary simulate path, driven
    # by the input as discover's note says it takes it (without the force sensor's noise
    # under the band: 6.25 Hz here); the raw force gives the same within 0.1 %
    assert any("is its sensor's noise" in n for n in doc["notes"])
    m = mdl.load(out_model)
    for pt in doc["per_test"][:2]:
        rec = read_test(folder / f"{pt['test']}.csv")
        raw = mdl.residual(m, rec)
        ch = rec.channel(mdl.input_channel(m, rec))
        ch.data = nz.simulated_input(m.input.kind, ch.data, rec.fs_hz)
        res = mdl.residual(m, rec)
        for c, v in pt["rmse_after"].items():
            assert res.channels[c].rmse == pytest.approx(v, rel=1e-9)
            assert raw.channels[c].rmse == pytest.approx(v, rel=1e-3)


# ---- real data: the banded rotary friction damper (BRFD) -----------------------------------
BRFD = ("1Hz30lbtension1amplitude", "0.5Hz30lbtension1amplitude", "2Hz30lbtension0.5amplitude")


def brfd_declared(recs: list[Any]) -> mdl.Model:
    """A linear spring-damper driven by the measured stroke (in, kip: consistent units), k and
    c by least squares over the tests, behind a rigid (huge) reaction mass; the measured
    friction force is the reaction with the sensor's sign reversed. The quantised stroke is
    held linearly (foh): band-limited interpolation would differentiate its steps."""
    u = np.concatenate([r.channel("displacement").data for r in recs])
    f = np.concatenate([r.channel("friction_force").data for r in recs])
    v = np.concatenate([np.gradient(r.channel("displacement").data) * r.fs_hz for r in recs])
    k, c = np.linalg.lstsq(np.column_stack([u, v]), f, rcond=None)[0]
    return mdl.from_dict({
        "format": "dynval-model/1", "name": "brfd-linear", "masses_kg": [1e7],
        "stiffness_n_per_m": [float(k)],
        "damping": {"type": "rayleigh", "alpha_per_s": 0.0, "beta_s": float(c / k)},
        "input": {"kind": "ground_disp", "channel": "displacement"},
        "outputs": {"friction_force": {"kind": "reaction", "gain": -1.0}}, "fs_hz": 1024.0,
        "simulation": {"input_interpolation": "foh", "oversample": 1}})


def hand_columns(x: np.ndarray, fs_hz: float, v0: float) -> np.ndarray:
    """The hand fit's regressors: stroke, velocity, tanh(v / v0), 1."""
    v = np.gradient(x) * fs_hz
    return np.column_stack([x, v, np.tanh(v / v0), np.ones_like(x)])


def hand_coulomb_fit(recs: list[Any]) -> tuple[np.ndarray, float, list[float]]:
    """A hand-made physical fit as a user would make it: F = k x + c v + Fc tanh(v / v0) + F0
    by least squares on the even time blocks (v0 on a grid), RMSE on the odd blocks (kip):
    the same blocks discover holds out with fewer than four tests. Returns the coefficients,
    v0 and the held-out RMSE per record, for the v0 with the least pooled one."""
    rows = []
    for r in recs:
        x = r.channel("displacement").data
        even = (np.arange(x.size) * rs.SEGMENT_BLOCKS // x.size) % 2 == 0
        rows.append((x, r.fs_hz, r.channel("friction_force").data, even))
    best: tuple[float, np.ndarray, float, list[float]] | None = None
    for v0 in np.geomspace(1e-3, 10.0, 40):
        cols = [(hand_columns(x, fs, v0), f, even) for x, fs, f, even in rows]
        p = np.linalg.lstsq(np.concatenate([a[e] for a, _, e in cols]),
                            np.concatenate([f[e] for _, f, e in cols]), rcond=None)[0]
        rmse = [math.sqrt(float(np.mean((a[~e] @ p - f[~e]) ** 2))) for a, f, e in cols]
        pooled = math.sqrt(float(np.mean(np.square(rmse))))
        if best is None or pooled < best[0]:
            best = (pooled, p, float(v0), rmse)
    assert best is not None
    return best[1], best[2], best[3]


def test_discover_brfd_finds_stick_slip_friction(shared_data: Path) -> None:
    """Real measured rig, default options (no expert flags): the declared model is the
    best linear spring-damper, so k1 and beta must be re-adjusted by default."""
    folder = shared_data / "real" / "friction-damper-brfd" / "dataset-2" / \
        "characterization datasets"
    recs = [read_test(folder / f"{n}.json") for n in BRFD]
    m = brfd_declared(recs)
    r = loop.discover(m, recs, loop.Options())
    top = r.rounds[0].evidence[0]
    assert top.cand.type in ("stick_slip", "friction") and top.cand.location["between"] == [0, 1]
    e = only_effect(r)
    assert e["type"] == "stick_slip" and set(e["readjusted"]) >= {"k1"}
    before = r.before.pooled(r.held_names, r.chans)["friction_force"]
    after = r.after.pooled(r.held_names, r.chans)["friction_force"]
    # measured: 1.013 -> 0.532 kip held out, floor 0.500 (periods), hand fit 0.96
    assert after < 0.6 * before
    assert after < 1.15 * r.noise["friction_force"]
    hand = hand_coulomb_fit(recs)[2]
    assert after < 0.7 * math.sqrt(float(np.mean(np.square(hand))))


def test_cli_discover_bad_model_exits_2(tmp_path: Path) -> None:
    bad = tmp_path / "m.json"
    bad.write_text("{}")
    assert cli.main(["-q", "discover", str(bad), str(tmp_path)]) == 2


# ---- elements between any two DOFs (issue 16, item 7) -------------------------------------
@pytest.mark.parametrize(("truth", "want"), [
    (gen.Truth(elements=(mdl.Friction(1, 2, 0.8, 1e-4),)), ("friction", [1, 2])),
    (gen.Truth(elements=(mdl.Friction(1, 3, 0.8, 1e-4),)), ("friction", [1, 3])),
    (gen.Truth(elements=(mdl.CubicSpring(2, 4, 5e12),)), ("cubic_stiffness", [2, 4])),
])
def test_trace_ranks_an_element_between_any_two_dofs(truth: gen.Truth,
                                                     want: tuple[str, list[int]]) -> None:
    m = declared()
    recs = gen.generate(m, truth, n_tests=3, seed=9)
    view = tr.force_view(m, rs.prepare(m, recs))
    assert view is not None
    top = tr.score(view, fx.catalogue(m))[0]
    assert (top.cand.type, top.cand.location["between"]) == want


def test_discover_a_sliding_joint_between_two_dofs() -> None:
    r = run(gen.Truth(elements=(mdl.Friction(1, 2, 0.6, 1e-4),), label="joint"), 85)
    e = only_effect(r)
    assert e["type"] == "friction" and e["location"]["between"] == [1, 2]
    assert e["parameters"]["force_n"]["value"] == pytest.approx(0.6, rel=0.1)
    assert held_reduction(r) > 0.8


def test_a_bases_products_over_its_rows_are_the_dense_ones() -> None:
    """trace._Products takes |b|^2, b.f, Q'b and b.f_res over the rows an n x T field is not
    zero on (an element between two DOFs): the same numbers as over the whole flattened
    field, and as the 1-D image's."""
    rng = np.random.default_rng(3)
    n, t = 5, 700
    f = rng.standard_normal(n * t)
    q, _ = np.linalg.qr(rng.standard_normal((n * t, 4)))
    f_res = f - q @ (q.T @ f)
    b = np.zeros((n, t))
    b[1], b[3] = rng.standard_normal(t), rng.standard_normal(t)
    products = tr._Products(f, f_res, np.ascontiguousarray(q.T), n)
    dense = b.ravel()
    want = (dense @ dense, dense @ f, q.T @ dense, dense @ f_res)
    for got in (products(b), products(dense)):
        np.testing.assert_allclose(got[0], want[0], rtol=1e-12)
        np.testing.assert_allclose([got[1], got[3]], [want[1], want[3]], rtol=1e-12)
        np.testing.assert_allclose(got[2], want[2], rtol=1e-12, atol=1e-12)
    assert products(np.zeros((n, t)))[0] == 0.0
