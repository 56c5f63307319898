"""JSON and self-contained HTML reports of a validation or calibration study (matplotlib
PNGs embedded as base64; one file, no external assets)."""
from __future__ import annotations

import base64
import html
import importlib
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dynval import labels as lb
from dynval import plotting as plot
from dynval.errors import ConfigError, InputFileError
from dynval.validate import verdict as verdict_mod
from dynval.validate.study import Artifacts


def _clean(o: Any) -> Any:
    """NaN/Inf -> null (strict JSON), numpy scalars -> Python."""
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, (np.floating, float)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, np.integer):
        return int(o)
    return o


def write_json(result: dict[str, Any], path: Path | str) -> None:
    p = Path(path)
    try:
        p.write_text(json.dumps(_clean(result), indent=1, allow_nan=False) + "\n",
                     encoding="utf-8")
    except OSError as exc:
        raise InputFileError(p, f"cannot write: {exc.strerror or exc}") from exc


def _plt() -> Any:
    try:
        return plot.pyplot()
    except ImportError as exc:
        raise ConfigError("the HTML report needs matplotlib (pip install "
                          "'dynval[validate]')") from exc


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    _plt().close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


# line colour of each overlay, by role (plotting's convention: green best, red worst)
OVERLAY_COLOURS = {"measured": plot.MEASURED, "nominal": plot.NEUTRAL,
                   "calibrated": plot.MODEL, "best run": plot.BEST, "worst run": plot.WORST}


def _label(a: Artifacts, ch: str) -> lb.ChannelLabel:
    return a.labels.get(ch) or lb.channel_labels([ch])[ch]


def param_axis(a: Artifacts, j: int) -> str:
    """'k3 (N/m)'; a dimensionless parameter (zeta) goes bare."""
    u = lb.pretty_unit(a.param_units[j]) if j < len(a.param_units) else ""
    return f"{a.param_names[j]} ({u})" if u else a.param_names[j]


def score_axis(a: Artifacts) -> str:
    """The y label of the per-run accuracy: an RMSE in the channel's unit (one channel), or
    the normalised RMSE (RMSE / measured RMS, no unit) combined over several."""
    chans = list(a.labels) or [a.overlay_channel]
    if len(chans) == 1:
        lab = _label(a, chans[0])
        return f"RMSE of {lab.short} ({lab.unit_text})"
    return "normalised RMSE (no unit)"


def score_caption(a: Artifacts) -> str:
    chans = list(a.labels) or [a.overlay_channel]
    if len(chans) == 1:
        return f"RMSE (eq. 47) of {_label(a, chans[0]).title} of each run"
    return ("Normalised RMSE of each run: the RMS over " + ", ".join(
        _label(a, c).short for c in chans) + " of each channel's RMSE (eq. 47) divided by its "
        "measured RMS")


