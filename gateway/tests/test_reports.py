"""The reports (issue 18, section 8): units on every axis and in every table, readable channel
names, green = best / red = worst, tick labels that do not overlap, one verdict with its
evidence (the HTML headline is the JSON verdict and the exit code's meaning), and every file
a command writes named in its log and in the discover HTML. The screenshot check renders the
reports in headless Chromium where it is installed (scripts/report_screenshots.sh does the
same for a person to look at)."""
from __future__ import annotations

import html
import json
import logging
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynval import labels as lb
from dynval import plotting as plot
from dynval.cli import main
from dynval.io.recording import Channel, Recording

pytest.importorskip("matplotlib")
colors: Any = pytest.importorskip("matplotlib.colors")

REPO = Path(__file__).resolve().parents[2]
BUMPER = REPO / "data" / "lanl4dof-sim" / "bumper"
M_S2 = "m/s\u00b2"
PSD_M_S2 = "PSD ((m/s\u00b2)\u00b2/Hz)"


# ---- labels and units ----------------------------------------------------------------------
def test_units_are_typeset_and_squared_with_brackets_where_needed() -> None:
    assert lb.psd_unit("m/s^2") == "(m/s\u00b2)\u00b2/Hz"
    assert lb.psd_unit("N") == "N\u00b2/Hz"
    assert lb.psd_unit("um") == "\u00b5m\u00b2/Hz"
    assert "no unit declared" in lb.psd_unit("")
    assert lb.pretty_unit("1") == ""  # dimensionless parameters go bare


def test_channel_label_takes_the_recordings_unit_then_the_models() -> None:
    from dynval import model as mdl

    m = mdl.load(BUMPER / "declared_model.json")
    rec = Recording("t", 640.0, [Channel("acc3_mps2", np.zeros(4), unit="g")])
    from_rec = lb.channel_labels(["acc3_mps2"], m, [rec])["acc3_mps2"]
    assert from_rec.unit == "g" and from_rec.psd_axis() == "PSD (g\u00b2/Hz)"
    # no recording: the name's suffix, else the SI unit of what the model predicts there
    assert lb.channel_labels(["acc3_mps2"], m)["acc3_mps2"].unit == "m/s^2"
    m2 = mdl.Model(masses_kg=m.masses_kg, stiffness_n_per_m=m.stiffness_n_per_m,
                   damping=m.damping, input=m.input, outputs={"top": mdl.Output("disp", 4)})
    top = lb.channel_labels(["top"], m2)["top"]
    assert top.unit == "m" and top.what == "DOF 4 displacement"
    lab = lb.channel_labels(["acc3_mps2"], m)["acc3_mps2"]
    assert lab.what == "DOF3 floor 2 acceleration"  # the model's DOF name, not the column
    assert lab.axis("residual") == f"DOF3 floor 2 acceleration residual ({M_S2})"


