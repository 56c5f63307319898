"""The two studies behind `dynval validate` and `dynval calibrate` (report Section 6), as
library functions: they return a JSON-ready result (gateway/docs/validate-schema.md) and the
arrays the HTML report plots. Progress goes to an optional ``progress(stage) -> callback``."""
from __future__ import annotations

import contextlib
import dataclasses
import importlib
import logging
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import __version__
from dynval import labels as lb
from dynval import model as mdl
from dynval.errors import ConfigError
from dynval.io.recording import Recording
from dynval.validate import calibrate as cal
from dynval.validate import checks as chk
from dynval.validate import doe
from dynval.validate import mahalanobis as mh
from dynval.validate import measurement as meas
from dynval.validate import verdict as vd
from dynval.validate.featvec import FeatureSet, parse
from dynval.validate.sensitivity import anova_table, pca

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
ProgressFactory = Callable[[str], Progress | None]
N_MARK = 20  # best / worst runs marked in the plots (the report's twenty)


@contextlib.contextmanager
def single_thread_blas() -> Iterator[None]:
    """Small matrices: BLAS threads only contend (up to 7x slower GP predictions on a busy
    2-core box)."""
    try:
        tpc = importlib.import_module("threadpoolctl")
    except ImportError:
        yield
        return
    with tpc.threadpool_limits(limits=1):
        yield


def _data(rec: Recording) -> dict[str, np.ndarray]:
    return {c.name: c.data for c in rec.channels}


def _no_progress(_stage: str) -> Progress | None:
    return None


@dataclass
class Setup:
    model: mdl.Model
    recs: list[Recording]
    features: FeatureSet
    fs_hz: float
    input_channel: str
    rmse_channels: list[str]
    noise: list[dict[str, float]] = field(default_factory=list)  # per test of recs


def setup(m: mdl.Model, recs: Sequence[Recording], spec: str,
          rmse_channels: Sequence[str] | None = None, noise: str = "auto") -> Setup:
    """Check the tests (same rate and length, the model's channels), bind the features and
    find the sensor noise each test's simulated features get (measurement.noise_levels)."""
    if len(recs) < 2:
        raise ConfigError(f"validation needs at least 2 experimental tests, got {len(recs)}")
    fs = recs[0].fs_hz
    for r in recs[1:]:
        if abs(r.fs_hz - fs) > 1e-6 * fs:
            raise ConfigError(f"{r.name}: sampled at {r.fs_hz:g} Hz, {recs[0].name} at {fs:g} Hz")
    n = min(r.n_samples for r in recs)
    if any(r.n_samples != n for r in recs):
        log.warning("tests differ in length: features use the first %d samples of each", n)
        recs = [dataclasses.replace(r, channels=[dataclasses.replace(c, data=c.data[:n])
                                                 for c in r.channels]) for r in recs]
    avail = [c for c in recs[0].names if c in m.outputs]
    inp = mdl.input_channel(m, recs[0])
    fset = parse(spec).resolve(avail).with_input(inp).fit_reference(_data(recs[0]), fs,
                                                                    _data(recs[1]))
    rc = list(rmse_channels) if rmse_channels else fset.channels
    rc = parse("rms@" + ",".join(rc)).resolve(avail).channels
    nz = meas.noise_levels(noise, m, recs, fset.channels, inp)
    return Setup(m, list(recs), fset, fs, inp, rc, nz)


def experiment_features(s: Setup, recs: Sequence[Recording]) -> np.ndarray:
    return np.array([s.features.extract(_data(r), s.fs_hz) for r in recs])


# samples of each record the report's time-history and spectrum figures get (the first ones):
# an hour-long test's predictions are not kept whole for a 0.6 s window
OVERLAY_SAMPLES = 1 << 17


def _excerpt(a: np.ndarray) -> np.ndarray:
    return np.array(a[:OVERLAY_SAMPLES])