def plot_mahalanobis(a: Artifacts) -> Any:
    """Report Fig. 74-79 style: experiments (blue), simulation runs (black), lowest / highest
    RMSE runs (green / red circles), the model (purple stars), the threshold (dashed)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.2))
    n_e = 0
    if a.d_exp is not None:
        n_e = a.d_exp.size
        ax.semilogy(np.arange(1, n_e + 1), a.d_exp, "o", color="tab:blue", ms=5,
                    label="experiments (baseline)")
    off = n_e
    if a.d_heldout_exp is not None:
        k = a.d_heldout_exp.size
        ax.semilogy(np.arange(off + 1, off + k + 1), a.d_heldout_exp, "s", color="tab:blue",
                    mfc="none", ms=6, label="held-out experiments")
        off += k
    if a.d_runs is not None:
        idx = np.arange(off + 1, off + a.d_runs.size + 1)
        ax.semilogy(idx, a.d_runs, ".", color="black", ms=4, label="simulation runs")
        if a.best:
            ax.semilogy(idx[a.best], a.d_runs[a.best], "o", mfc="none", mec=plot.BEST, ms=9,
                        mew=1.4, label=f"lowest {len(a.best)} RMSE")
        if a.worst:
            ax.semilogy(idx[a.worst], a.d_runs[a.worst], "o", mfc="none", mec=plot.WORST, ms=9,
                        mew=1.4, label=f"highest {len(a.worst)} RMSE")
        off += a.d_runs.size
    if a.d_model is not None:
        k = a.d_model.size
        ax.semilogy(np.arange(off + 1, off + k + 1), a.d_model, "*", color=plot.MODEL,
                    mec="black", mew=0.5, ms=12, label=f"{a.model_label} model")
    if math.isfinite(a.threshold):
        ax.axhline(a.threshold, ls="--", color="gray", lw=1, label="95 % threshold")
    hidden = sum(int(np.sum(~(np.asarray(d) > 0))) for d in (a.d_exp, a.d_heldout_exp,
                                                              a.d_runs, a.d_model)
                 if d is not None)
    if hidden:  # a log axis drops them silently; a singular baseline makes them negative
        ax.text(0.01, 0.02, f"{hidden} distance(s) <= 0 or undefined not drawn (a singular "
                "baseline covariance: too few tests)", transform=ax.transAxes, fontsize=8,
                color=plot.WORST)
    ax.set_xlabel("experiment / run number")
    ax.set_ylabel("Mahalanobis distance D (eq. 39, no unit)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=4)
    plot.untangle_ticks(fig)
    return fig


def plot_space(a: Artifacts) -> Any:
    """Sampled parameter space (first two parameters) with the lowest / highest RMSE runs and
    the calibrated point (Fig. 71, 83, 89)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    assert a.x is not None
    j1 = 1 if a.x.shape[1] > 1 else 0
    ax.plot(a.x[:, 0], a.x[:, j1], ".", color="tab:blue", ms=4, label="design")
    if a.best:
        ax.plot(a.x[a.best, 0], a.x[a.best, j1], "o", mfc="none", mec=plot.BEST, ms=8,
                mew=1.4, label="lowest RMSE")
    if a.worst:
        ax.plot(a.x[a.worst, 0], a.x[a.worst, j1], "o", mfc="none", mec=plot.WORST, ms=8,
                mew=1.4, label="highest RMSE")
    if a.calibrated:
        v = list(a.calibrated.values())
        ax.plot(v[0], v[j1] if j1 else v[0], "*", color=plot.MODEL, mec="black", mew=0.5,
                ms=16, label="calibrated")
    ax.set_xlabel(param_axis(a, 0))
    ax.set_ylabel(param_axis(a, j1))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    plot.untangle_ticks(fig)
    return fig


def plot_score(a: Artifacts) -> Any:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.2))
    assert a.score is not None
    i = np.arange(1, a.score.size + 1)
    ax.plot(i, a.score, ".", color="tab:blue", ms=4)
    ax.plot(i[a.best], a.score[a.best], "o", color=plot.BEST, ms=6, label="lowest")
    ax.plot(i[a.worst], a.score[a.worst], "o", mfc="none", mec=plot.WORST, mew=1.4, ms=7,
            label="highest")
    ax.set_xlabel("run number")
    ax.set_ylabel(score_axis(a))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    plot.untangle_ticks(fig)
    return fig