def test_residual_command_reports_each_channels_unit(capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    assert main(["-q", "residual", str(BUMPER / "declared_model.json"),
                 str(BUMPER / "test_low_01.csv"), "--json"]) == 0
    (t,) = json.loads(capsys.readouterr().out)["tests"]
    assert {c: v["unit"] for c, v in t["channels"].items()} == {
        f"acc{i}_mps2": "m/s^2" for i in range(1, 5)}


# ---- shared figure conventions ---------------------------------------------------------------
def test_crowded_ticks_are_found_and_untangled() -> None:
    """The overlap check fails on a crowded axis (so it can fail), and untangle_ticks fixes
    it on the rendered figure."""
    ticker: Any = pytest.importorskip("matplotlib.ticker")
    plt = plot.pyplot()
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot(np.linspace(-1.3e-4, 1.6e-4, 50), np.linspace(0, 0.018, 50))
    ax.xaxis.set_major_locator(ticker.MaxNLocator(nbins=12))
    ax.yaxis.set_major_locator(ticker.MaxNLocator(nbins=30))
    assert plot.overlapping_ticks(fig)
    plot.untangle_ticks(fig)
    assert plot.overlapping_ticks(fig) == []
    plt.close(fig)


def test_si_scale_shortens_tick_labels_and_envelope_keeps_peaks() -> None:
    assert plot.si_scale(np.array([-1.3e-4, 1.6e-4]), "m") == (1e6, "\u00b5m")
    assert plot.si_scale(np.array([20.0]), "N") == (1.0, "N")
    assert plot.si_scale(np.array([3.0]), "m/s^2") == (1.0, "m/s^2")  # no prefix on compounds
    y = np.random.default_rng(0).standard_normal(100_001)
    y[77_777], y[3] = 50.0, -40.0
    idx, v, per = plot.envelope(y)
    assert per > 1 and v.size <= plot.MAX_POINTS + 2
    assert v.max() == 50.0 and v.min() == -40.0 and np.all(np.diff(idx) >= 0)


# ---- discover --------------------------------------------------------------------------------
class _Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


@pytest.fixture(scope="module")
def discover_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """`dynval discover` on the bundled bumper data with relative output paths, once: its exit
    code, log lines, JSON, HTML and the result object the HTML was drawn from."""
    from dynval.discover import report

    work = tmp_path_factory.mktemp("discover")
    (work / "out").mkdir()
    seen: dict[str, Any] = {}
    real = report.write_html

    def keep(r: Any, doc: dict[str, Any], path: Any, **kw: Any) -> None:
        seen["result"] = r
        real(r, doc, path, **kw)

    rec = _Records()
    logger = logging.getLogger("dynval")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(work)
        mp.setattr(report, "write_html", keep)
        logger.addHandler(rec)
        try:
            rc = main(["discover", str(BUMPER / "declared_model.json"), str(BUMPER),
                       "--json", "out/d.json", "--html", "out/d.html",
                       "--model-out", "out/m.json"])
        finally:
            logger.removeHandler(rec)
    yield {"rc": rc, "log": rec.lines, "doc": json.loads((work / "out/d.json").read_text()),
           "html": (work / "out/d.html").read_text(), "html_path": work / "out/d.html",
           "result": seen["result"]}


def test_discover_logs_each_file_it_wrote_as_given(discover_run: dict[str, Any]) -> None:
    assert discover_run["rc"] == 1  # the declared model lacks the bumper
    wrote = [x for x in discover_run["log"] if x.startswith("wrote ")]
    assert wrote == ["wrote out/m.json (updated model)", "wrote out/d.json (JSON report)",
                     "wrote out/d.html (HTML report)"]


def test_discover_html_names_the_files_it_wrote(discover_run: dict[str, Any]) -> None:
    page = discover_run["html"]
    files = page[page.index("Files written by this run"):page.index("<h2>Figures")]
    for what, path in (("updated model", "out/m.json"), ("JSON report", "out/d.json"),
                       ("HTML report", "out/d.html")):
        assert f"{what}: <code>{path}</code>" in files


def test_discover_html_verdict_is_the_json_verdict_with_its_evidence(
        discover_run: dict[str, Any]) -> None:
    doc, page = discover_run["doc"], discover_run["html"]
    assert f"<h2>Verdict</h2><p class=\"verdict\"><b>{html.escape(doc['verdict'])}</b>" in page
    assert page.count("class=\"verdict\"") == 1  # one verdict
    evidence = page[page.index("<h3>Evidence</h3>"):page.index("<h2>RMSE per channel")]
    assert f"{100 * doc['held_out_reduction']:.1f} % lower" in evidence
    assert "noise floor" in evidence and "Paired feature test" in evidence


def test_discover_units_in_json_table_and_every_axis(discover_run: dict[str, Any]) -> None:
    from dynval.discover import report

    doc, r = discover_run["doc"], discover_run["result"]
    assert doc["units"] == {f"acc{i}_mps2": "m/s^2" for i in range(1, 5)}
    table = discover_run["html"].split("<h2>RMSE per channel</h2>")[1].split("</table>")[0]
    assert table.count(f"<td>{M_S2}</td>") == 4 and "DOF3 floor 2 acceleration" in table
    labels = report.labels_of(r, doc["units"])
    plt = plot.pyplot()
    fig, _ = report.figure_spectra(r, labels)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert len(panels) == 4
    for ax in panels:
        assert ax.get_ylabel() == PSD_M_S2 and ax.get_xlabel() == "frequency (Hz)"
        assert "acceleration" in ax.get_title()  # what it measures, not the column name
    plt.close(fig)
    fig, _ = report.figure_residual(r, labels)
    assert all(ax.get_ylabel() == f"residual\n({M_S2})" for ax in fig.axes)
    plt.close(fig)
    # a channel recorded in g is labelled in g: the unit is the recording's, not hard-coded
    fig, _ = report.figure_spectra(r, report.labels_of(r, {"acc1_mps2": "g"}))
    assert fig.axes[0].get_ylabel() == "PSD (g\u00b2/Hz)"
    plt.close(fig)


def test_discover_restoring_force_surface_ticks_do_not_overlap(
        discover_run: dict[str, Any]) -> None:
    from dynval.discover import report

    made = report.figure_surface(discover_run["result"])
    assert made is not None
    fig, _ = made
    ax = fig.axes[0]
    assert ax.get_xlabel().endswith("(\u00b5m)") and ax.get_ylabel().endswith("(N)")
    assert plot.overlapping_ticks(fig) == []
    plot.pyplot().close(fig)


def test_discover_long_record_is_drawn_as_a_stated_envelope(
        discover_run: dict[str, Any]) -> None:
    page = discover_run["html"]
    assert "minimum and maximum of every" in page  # 8192 samples > plot.MAX_POINTS
    assert "Zoom: 0.5 s of test" in page and "every sample drawn" in page


def _doc(effects: bool, p_before: float, p_after: float, verdict: str) -> dict[str, Any]:
    return {"effects": [{"label": "x"}] if effects else [], "verdict": verdict,
            "held_out_reduction": 0.936 if effects else 0.0,
            "rmse_after": {"held_out": {"a_mps2": 0.03}}, "noise_floor": {"a_mps2": 0.025},
            "mahalanobis": {"before": 0.77, "after": 0.21, "p_before": p_before,
                            "p_after": p_after}}


def test_discover_evidence_that_disagrees_with_the_verdict_is_explained() -> None:
    from dynval.discover import report

    lab = {"a_mps2": lb.ChannelLabel("a_mps2", "m/s^2", "DOF 1 acceleration")}
    found = _doc(True, 0.002, 0.041, "the model lacks: x")
    note = report.agreement(found)
    assert note is not None and "p = 0.041" in note and "not all" in note
    lines = report.evidence(found, lab)
    assert any("updated model p = 0.041 < 0.05: its features differ" in x for x in lines)
    assert any(f"a 1.20 \u00d7 (0.03 against 0.025 {M_S2})" in x for x in lines)
    assert report.agreement(_doc(True, 0.002, 0.30, "the model lacks: x")) is None
    floor = _doc(False, 0.01, 0.01, "no effect: the declared model explains the tests to the "
                 "noise floor")
    assert "too small" in (report.agreement(floor) or "")


# ---- validate / calibrate ---------------------------------------------------------------------
def _artifacts() -> Any:
    from dynval.validate.study import Artifacts

    rng = np.random.default_rng(1)
    a = Artifacts(640.0, param_names=["zeta2", "k3"], param_units=["1", "N/m"],
                  x=rng.uniform(size=(30, 2)), d_exp=rng.uniform(1, 5, 10),
                  d_runs=rng.uniform(1, 100, 30), score=rng.uniform(0.1, 1, 30),
                  best=[0, 1], worst=[2, 3], threshold=20.0, d_model=rng.uniform(1, 5, 10))
    t = np.arange(4096) / 640.0
    a.overlay_channel = "acc3_mps2"
    a.overlays = {"measured": {"acc3_mps2": np.sin(2 * np.pi * 30 * t)},
                  "best run": {"acc3_mps2": np.sin(2 * np.pi * 30 * t + 0.1)},
                  "worst run": {"acc3_mps2": np.sin(2 * np.pi * 31 * t)}}
    a.labels = lb.channel_labels(["acc3_mps2"])
    return a


def _line(fig: Any, label: str) -> Any:
    (line,) = [x for x in fig.axes[0].get_lines() if x.get_label().startswith(label)]
    return line


def _is(colour: Any, name: str) -> bool:
    return bool(colors.to_rgba(colour) == colors.to_rgba(name))


def test_validate_best_is_green_worst_is_red() -> None:
    from dynval.validate import report

    a = _artifacts()
    plt = plot.pyplot()
    for fig, best, worst in ((report.plot_mahalanobis(a), "lowest", "highest"),
                             (report.plot_space(a), "lowest", "highest"),
                             (report.plot_score(a), "lowest", "highest")):
        b, w = _line(fig, best), _line(fig, worst)
        assert _is(b.get_markeredgecolor(), "tab:green") and _is(w.get_markeredgecolor(),
                                                               "tab:red")
        plt.close(fig)
    fig = report.plot_psd(a)
    assert _is(_line(fig, "best run").get_color(), "tab:green")
    assert _is(_line(fig, "worst run").get_color(), "tab:red")
    plt.close(fig)


def test_validate_axes_carry_units() -> None:
    from dynval.validate import report

    a = _artifacts()
    plt = plot.pyplot()
    fig = report.plot_psd(a)
    assert fig.axes[0].get_ylabel() == PSD_M_S2 and "unit^2" not in fig.axes[0].get_ylabel()
    plt.close(fig)
    fig = report.plot_score(a)
    assert fig.axes[0].get_ylabel() == f"RMSE of acc3 ({M_S2})"
    plt.close(fig)
    fig = report.plot_overlay(a)
    assert all(ax.get_ylabel() == f"acc3 ({M_S2})" for ax in fig.axes)
    plt.close(fig)
    fig = report.plot_space(a)
    assert fig.axes[0].get_xlabel() == "zeta2" and fig.axes[0].get_ylabel() == "k3 (N/m)"
    plt.close(fig)
    a.labels = lb.channel_labels(["acc3_mps2", "acc4_mps2"])  # several: normalised, no unit
    fig = report.plot_score(a)
    assert fig.axes[0].get_ylabel() == "normalised RMSE (no unit)"
    plt.close(fig)


def test_posterior_ticks_do_not_overlap() -> None:
    from dynval.validate import report

    a = _artifacts()
    rng = np.random.default_rng(2)
    a.posteriors = {"gp": np.column_stack([rng.normal(0.044, 0.006, 4000),
                                           rng.normal(0.010, 0.0015, 4000)])}
    fig = report.plot_posterior(a)
    assert plot.overlapping_ticks(fig) == []
    plot.pyplot().close(fig)


@pytest.mark.parametrize("features, tests", [("peak,std@acc3,acc4", "shared"),
                                             ("peak@acc4", "shared"),
                                             ("peak,std@acc3,acc4", "bundled")])
def test_validate_headline_is_the_json_verdict_and_the_exit_code(
        features: str, tests: str, shared_data: Path, tmp_path: Path) -> None:
    """PASS, FAIL and INCONCLUSIVE (2 tests): the HTML's one headline names the JSON verdict,
    the exit code the command returned and its meaning; the evidence says how it reads."""
    from dynval.validate import verdict as vd

    folder = shared_data / "synthetic" / "lanl4dof-bumper" if tests == "shared" else BUMPER
    out_j, out_h = tmp_path / "v.json", tmp_path / "v.html"
    rc = main(["-q", "validate", "--model", str(folder / "declared_model.json"),
               "--experiments", str(folder), "--features", features, "--workers", "1",
               "--json", str(out_j), "--html", str(out_h)])
    v = json.loads(out_j.read_text())["verdict"]
    page = out_h.read_text()
    assert rc == vd.EXIT[v["verdict"]] == v["exit_code"]
    assert page.count("<h2>Verdict") == 1
    assert (f"<h2>Verdict: {v['verdict']} (exit code {rc}: "
            f"{vd.EXIT_MEANING[v['verdict']]})</h2>") in page
    want = {("peak,std@acc3,acc4", "shared"): "PASS", ("peak@acc4", "shared"): "FAIL",
            ("peak,std@acc3,acc4", "bundled"): "INCONCLUSIVE"}[(features, tests)]
    assert v["verdict"] == want
    assert "together: " in page


def test_verdict_exit_codes_are_not_the_error_codes() -> None:
    """CI tells an INCONCLUSIVE study from a crash (3) and from bad input (2)."""
    from dynval import cli
    from dynval.validate import verdict as vd

    errors = {cli.EXIT_INPUT, cli.EXIT_INTERNAL, cli.EXIT_USAGE, cli.EXIT_INTERRUPTED,
              cli.EXIT_PIPE}
    assert vd.EXIT == {"PASS": 0, "FAIL": 1, "INCONCLUSIVE": 4}
    assert not errors & set(vd.EXIT.values())


def _verdict(word: str, median_d: float) -> dict[str, Any]:
    return {"verdict": word, "evidence": {"mahalanobis": {"median_d": median_d,
                                                          "threshold": 9.5}}}


def test_validate_reads_the_two_pieces_of_evidence_together() -> None:
    from dynval.validate import verdict as vd

    assert "yet the paired test finds no difference" in vd.agreement(_verdict("PASS", 89.7))
    assert "bias the scatter hides" in vd.agreement(_verdict("FAIL", 3.0))
    assert vd.agreement(_verdict("PASS", 3.0)).endswith("the paired test agrees: PASS")
    assert "size, not a test" in vd.agreement(_verdict("INCONCLUSIVE", 3.0))
    # 2 tests for 4 features: a singular baseline gives a negative "distance" (-2.2e15 was
    # reported as inside the scatter)
    assert "not usable" in vd.agreement(_verdict("INCONCLUSIVE", -2.2e15))


def test_calibrate_nominal_check_is_marked_as_not_the_verdict() -> None:
    from dynval.validate import report

    def check(word: str) -> dict[str, Any]:
        return {"verdict": {"verdict": word, "meaning": "m"}, "rmse": {"acc3_mps2": [0.1, 0.2]}}

    part = report._consistency_html({
        "rmse_channels": ["acc3_mps2"], "units": {"acc3_mps2": "m/s^2"},
        "consistency": {"held_out": ["a", "b"], "calibrated": check("PASS"),
                        "nominal": check("FAIL")}})
    assert "calibrated model (the verdict): <b>PASS</b>" in part
    assert "nominal model (for comparison, not the verdict): <b>FAIL</b>" in part
    assert f"acc3 0.15 {M_S2}" in part


# ---- the real browser ------------------------------------------------------------------------
def _chromium() -> str | None:
    return next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser",
                                                       "google-chrome")) if p), None)