def _model_on_tests(s: Setup, m: mdl.Model, recs: Sequence[Recording], first: int = 0
                    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Features (as measured: with the sensor noise of s.recs[first + k], measurement.
    add_noise) and RMSE per RMSE channel of model m driven by each test's force, and the
    excerpt (_excerpt) of each test's prediction of the first RMSE channel."""
    need = list(dict.fromkeys([*s.features.channels, *s.rmse_channels]))
    cut = dataclasses.replace(m, outputs={c: m.outputs[c] for c in need})  # a faster core run
    feats, rmse, preds = [], [], []
    for k, (r, nz) in enumerate(zip(recs, s.noise[first:first + len(recs)], strict=True)):
        u = r.channel(s.input_channel).data
        y = meas.simulate(cut, u, s.fs_hz)
        feats.append(s.features.extract(meas.add_noise(y, nz, u, first + k), s.fs_hz, u))
        rmse.append([doe.rmse_eq47(y[c], r.channel(c).data) for c in s.rmse_channels])
        preds.append(_excerpt(y[s.rmse_channels[0]]))
    return np.array(feats), np.array(rmse), preds


def _sim_summary(s: Setup) -> dict[str, Any]:
    return {"input_hold": meas.HOLD, "oversample": meas.OVERSAMPLE,
            "sensor_noise_rms": meas.median_noise(s.noise),
            "sensor_noise_rms_per_test": [dict(n) for n in s.noise]}


def _check(s: Setup, base: mh.Baseline, x_exp: np.ndarray, f_mod: np.ndarray,
           rmse: np.ndarray) -> dict[str, Any]:
    """A model's features against the tests': the verdict, its evidence, distances, RMSE."""
    d = base.distance(f_mod)
    size = mh.verdict(base, d)
    paired = mh.paired_test(base, x_exp, f_mod, base.level)
    return {"d": d.tolist(), "rmse": {c: rmse[:, j].tolist()
                                      for j, c in enumerate(s.rmse_channels)},
            "verdict": vd.decide(paired, size), "mahalanobis": size,
            "paired": paired.summary()}


def _spearman(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3:
        return math.nan
    st = importlib.import_module("scipy.stats")
    return float(st.spearmanr(a[ok], b[ok]).statistic)


def _marks(score: np.ndarray) -> tuple[list[int], list[int]]:
    order = [int(i) for i in np.argsort(score) if np.isfinite(score[i])]
    k = min(N_MARK, max(1, len(order) // 10))
    return order[:k], order[-k:][::-1]


@dataclass
class Artifacts:
    """Arrays for the HTML report."""

    fs_hz: float
    param_names: list[str] = field(default_factory=list)
    x: np.ndarray | None = None
    d_exp: np.ndarray | None = None
    d_runs: np.ndarray | None = None
    score: np.ndarray | None = None
    best: list[int] = field(default_factory=list)
    worst: list[int] = field(default_factory=list)
    threshold: float = math.nan
    d_model: np.ndarray | None = None
    model_label: str = "nominal"
    d_heldout_exp: np.ndarray | None = None
    overlays: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    overlay_channel: str = ""
    posteriors: dict[str, np.ndarray] = field(default_factory=dict)
    calibrated: dict[str, float] = field(default_factory=dict)
    ranges: list[tuple[float, float]] = field(default_factory=list)
    # the RMSE channels' labels and units (the score's unit) and the parameters' units
    labels: dict[str, lb.ChannelLabel] = field(default_factory=dict)
    param_units: list[str] = field(default_factory=list)
    overlay_test: str = ""
    feature_names: list[str] = field(default_factory=list)  # the spec's, for their figures
    overlay_input: np.ndarray | None = None  # the overlay test's input (FRF figures)
    overlay_record_s: float = 0.0  # the overlay test's length (the overlays: its first part)
    checks: list[chk.Outcome] = field(default_factory=list)  # linearity / reciprocity
    input_unit: str = "N"


def _label(art: Artifacts, s: Setup, ranges: Sequence[doe.ParamRange]) -> dict[str, str]:
    """Give the artifacts the channels' labels and the parameters' units; the RMSE channels'
    units for the JSON result."""
    art.labels = lb.channel_labels(s.rmse_channels, s.model, s.recs)
    art.param_units = [mdl.param_unit(r.name, s.model) for r in ranges]
    return {c: lab.unit for c, lab in art.labels.items()}


def _sweep(s: Setup, runner: doe.Runner, ranges: Sequence[doe.ParamRange], x: np.ndarray,
           test: int, rmse: bool, progress: Progress | None) -> doe.SweepResult:
    """The sweep driven by test number test's force (its records the RMSE references)."""
    ref = s.recs[test]
    refs = {c: ref.channel(c).data for c in s.rmse_channels} if rmse else None
    job = doe.make_job(s.model, [ref.channel(s.input_channel).data], s.fs_hz, s.features,
                       rmse_refs=refs, noise=[s.noise[test]], streams=[test])
    return runner.run(job, doe.as_sets(ranges, x), on_progress=progress)


def validate(m: mdl.Model, recs: Sequence[Recording], spec: str,
             ranges: Sequence[doe.ParamRange] = (), *, runs: int = 200, design: str = "lhs",
             ref_test: int = 0, rmse_channels: Sequence[str] | None = None, seed: int = 0,
             levels: int = 3, shrink: str = "auto", noise: str = "auto", level: float = 0.95,
             checks: Sequence[str] = (), swapped: Sequence[Recording] = (),
             runner: doe.Runner | None = None, progress: ProgressFactory = _no_progress
             ) -> tuple[dict[str, Any], Artifacts]:
    """Validation of m against the tests (one verdict: verdict.decide, joined by the
    linearity / reciprocity checks of validate.checks; swapped: the reciprocity check's
    tests), with an optional DOE over ranges."""
    s = setup(m, recs, spec, rmse_channels, noise)
    outcomes = chk.run(m, s.recs, chk.parse(checks, m, [c for c in s.recs[0].names
                                                        if c in m.outputs]),
                       s.input_channel, noise, swapped)
    x_exp = experiment_features(s, s.recs)
    base = mh.fit(x_exp, s.features.labels(), shrink=shrink, level=level)
    f_nom, r_nom, preds = _model_on_tests(s, m, s.recs)
    d_nom = base.distance(f_nom)
    check = _check(s, base, x_exp, f_nom, r_nom)
    res: dict[str, Any] = {
        "format": "dynval-validate/2", "kind": "validate", "dynval": __version__,
        "model": m.source or m.name, "tests": [r.name for r in s.recs], "fs_hz": s.fs_hz,
        "features": {"spec": spec, "labels": s.features.labels()},
        "simulation": _sim_summary(s), "baseline": base.summary(),
        "verdict": check["verdict"], "nominal": check, "rmse_channels": s.rmse_channels}
    if outcomes:
        res["checks"] = [o.summary() for o in outcomes]
        res["verdict"] = check["verdict"] = vd.with_checks(check["verdict"], res["checks"])
    art = Artifacts(s.fs_hz, d_exp=base.baseline_d, threshold=base.threshold, d_model=d_nom,
                    checks=outcomes)
    ref = s.recs[ref_test] if 0 <= ref_test < len(s.recs) else None
    if ref is None:
        raise ConfigError(f"--ref-test {ref_test}: there are {len(s.recs)} tests (0-based)")
    if ranges:
        doe.check_params(m, ranges)
    res["units"] = _label(art, s, ranges)
    art.overlay_test = ref.name
    art.feature_names = [n for t in s.features.terms for n in t.names]
    art.overlay_input = _excerpt(ref.channel(s.input_channel).data)
    art.overlay_record_s = ref.n_samples / s.fs_hz
    art.input_unit = ref.channel(s.input_channel).unit or lb.SI_UNIT.get(m.input.kind, "")
    ch0 = s.rmse_channels[0]
    art.overlay_channel = ch0
    art.overlays["measured"] = {ch0: _excerpt(ref.channel(ch0).data)}
    art.overlays["nominal"] = {ch0: preds[ref_test]}
    if ranges:
        own = runner is None
        rn = runner or doe.Runner()
        try:
            x = doe.design(design, ranges, runs, seed, levels)
            sw = _sweep(s, rn, ranges, x, ref_test, True, progress("sweep"))
            d_runs = base.distance(sw.mean_features)
            score = sw.score
            best, worst = _marks(score)
            res["doe"] = {
                "design": design, "runs": int(x.shape[0]), "seed": seed,
                "ref_test": ref.name, "parameters": [dataclasses.asdict(r) for r in ranges],
                "x": x.tolist(), "d": d_runs.tolist(),
                "rmse": {c: sw.rmse[:, j].tolist() for j, c in enumerate(s.rmse_channels)},
                "score": score.tolist(), "score_kind": "rmse" if len(s.rmse_channels) == 1
                else "nrmse_combined", "failed": sw.failed,
                "best": best, "worst": worst,
                "spearman_d_vs_rmse": _spearman(d_runs, score),
                "fraction_within_threshold": float(np.mean(d_runs <= base.threshold)),
                "best_run": {r.name: float(x[best[0], j]) for j, r in enumerate(ranges)}
                if best else {}}
            zs = base.standardise(sw.mean_features)
            pc = pca(zs)
            res["pca"] = {**pc.summary(), "on": "sweep features standardised by the baseline"}
            if len(ranges) <= 4:
                xf = doe.full_factorial(ranges, 3)
                sf = _sweep(s, rn, ranges, xf, ref_test, False, progress("factorial"))
                res["sensitivity"] = {"design": "full factorial, 3 levels",
                                      "runs": int(xf.shape[0]),
                                      "table": anova_table(xf, sf.mean_features,
                                                           [r.name for r in ranges],
                                                           s.features.labels())}
            art.param_names = [r.name for r in ranges]
            art.ranges = [(r.lo, r.hi) for r in ranges]
            art.x, art.d_runs, art.score, art.best, art.worst = x, d_runs, score, best, worst
            full = s.model
            for lab, idx in (("best run", best[0] if best else None),
                             ("worst run", worst[0] if worst else None)):
                if idx is not None:
                    y = doe.simulate_one(full, doe.as_sets(ranges, x[idx:idx + 1])[0],
                                         art.overlay_input, s.fs_hz)  # the excerpt only
                    art.overlays[lab] = {ch0: y[ch0]}
        finally:
            if own:
                rn.close()
    return res, art


def calibrate(m: mdl.Model, recs: Sequence[Recording], spec: str,
              ranges: Sequence[doe.ParamRange], *, method: str = "both", runs: int = 150,
              holdout: int | None = None, direct_forces: int = 4, gp_forces: int | None = None,
              walkers: int = 32, steps: int = 1500, direct_walkers: int = 16,
              direct_steps: int = 300, rmse_channels: Sequence[str] | None = None,
              seed: int = 0, shrink: str = "auto", oversample: int | None = None,
              noise: str = "auto", level: float = 0.95, runner: doe.Runner | None = None,
              progress: ProgressFactory = _no_progress
              ) -> tuple[dict[str, Any], Artifacts, mdl.Model]:
    """Bayesian calibration of the ranged parameters (see calibrate.py), then the report's
    consistency check on held-out tests. Returns (result, artifacts, calibrated model)."""
    if method not in ("gp", "direct", "both"):
        raise ConfigError(f"--method must be gp, direct or both, not {method!r}")
    doe.check_params(m, ranges)
    s = setup(m, recs, spec, rmse_channels, noise)
    n = len(s.recs)
    h = max(1, n // 4) if holdout is None else holdout
    if not 0 <= h <= n - 3:
        raise ConfigError(f"--holdout {h}: need at least 3 training tests of {n}")
    train, held = s.recs[: n - h], s.recs[n - h:]
    x_tr = experiment_features(s, train)
    base = mh.fit(x_tr, s.features.labels(), shrink=shrink, level=level)
    mg = min(len(train), gp_forces or len(train))
    md = min(len(train), direct_forces)
    own = runner is None
    rn = runner or doe.Runner()
    res: dict[str, Any] = {
        "format": "dynval-validate/2", "kind": "calibrate", "dynval": __version__,
        "model": m.source or m.name, "fs_hz": s.fs_hz,
        "tests": {"training": [r.name for r in train], "held_out": [r.name for r in held]},
        "features": {"spec": spec, "labels": s.features.labels()},
        "parameters": [dataclasses.asdict(r) for r in ranges], "baseline": base.summary(),
        "rmse_channels": s.rmse_channels, "simulation": _sim_summary(s),
        "verdict": {"verdict": "INCONCLUSIVE", "exit_code": vd.EXIT["INCONCLUSIVE"],
                    "meaning": "no held-out tests (--holdout 0): nothing checks the "
                               "calibrated model", "evidence": {}}}
    art = Artifacts(s.fs_hz, param_names=[r.name for r in ranges],
                    ranges=[(r.lo, r.hi) for r in ranges], d_exp=base.baseline_d,
                    threshold=base.threshold, model_label="calibrated")
    res["units"] = _label(art, s, ranges)
    posts: dict[str, cal.Posterior] = {}
    try:
        with single_thread_blas():
            x = doe.latin_hypercube(ranges, runs, seed)
            forces = [r.channel(s.input_channel).data for r in train[:mg]]
            job = doe.make_job(s.model, forces, s.fs_hz, s.features, oversample=oversample,
                               noise=s.noise[:mg])
            sw = rn.run(job, doe.as_sets(ranges, x), on_progress=progress("sweep"))
            resid, jbest = cal.residual_at_best(base, x_tr[:mg], sw.features)
            basis = cal.choose_basis(base, sw.mean_features, mg)
            res["sweep"] = {"design": "lhs", "runs": runs, "forces": mg, "seed": seed,
                            "x": x.tolist(), "d": base.distance(sw.mean_features).tolist(),
                            "reduced_dims": int(basis.shape[0]),
                            "residual_cov_at": {r.name: float(x[jbest, j])
                                                for j, r in enumerate(ranges)}}
            art.x, art.d_runs = x, base.distance(sw.mean_features)
            start = None
            if method in ("gp", "both"):
                tg = cal.make_target(base, x_tr[:mg], resid, basis)
                post, _ = cal.calibrate_gp(tg, ranges, x, sw.mean_features, walkers=walkers,
                                           steps=steps, seed=seed, on_progress=progress("gp"))
                posts["gp"] = post
                start = post.samples[-4 * direct_walkers:]
            if method in ("direct", "both"):
                tg2 = cal.make_target(base, x_tr[:md], resid, basis)
                job2 = doe.make_job(s.model, [r.channel(s.input_channel).data
                                              for r in train[:md]], s.fs_hz, s.features,
                                    oversample=oversample, noise=s.noise[:md])
                posts["direct"] = cal.calibrate_direct(
                    tg2, ranges, job2, rn, start=start, walkers=direct_walkers,
                    steps=direct_steps, seed=seed, on_progress=progress("direct"))
    finally:
        if own:
            rn.close()
    res["posterior"] = {k: p.summary(level) for k, p in posts.items()}
    if len(posts) == 2:
        res["comparison"] = {"gp_minus_direct": cal.compare(posts["gp"], posts["direct"])}
    chosen = posts["direct"] if "direct" in posts else posts["gp"]
    params = chosen.as_params()
    res["calibrated"] = {"from": chosen.method, "parameters": params}
    m_cal = m.with_params(params)
    art.calibrated = params
    for k, p in posts.items():
        art.posteriors[k] = p.samples[:: max(1, p.samples.shape[0] // 4000)]
    # consistency check (Section 6.2.4) on the held-out tests
    if held:
        f_cal, r_cal, p_cal = _model_on_tests(s, m_cal, held, n - h)
        f_nom, r_nom, p_nom = _model_on_tests(s, m, held, n - h)
        x_hx = experiment_features(s, held)
        d_hx = base.distance(x_hx)
        cal_chk = _check(s, base, x_hx, f_cal, r_cal)
        res["consistency"] = {"held_out": [r.name for r in held],
                              "d_experiments": d_hx.tolist(), "calibrated": cal_chk,
                              "nominal": _check(s, base, x_hx, f_nom, r_nom)}
        res["verdict"] = cal_chk["verdict"]
        d_cal = np.asarray(cal_chk["d"])
        art.d_model, art.d_heldout_exp = d_cal, d_hx
        ch0 = s.rmse_channels[0]
        art.overlay_channel = ch0
        art.overlays = {"measured": {ch0: _excerpt(held[0].channel(ch0).data)},
                        "calibrated": {ch0: p_cal[0]}, "nominal": {ch0: p_nom[0]}}
        art.overlay_record_s = held[0].n_samples / s.fs_hz
        res["consistency"]["overlay_test"] = art.overlay_test = held[0].name
    return res, art, m_cal
