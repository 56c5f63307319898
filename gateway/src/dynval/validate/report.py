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
        mpl = importlib.import_module("matplotlib")
    except ImportError as exc:
        raise ConfigError("the HTML report needs matplotlib (pip install "
                          "'dynval[validate]')") from exc
    mpl.use("Agg")
    return importlib.import_module("matplotlib.pyplot")


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    _plt().close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def plot_mahalanobis(a: Artifacts) -> Any:
    """Report Fig. 74-79 style: experiments (blue), simulation runs (black), best / worst
    RMSE runs (red / green circles), the model (green stars), the threshold (dashed)."""
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
            ax.semilogy(idx[a.best], a.d_runs[a.best], "o", mfc="none", mec="red", ms=9,
                        mew=1.4, label=f"lowest {len(a.best)} RMSE")
        if a.worst:
            ax.semilogy(idx[a.worst], a.d_runs[a.worst], "o", mfc="none", mec="green", ms=9,
                        mew=1.4, label=f"highest {len(a.worst)} RMSE")
        off += a.d_runs.size
    if a.d_model is not None:
        k = a.d_model.size
        ax.semilogy(np.arange(off + 1, off + k + 1), a.d_model, "*", color="limegreen",
                    mec="darkgreen", ms=12, label=f"{a.model_label} model")
    if math.isfinite(a.threshold):
        ax.axhline(a.threshold, ls="--", color="gray", lw=1, label="95 % threshold")
    ax.set_xlabel("experiment / run number")
    ax.set_ylabel("Mahalanobis distance D (eq. 39)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=4)
    return fig


def plot_space(a: Artifacts) -> Any:
    """Sampled parameter space (first two parameters) with the best / worst runs and the
    calibrated point (Fig. 71, 83, 89)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    assert a.x is not None
    j1 = 1 if a.x.shape[1] > 1 else 0
    ax.plot(a.x[:, 0], a.x[:, j1], ".", color="tab:blue", ms=4, label="design")
    if a.best:
        ax.plot(a.x[a.best, 0], a.x[a.best, j1], "o", mfc="none", mec="red", ms=8,
                label="lowest RMSE")
    if a.worst:
        ax.plot(a.x[a.worst, 0], a.x[a.worst, j1], "o", mfc="none", mec="green", ms=8,
                label="highest RMSE")
    if a.calibrated:
        v = list(a.calibrated.values())
        ax.plot(v[0], v[j1] if j1 else v[0], "*", color="limegreen", mec="darkgreen", ms=16,
                label="calibrated")
    ax.set_xlabel(a.param_names[0])
    ax.set_ylabel(a.param_names[j1])
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return fig


def plot_score(a: Artifacts) -> Any:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.2))
    assert a.score is not None
    i = np.arange(1, a.score.size + 1)
    ax.plot(i, a.score, ".", color="tab:blue", ms=4)
    ax.plot(i[a.best], a.score[a.best], "o", color="red", ms=5, label="lowest")
    ax.plot(i[a.worst], a.score[a.worst], "o", mfc="none", mec="green", ms=7, label="highest")
    ax.set_xlabel("run number")
    ax.set_ylabel("RMSE (eq. 47)")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return fig


def plot_posterior(a: Artifacts) -> Any:
    """Histograms on the diagonal, pair scatter below (Fig. 81), one colour per method."""
    plt = _plt()
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
                ax.set_xlabel(a.param_names[j], fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(a.param_names[i], fontsize=8)
            ax.tick_params(labelsize=7)
    fig.suptitle("posterior (emcee): GP emulator vs direct C model", fontsize=9)
    return fig


def plot_overlay(a: Artifacts, seconds: float = 0.6) -> Any:
    """Measured vs simulated time histories (Fig. 73, 85), a window from the middle."""
    plt = _plt()
    ch = a.overlay_channel
    meas = a.overlays["measured"][ch]
    n = meas.size
    w = min(n, int(seconds * a.fs_hz))
    i0 = max(0, n // 2 - w // 2)
    t = (np.arange(i0, i0 + w)) / a.fs_hz
    others = [k for k in a.overlays if k != "measured"]
    fig, axs = plt.subplots(len(others), 1, figsize=(8, 2.1 * len(others)), sharex=True,
                            squeeze=False)
    for ax, k in zip(axs[:, 0], others, strict=True):
        ax.plot(t, meas[i0:i0 + w], color="tab:blue", lw=1, label="measured")
        ax.plot(t, a.overlays[k][ch][i0:i0 + w], color="tab:red", lw=0.9, label=k)
        ax.set_ylabel(ch, fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(True, alpha=0.3)
    axs[-1, 0].set_xlabel("time (s)")
    return fig


def plot_psd(a: Artifacts) -> Any:
    plt = _plt()
    sig = importlib.import_module("scipy.signal")
    ch = a.overlay_channel
    fig, ax = plt.subplots(figsize=(8, 3.4))
    colours = {"measured": "black", "nominal": "tab:gray", "best run": "tab:red",
               "worst run": "tab:green", "calibrated": "tab:red"}
    for k, d in a.overlays.items():
        f, p = sig.welch(d[ch], fs=a.fs_hz, nperseg=1024)
        ax.semilogy(f, p, lw=1.5 if k == "measured" else 0.9, color=colours.get(k), label=k)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"PSD of {ch} (unit^2/Hz)")
    ax.set_xlim(0, a.fs_hz / 2)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def figures(a: Artifacts) -> list[tuple[str, str]]:
    """(caption, base64 PNG) of every plot the artifacts allow."""
    out: list[tuple[str, str]] = []
    out.append(("Mahalanobis distances: experiments, simulation runs (red/green: lowest/highest "
                "RMSE), the model; dashed: the verdict threshold", _png(plot_mahalanobis(a))))
    if a.x is not None and a.param_names:
        out.append(("Sampled parameter space with the best runs", _png(plot_space(a))))
    if a.score is not None:
        out.append(("RMSE of each run (eq. 47)", _png(plot_score(a))))
    if a.posteriors:
        out.append(("Posterior histograms and pair plot", _png(plot_posterior(a))))
    if "measured" in a.overlays and len(a.overlays) > 1:
        out.append(("Measured vs simulated time histories", _png(plot_overlay(a))))
        out.append(("Power spectral densities (Welch)", _png(plot_psd(a))))
    return out


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
        parts.append(_verdict_html(res["verdict"], res.get("model", "")))
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
        c = res["consistency"]
        for k in ("calibrated", "nominal"):
            v = c[k]["verdict"]
            rm = {ch: float(np.mean(x)) for ch, x in c[k]["rmse"].items()}
            parts.append(f"<p>Held-out check, {k} model: <b>{v['verdict']}</b> &mdash; "
                         f"{html.escape(v['meaning'])}; mean RMSE "
                         f"{html.escape(json.dumps({k2: round(v2, 5) for k2, v2 in rm.items()}))}"
                         "</p>")
    return "\n".join(parts)


def _verdict_html(v: dict[str, Any], model: str) -> str:
    """The verdict as the headline, the evidence under it with each one's role."""
    out = [f"<h2>Verdict: {html.escape(v['verdict'])} (exit code {v['exit_code']})</h2>",
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