def test_discover_report_renders_in_a_headless_browser(discover_run: dict[str, Any],
                                                       tmp_path: Path) -> None:
    """Chromium loads the page and draws its figures (a blank or broken page has almost no
    dark pixels; the embedded PNGs are most of them)."""
    image: Any = pytest.importorskip("PIL.Image")
    exe = _chromium()
    if exe is None:
        pytest.skip("no chromium (apt-get install chromium)")
    shot = tmp_path / "d.png"
    subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    f"--screenshot={shot}", "--window-size=1280,4000",
                    discover_run["html_path"].as_uri()], check=True, timeout=120,
                   capture_output=True)
    px = np.asarray(image.open(shot).convert("L"))
    assert px.shape == (4000, 1280)
    figures_part = px[1600:]  # below the tables: the figures
    assert np.mean(figures_part < 128) > 0.01


def test_validate_report_draws_the_catalogue_features_it_computed() -> None:
    """Issue 19: a catalogue term in the spec brings its figure into the report (one per kind
    of figure: ks and ad share the distribution plot), drawn on the overlay channel."""
    from dynval.validate import report

    a = _artifacts()
    before = len(report.figures(a))
    a.feature_names = ["std", "ks", "ad", "acf_corr"]
    caps = [c for c, _ in report.figures(a)][before:]
    assert len(caps) == 2
    assert caps[0].startswith("ks: Kolmogorov-Smirnov") and "; ad: Anderson-Darling" in caps[0]
    assert caps[1].startswith("acf_corr: correlation coefficient") and caps[1].endswith("acc3")


def test_validate_report_draws_the_frf_of_the_input_output_features() -> None:
    """coh / modal_* in the spec bring the FRF and coherence figure (report Fig. 43-47) of the
    overlay channel to the input, measured and simulated, with the input's unit."""
    from dynval.validate import report

    a = _artifacts()
    rng = np.random.default_rng(2)
    a.overlay_input = rng.standard_normal(4096)
    a.overlays = {k: {"acc3_mps2": np.convolve(a.overlay_input, [1.0, 0.5, g], "same")}
                  for k, g in (("measured", 0.2), ("nominal", 0.25))}
    a.feature_names = ["coh", "modal_f3"]
    cap, _ = report.figures(a)[-1]
    assert cap.startswith("FRF (H1) and coherence to the input (coh, modal_f3")
    fig = report.plot_frf(a, {k: d["acc3_mps2"] for k, d in a.overlays.items()},
                          lb.channel_labels(["acc3_mps2"])["acc3_mps2"])
    assert fig.axes[0].get_ylabel() == f"|H1| ({M_S2}/N)"
    coh = fig.axes[1].get_lines()[0].get_ydata()  # a noise-free FIR: coherence 1
    assert float(np.median(coh)) > 0.99
    plot.pyplot().close(fig)