def plot_posterior(a: Artifacts) -> Any:
    """Histograms on the diagonal, pair scatter below (Fig. 81), one colour per method."""
    plt = _plt()
    ticker = importlib.import_module("matplotlib.ticker")
    k = len(a.param_names)
    fig, axs = plt.subplots(k, k, figsize=(2.6 * k + 0.6, 2.4 * k + 0.4), squeeze=False)
    colours = {"gp": "tab:blue", "direct": "tab:orange"}
    for i in range(k):
        for j in range(k):
            ax = axs[i][j]
            if j > i:
                ax.axis("off")
                continue
            for name, s in a.posteriors.items():
                c = colours.get(name, "gray")
                if i == j:
                    ax.hist(s[:, i], bins=40, density=True, histtype="step", color=c, lw=1.4,
                            label=name)
                else:
                    ax.plot(s[:, j], s[:, i], ",", color=c, alpha=0.5)
            if i == j:
                ax.set_yticks([])
                if i == 0:
                    ax.legend(fontsize=7)
            if i == k - 1:
                ax.set_xlabel(param_axis(a, j), fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(param_axis(a, i), fontsize=8)
            ax.xaxis.set_major_locator(ticker.MaxNLocator(nbins=4))
            ax.tick_params(labelsize=7)
    fig.suptitle("posterior (emcee): GP emulator vs direct C model", fontsize=9)
    plot.untangle_ticks(fig)
    return fig


def _overlay_window(a: Artifacts, n: int, seconds: float) -> tuple[int, int]:
    w = min(n, round(seconds * a.fs_hz))
    i0 = max(0, n // 2 - w // 2)
    return i0, w


def plot_overlay(a: Artifacts, seconds: float = 0.6) -> Any:
    """Measured vs simulated time histories (Fig. 73, 85), a window from the middle."""
    plt = _plt()
    ch = a.overlay_channel
    lab = _label(a, ch)
    meas = a.overlays["measured"][ch]
    i0, w = _overlay_window(a, meas.size, seconds)
    t = (np.arange(i0, i0 + w)) / a.fs_hz
    others = [k for k in a.overlays if k != "measured"]
    fig, axs = plt.subplots(len(others), 1, figsize=(8, 2.1 * len(others)), sharex=True,
                            squeeze=False)
    for ax, k in zip(axs[:, 0], others, strict=True):
        ax.plot(t, meas[i0:i0 + w], color=plot.MEASURED, lw=1, label="measured")
        ax.plot(t, a.overlays[k][ch][i0:i0 + w], color=OVERLAY_COLOURS.get(k, plot.MODEL),
                lw=0.9, label=k)
        ax.set_ylabel(f"{lab.short} ({lab.unit_text})", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(True, alpha=0.3)
    axs[0, 0].set_title(lab.title, fontsize=9, loc="left")
    axs[-1, 0].set_xlabel("time (s)")
    plot.untangle_ticks(fig)
    return fig


def plot_psd(a: Artifacts) -> Any:
    plt = _plt()
    sig = importlib.import_module("scipy.signal")
    ch = a.overlay_channel
    lab = _label(a, ch)
    fig, ax = plt.subplots(figsize=(8, 3.4))
    for k, d in a.overlays.items():
        f, p = sig.welch(d[ch], fs=a.fs_hz, nperseg=1024)
        ax.semilogy(f, p, lw=1.5 if k == "measured" else 0.9,
                    color=OVERLAY_COLOURS.get(k, plot.MODEL), label=k)
    ax.set_title(lab.title, fontsize=9, loc="left")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(lab.psd_axis())
    ax.set_xlim(0, a.fs_hz / 2)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    plot.untangle_ticks(fig)
    return fig


def figures(a: Artifacts) -> list[tuple[str, str]]:
    """(caption, base64 PNG) of every plot the artifacts allow."""
    out: list[tuple[str, str]] = []
    marks = " (green / red circles: the runs of lowest / highest RMSE)" if a.best else ""
    out.append(("Mahalanobis distances of the experiments, the simulation runs" + marks
                + f" and the {a.model_label} model; dashed: the 95 % limit of the "
                "test-to-test scatter (the size of a discrepancy, not the verdict)",
                _png(plot_mahalanobis(a))))
    if a.x is not None and a.param_names:
        out.append(("Sampled parameter space" + (marks or "")
                    + ("; star: the calibrated point" if a.calibrated else ""),
                    _png(plot_space(a))))
    if a.score is not None:
        out.append((score_caption(a) + marks, _png(plot_score(a))))
    if a.posteriors:
        out.append(("Posterior histograms and pair plot", _png(plot_posterior(a))))
    if "measured" in a.overlays and len(a.overlays) > 1:
        n = a.overlays["measured"][a.overlay_channel].size
        i0, w = _overlay_window(a, n, 0.6)
        test = f" of test {a.overlay_test}" if a.overlay_test else ""
        first = (f" (these figures: its first {n / a.fs_hz:g} s of {a.overlay_record_s:g} s)"
                 if a.overlay_record_s > n / a.fs_hz else "")
        out.append((f"Measured vs simulated time histories{test}: {w / a.fs_hz:.3g} s from "
                    f"{i0 / a.fs_hz:.2f} s of {n / a.fs_hz:g} s, every sample drawn{first}",
                    _png(plot_overlay(a))))
        out.append((f"Power spectral densities (Welch){test}", _png(plot_psd(a))))
        out += _catalogue_figures(a, test)
    return out


def _catalogue_figures(a: Artifacts, test: str) -> list[tuple[str, str]]:
    """The figure of each catalogue feature the spec computes (one per kind of figure), drawn
    for the overlay channel's measured and simulated records."""
    from dynval.catalogue import signal_plots, signal_terms

    lab = _label(a, a.overlay_channel)
    series = {k: d[a.overlay_channel] for k, d in a.overlays.items()}
    by_figure: dict[Any, list[str]] = {}
    for name in dict.fromkeys(a.feature_names):
        if name in signal_plots.FIGURES:
            by_figure.setdefault(signal_plots.FIGURES[name], []).append(name)
    out = []
    for draw, names in by_figure.items():
        what = "; ".join(f"{n}: {signal_terms.TERMS[n].doc}" for n in names)
        out.append((f"{what}{test}, {lab.short}",
                    _png(draw(series, a.fs_hz, lab.unit_text))))
    out += [(_check_caption(o), _png(plot_check(o))) for o in a.checks]
    io = [n for n in dict.fromkeys(a.feature_names) if n == "coh" or n.startswith("modal_")]
    if io and a.overlay_input is not None:
        out.append((f"FRF (H1) and coherence to the input ({', '.join(io)}: 5.1, 5.3.1; "
                    f"Hann 1024, 50 %){test}, {lab.short}; shaded: the input's band; the "
                    "simulation drawn without the sensor noise its features carry",
                    _png(plot_frf(a, series, lab))))
    return out


def _check_caption(o: Any) -> str:
    s = o.summary()
    mo = s["model"]
    return (f"{s['check'].capitalize()} check (5.3.1): H1 and coherence of "
            f"{s['groups'][0]} against {s['groups'][1]}, measured (black, grey) and the model "
            f"driven by the same forces with the same sensor noise (purple, pink); title: the "
            f"tests' scalars; the model's: z2(H1) {mo['z2']:.2f}, z2(coherence) "
            f"{mo['z2_coh']:.2f} ({'holds' if mo['holds'] else 'fails'}); {s['meaning']}")


def plot_check(o: Any) -> Any:
    """A linearity / reciprocity check: both groups' H1 and coherence, tests and model."""
    from dynval.catalogue import modal_plots

    (ma, mb), (sa, sb) = o.frfs["measured"], o.frfs["model"]
    la, lb_ = o.labels
    curves = [(f"tests: {la}", ma, 0, plot.MEASURED), (f"tests: {lb_}", mb, 0, plot.NEUTRAL),
              (f"model: {la}", sa, 0, plot.MODEL), (f"model: {lb_}", sb, 0, "tab:pink")]
    return modal_plots.plot_frf(curves, o.measured.band_hz, o.measured)


def plot_frf(a: Artifacts, series: dict[str, np.ndarray], lab: lb.ChannelLabel) -> Any:
    """H1 and coherence of the overlay channel to the input, measured and simulated."""
    from dynval.catalogue import frf, modal_plots
    from dynval.validate import measurement

    assert a.overlay_input is not None
    u = a.overlay_input
    curves = [(k, frf.estimate(u, {"y": y}, a.fs_hz), 0, OVERLAY_COLOURS.get(k, plot.MODEL))
              for k, y in series.items()]
    return modal_plots.plot_frf(curves, measurement.input_band(u, a.fs_hz),
                                unit=f"{lab.unit_text}/{a.input_unit}")


def _table(rows: Sequence[Sequence[Any]], head: Sequence[str]) -> str:
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.5g}"
        return html.escape(str(v))
    h = "".join(f"<th>{html.escape(x)}</th>" for x in head)
    b = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{b}</table>"


def _summary_html(res: dict[str, Any]) -> str:
    parts = []
    b = res["baseline"]
    parts.append(f"<p>Features: <code>{html.escape(res['features']['spec'])}</code> "
                 f"({b['n_features']} values); baseline of {b['n_tests']} tests, "
                 f"{b['covariance']} covariance; threshold {b['threshold_kind']} "
                 f"{b['threshold']:.4g} (empirical 95th percentile {b['empirical_threshold']:.4g})"
                 "</p>")
    if "verdict" in res:
        what = ("held-out check of the calibrated model" if res.get("kind") == "calibrate"
                else "")
        parts.append(_verdict_html(res["verdict"], res.get("model", ""), what))
    if res.get("checks"):
        parts.append("<h3>Linearity and reciprocity checks (z2 limit "
                     f"{res['checks'][0]['limit']:g})</h3>" + _table(
                         [[c["check"], c["channel"], " vs ".join(c["groups"]),
                           f"{c['band_hz'][0]:g}-{c['band_hz'][1]:g}",
                           c["measured"]["z2"], c["measured"]["z2_coh"], c["model"]["z2"],
                           c["model"]["z2_coh"], "yes" if c["consistent"] else "NO"]
                          for c in res["checks"]],
                         ["check", "channel", "groups", "band (Hz)", "tests z2(H1)",
                          "tests z2(coh)", "model z2(H1)", "model z2(coh)",
                          "model reproduces it"]))
    if "doe" in res:
        d = res["doe"]
        parts.append(f"<p>DOE: {d['design']} with {d['runs']} runs driven by {d['ref_test']}; "
                     f"Spearman(D, RMSE) = {d['spearman_d_vs_rmse']:.3f}; best run "
                     f"{html.escape(json.dumps(d['best_run']))}.</p>")
    if "pca" in res:
        parts.append(f"<p>PCA: {res['pca']['n_components_98']} components hold 98 % "
                     "(cumulative: " + ", ".join(f"{100 * c:.2f} %" for c in
                                                res["pca"]["cumulative"][:5]) + ").</p>")
    if "sensitivity" in res:
        t = res["sensitivity"]["table"]
        ps = list(t[0]["r2"]) if t else []
        parts.append("<h3>ANOVA R<sup>2</sup> (eq. 44), share in %</h3>" + _table(
            [[r["feature"], *(100 * r["share"][p] for p in ps),
              *(r["r2"][p] for p in ps)] for r in t],
            ["feature", *(f"{p} %" for p in ps), *(f"R2 {p}" for p in ps)]))
    if "posterior" in res:
        rows = []
        for meth, post in res["posterior"].items():
            for n, v in post["parameters"].items():
                rows.append([meth, n, v["mean"], v["std"], v["q2.5"], v["q97.5"],
                             post["acceptance"], post["n_model_runs"], post["seconds"]])
        parts.append("<h3>Posterior</h3>" + _table(rows, [
            "method", "parameter", "mean", "std", "2.5 %", "97.5 %", "acceptance",
            "model runs", "s"]))
        for meth, post in res["posterior"].items():
            cm = [[round(c, 3) for c in r] for r in post["correlation"]]
            parts.append(f"<p>{meth}: correlation matrix {html.escape(json.dumps(cm))}</p>")
    if "consistency" in res:
        parts.append(_consistency_html(res))
    return "\n".join(parts)


def _consistency_html(res: dict[str, Any]) -> str:
    """calibrate's held-out check: the calibrated model's (the verdict) and, for comparison,
    the nominal model's, with the mean held-out RMSE in each channel's unit."""
    c = res["consistency"]
    labels = lb.channel_labels(res.get("rmse_channels", []), units=res.get("units"))
    rows = []
    for k, role in (("calibrated", "the verdict"), ("nominal", "for comparison, not the "
                                                                "verdict")):
        v = c[k]["verdict"]
        rm = ", ".join(f"{labels[ch].short} {labels[ch].value(float(np.mean(x)))}"
                       for ch, x in c[k]["rmse"].items() if ch in labels)
        rows.append(f"<li>{k} model ({role}): <b>{html.escape(v['verdict'])}</b> &mdash; "
                    f"{html.escape(v['meaning'])}; mean held-out RMSE {html.escape(rm)}</li>")
    return (f"<h3>Held-out check on {len(c['held_out'])} tests</h3><ul>" + "".join(rows)
            + "</ul>")


def _verdict_html(v: dict[str, Any], model: str, what: str = "") -> str:
    """The verdict as the headline (``what``: what it checks, when not the model itself), the
    evidence under it with each one's role and how they read together."""
    out = [f"<h2>Verdict{', ' + html.escape(what) if what else ''}: "
           f"{html.escape(v['verdict'])} (exit code {v['exit_code']}: "
           f"{html.escape(verdict_mod.EXIT_MEANING[v['verdict']])})</h2>",
           f"<p>{html.escape(verdict_mod.headline(v, model))}</p>"]
    if v.get("evidence"):
        out.append("<ul>" + "".join(f"<li>{html.escape(line.strip())}</li>"
                                     for line in verdict_mod.evidence_lines(v)) + "</ul>")
    return "\n".join(out)


def write_html(result: dict[str, Any], art: Artifacts, path: Path | str,
               title: str | None = None) -> None:
    figs = figures(art)
    ttl = title or f"dynval {result.get('kind', 'validate')}: {result.get('model', '')}"
    body = [f"<h1>{html.escape(ttl)}</h1>", _summary_html(result)]
    for cap, b64 in figs:
        body.append(f"<figure><img src=\"data:image/png;base64,{b64}\" alt=\"{html.escape(cap)}\">"
                    f"<figcaption>{html.escape(cap)}</figcaption></figure>")
    doc = ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>" + html.escape(ttl)
           + "</title><style>body{font-family:sans-serif;max-width:980px;margin:auto;padding:1em}"
           "table{border-collapse:collapse;font-size:90%}td,th{border:1px solid #ccc;"
           "padding:2px 6px;text-align:right}figure{margin:1.5em 0}img{max-width:100%}"
           "figcaption{font-size:90%;color:#444}</style></head><body>"
           + "\n".join(body) + "</body></html>\n")
    p = Path(path)
    try:
        p.write_text(doc, encoding="utf-8")
    except OSError as exc:
        raise InputFileError(p, f"cannot write: {exc.strerror or exc}") from exc
