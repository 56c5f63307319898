"""The discover report: a JSON document (schema: gateway/docs/discover-schema.md) and a
self-contained HTML page with matplotlib figures embedded as PNG (residual time histories with
the detected events, the restoring-force surface, spectra before/after, the candidate
ranking). matplotlib is optional: without it the HTML carries the tables only."""
from __future__ import annotations

import base64
import html
import importlib
import io
import json
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from dynval.discover import effects as fx
from dynval.discover import trace as tr
from dynval.discover.loop import DiscoverResult

log = logging.getLogger(__name__)
signal: Any = importlib.import_module("scipy.signal")

SCHEMA = "dynval-discover/1"


def _f(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _evidence_list(rd: Any) -> list[dict[str, Any]]:
    by_label = {i["candidate"].label: i for i in rd.fits}
    out = []
    for rank, e in enumerate(rd.evidence, 1):
        d: dict[str, Any] = {"rank": rank, "type": e.cand.type, "location": e.cand.location,
                             "label": e.cand.label, "evidence": _f(e.r2),
                             "available": e.cand.available}
        if e.cand.note:
            d["note"] = e.cand.note
        if e.shape:
            d["shape"] = {k: _f(v) for k, v in e.shape.items()}
        if e.cand.type != "none":
            d["amplitude"] = _f(e.amp)
        info = by_label.get(e.cand.label)
        if info is not None:
            res = info["fit"]
            d["fit"] = {"parameters": {n: {"value": v, "uncertainty": _f(s), "unit": u}
                                       for n, v, s, u in zip(res.names, res.values, res.sigma,
                                                             res.units, strict=True)},
                        "held_out_gain": _f(info["held_gain"]),
                        "held_out_worst_test_change": _f(info["held_worst_test_change"]),
                        "delta_bic": _f(info["delta_bic"]), "accepted": info["accepted"],
                        "n_evaluations": res.nfev}
        out.append(d)
    return out


def to_json(r: DiscoverResult, model_path: str = "", model_out: str = "") -> dict[str, Any]:
    def rm(table: Any, names: list[str]) -> dict[str, float | None]:
        return {c: _f(v) for c, v in table.pooled(names, r.chans).items()}

    def nr(table: Any, names: list[str]) -> dict[str, float | None]:
        return {c: _f(v / r.scales[c]) for c, v in table.pooled(names, r.chans).items()}

    effects = []
    for e in r.effects:
        effects.append({k: v for k, v in e.items()})
    per_test = []
    for t in r.tests:
        per_test.append({"test": t.name,
                         "set": "fitting" if t.name in r.fit_names else "held_out",
                         "rmse_before": {c: _f(v) for c, v in r.before.rmse[t.name].items()},
                         "rmse_after": {c: _f(v) for c, v in r.after.rmse[t.name].items()}})
    held_b = r.before.total(r.held_names)
    held_a = r.after.total(r.held_names)
    rounds = []
    for rd in r.rounds:
        rounds.append({"round": rd.index, "rmse_over_noise": {c: _f(v) for c, v in
                                                              rd.ratio.items()},
                       "traits": {k: (_f(v) if isinstance(v, float) else v)
                                  for k, v in rd.traits.items()},
                       "candidates": _evidence_list(rd), "decision": rd.decision})
    last = r.rounds[-1] if r.rounds else None
    at_floor = last is not None and last.decision.startswith("residual at the noise floor")
    if r.effects:
        verdict = "the model lacks: " + "; ".join(e["label"] for e in r.effects)
        if r.unexplained:
            verdict += (" (a residual above the noise floor remains: "
                        f"{r.unexplained['summary']})")
    elif at_floor:
        verdict = "no effect: the declared model explains the tests to the noise floor"
    else:
        worst = max(last.ratio.values()) if last is not None and last.ratio else math.nan
        verdict = ("no effect in the library improves the held-out tests significantly, but "
                   f"the residual is {worst:.3g} x the noise floor: the model lacks something "
                   "this library cannot represent"
                   + (f"; the residual: {r.unexplained['summary']}" if r.unexplained else ""))
    doc: dict[str, Any] = _clean({
        "format": SCHEMA,
        "model": model_path,
        "model_out": model_out,
        "verdict": verdict,
        "tests": {"fitting": r.fit_names, "held_out": r.held_names},
        "channels": r.chans,
        "noise_floor": {c: _f(v) for c, v in r.noise.items()},
        "noise_method": {c: {"method": f.method, "detail": f.detail}
                         for c, f in r.noise_floors.items()},
        "effects": effects,
        "rmse_before": {"fitting": rm(r.before, r.fit_names),
                        "held_out": rm(r.before, r.held_names)},
        "rmse_after": {"fitting": rm(r.after, r.fit_names),
                       "held_out": rm(r.after, r.held_names)},
        "nrmse_before": {"fitting": nr(r.before, r.fit_names),
                         "held_out": nr(r.before, r.held_names)},
        "nrmse_after": {"fitting": nr(r.after, r.fit_names),
                        "held_out": nr(r.after, r.held_names)},
        "held_out_reduction": _f(1.0 - held_a / held_b) if held_b > 0 else None,
        "per_test": per_test,
        "mahalanobis": {k: (_f(v) if isinstance(v, float) else v)
                        for k, v in r.mahalanobis.items()},
        "rounds": rounds,
        "library": fx.describe(),
        "input_band_hz": list(r.band_hz),
        "model_modes_hz": r.modes_hz,
        "calibration": r.calibration,
        "notes": r.notes,
        "unexplained": r.unexplained,
        "prediction": r.prediction,
        "open_loop_before": {c: _f(v) for c, v in r.open_loop_before.items()},
        "timing_s": {k: round(v, 3) for k, v in r.timing_s.items()},
    })
    return doc


def _clean(x: Any) -> Any:
    """JSON-safe: non-finite floats become null, numpy scalars plain numbers."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return _f(float(x))
    if isinstance(x, np.integer):
        return int(x)
    return x


def write_json(doc: dict[str, Any], path: Path | str) -> None:
    Path(path).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")


# ---------------------------------------------------------------------------------------------
def _plt() -> Any:
    try:
        mpl = importlib.import_module("matplotlib")
        mpl.use("Agg")
        return importlib.import_module("matplotlib.pyplot")
    except ImportError:
        return None


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    fig.clf()
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _worst_test(r: DiscoverResult) -> str:
    return max(r.before.nsse, key=lambda k: r.before.nsse[k])


def figures(r: DiscoverResult) -> dict[str, str]:
    """name -> base64 PNG."""
    plt = _plt()
    if plt is None:
        return {}
    out: dict[str, str] = {}
    fs = r.tests[0].fs_hz
    tname = _worst_test(r)
    rb = r.res_before.get(tname, {})
    ra = r.res_after.get(tname, {})
    # 1. residual time histories with events
    fig, axs = plt.subplots(len(r.chans), 1, figsize=(10, 1.8 * len(r.chans)), sharex=True,
                            squeeze=False)
    for ax, c in zip(axs[:, 0], r.chans, strict=True):
        if c in rb:
            t = np.arange(rb[c].size) / fs
            ax.plot(t, rb[c], lw=0.5, color="tab:red", label="before")
            ev = tr.events(rb[c], fs)
            for ts in ev.times_s:
                ax.axvline(ts, color="k", alpha=0.15, lw=0.8)
        if c in ra:
            ax.plot(np.arange(ra[c].size) / fs, ra[c], lw=0.5, color="tab:blue", label="after")
        ax.set_ylabel(c, fontsize=8)
    axs[0, 0].legend(loc="upper right", fontsize=8)
    axs[0, 0].set_title(f"residual (measured - predicted), test {tname}; grey: detected events")
    axs[-1, 0].set_xlabel("time (s)")
    out["residual"] = _png(fig)
    plt.close(fig)
    # 2. restoring-force surface for the accepted (or best) story candidate
    rd0 = r.rounds[0]
    view = rd0.view
    if view is not None and view.propagate is None:  # the output view has no DOF forces
        story = None
        for e in rd0.evidence:
            if "story" in e.cand.location:
                story = int(e.cand.location["story"])
                break
        if story is not None:
            d, g = tr.surface(view, story)
            fig, ax = plt.subplots(figsize=(6, 4.5))
            step = max(1, d.size // 20000)
            ax.plot(d[::step], g[::step], ".", ms=1, alpha=0.4, color="tab:red",
                    label="declared model")
            last = r.rounds[-1].view
            if last is not None and last.propagate is None and len(r.rounds) > 1:
                d2, g2 = tr.surface(last, story)
                ax.plot(d2[::step], g2[::step], ".", ms=1, alpha=0.4, color="tab:blue",
                        label="updated model")
            ax.set_xlabel(f"story {story} drift x{story} - x{story - 1} (model length unit: m "
                          "in SI)")
            ax.set_ylabel("missing story force (model force unit: N in SI)")
            ax.set_title("restoring-force surface (fitting tests)")
            ax.legend(fontsize=8, markerscale=8)
            out["surface"] = _png(fig)
            plt.close(fig)
    # 3. spectra before / after
    fig, axs = plt.subplots(1, len(r.chans), figsize=(3.2 * len(r.chans), 3), squeeze=False)
    for ax, c in zip(axs[0], r.chans, strict=True):
        y = next(t.y[c] for t in r.tests if t.name == tname)
        for data, col, lab in ((y, "0.6", "measured"), (rb.get(c), "tab:red", "residual before"),
                               (ra.get(c), "tab:blue", "residual after")):
            if data is None:
                continue
            f, p = signal.welch(data, fs=fs, nperseg=min(1024, data.size))
            ax.semilogy(f, p, color=col, lw=0.8, label=lab)
        for fm in r.modes_hz:
            if fm > 1:
                ax.axvline(fm, color="k", ls=":", lw=0.6)
        ax.set_title(c, fontsize=9)
        ax.set_xlabel("Hz")
    axs[0, 0].legend(fontsize=7)
    axs[0, 0].set_ylabel("PSD")
    out["spectra"] = _png(fig)
    plt.close(fig)
    # 4. candidate ranking (first round)
    evs = rd0.evidence[:14]
    fig, ax = plt.subplots(figsize=(8, 0.32 * len(evs) + 1))
    labels = [e.cand.label + ("" if e.cand.available else " (unavailable)") for e in evs]
    colors = ["tab:green" if any(i["accepted"] and i["candidate"].label == e.cand.label
                                 for i in rd0.fits) else
              ("tab:gray" if not e.cand.available else "tab:orange") for e in evs]
    ax.barh(range(len(evs))[::-1], [e.r2 for e in evs], color=colors)
    ax.set_yticks(list(range(len(evs)))[::-1])
    ax.set_yticklabels(labels, fontsize=7)
    ax.set_xlabel("evidence (share of the missing force explained; 'no effect': share of the "
                  "residual the noise explains)", fontsize=7)
    ax.set_title("candidate ranking, round 1 (green: accepted)")
    out["ranking"] = _png(fig)
    plt.close(fig)
    return out


def _g(x: Any) -> str:
    return "-" if x is None else f"{x:.4g}"


def _html_effects(doc: dict[str, Any]) -> str:
    """Each accepted effect: its parameters, the declared parameters re-adjusted with it."""
    e = html.escape
    out = []
    for x in doc["effects"]:
        ps = ", ".join(f"{k} = {v['value']:.4g} &plusmn; {v['uncertainty']:.2g} {e(v['unit'])}"
                       for k, v in x["parameters"].items())
        ra = ", ".join(f"{e(k)} {v['before']:.4g} &rarr; {v['value']:.4g} "
                       f"({100 * v['change_rel']:+.1f} %)"
                       for k, v in x.get("readjusted", {}).items())
        out.append(f"<li><b>{e(x['label'])}</b>: {ps} (held-out gain "
                   f"{100 * x['held_out_gain']:.1f} %, &Delta;BIC {x['delta_bic']:.0f})"
                   + (f"<br>re-adjusted with it: {ra}" if ra else "")
                   + f"<br><small>{e(x['law'])}</small></li>")
    return "".join(out)


def _html_tests(r: DiscoverResult, doc: dict[str, Any]) -> str:
    views = any(t.mask is not None for t in r.tests)
    n = len({id(t.u) for t in r.tests})
    split = (f"{n} test(s), cross-validated over time ({len(r.fit_names)} fitting and "
             f"{len(r.held_names)} held-out views)" if views else
             f"{n} tests ({len(r.fit_names)} fitting, {len(r.held_names)} held-out)")
    pred = ("errors are the observer's one-step-ahead predictions (the model drifts open "
            "loop)" if doc.get("prediction") == "observer" else "errors are open-loop")
    return f"{split}; {pred}"


def _html_mahal(mah: dict[str, Any]) -> str:
    if mah.get("note"):
        return f"Mahalanobis distance of the features: {html.escape(str(mah['note']))}."
    return ("Paired Mahalanobis distance of the simulated features from the measured ones "
            f"(the measured tests' metric): before {_g(mah.get('before'))}, after "
            f"{_g(mah.get('after'))}; the paired test's p-value (is what is left more than "
            f"noise?): before {_g(mah.get('p_before'))}, after {_g(mah.get('p_after'))}.")


def write_html(r: DiscoverResult, doc: dict[str, Any], path: Path | str) -> None:
    figs = figures(r)
    e = html.escape
    b, a = doc["rmse_before"], doc["rmse_after"]
    rows = [f"<tr><td>{e(c)}</td><td>{_g(b['fitting'][c])}</td><td>{_g(a['fitting'][c])}</td>"
            f"<td>{_g(b['held_out'][c])}</td><td>{_g(a['held_out'][c])}</td>"
            f"<td>{_g(doc['noise_floor'][c])}</td>"
            f"<td>{e(doc['noise_method'].get(c, {}).get('method', ''))}</td></tr>"
            for c in r.chans]
    cands = []
    for rd in doc["rounds"]:
        for cd in rd["candidates"][:12]:
            fit = cd.get("fit")
            fs_ = "" if fit is None else (
                f"gain {100 * (fit['held_out_gain'] or 0):.1f} %, "
                f"{'accepted' if fit['accepted'] else 'rejected'}")
            cands.append(f"<tr><td>{rd['round']}</td><td>{cd['rank']}</td>"
                         f"<td>{e(cd['label'])}</td><td>{(cd['evidence'] or 0):.3f}</td>"
                         f"<td>{'yes' if cd['available'] else 'no'}</td><td>{e(fs_)}</td></tr>")
    imgs = "".join(f"<h3>{e(k)}</h3><img src=\"data:image/png;base64,{v}\">"
                   for k, v in figs.items())
    notes = "".join(f"<li>{e(n)}</li>" for n in doc["notes"])
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>dynval discover</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:1em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;font-size:13px}}
img{{max-width:100%}}</style></head><body>
<h1>dynval discover</h1>
<p>Model: <code>{e(doc['model'])}</code>; {e(_html_tests(r, doc))}.</p>
<h2>Verdict</h2><p><b>{e(doc['verdict'])}</b></p><ul>{_html_effects(doc)}</ul>
<p>Held-out normalised SSE reduction: {100 * (doc['held_out_reduction'] or 0):.1f} %.
{_html_mahal(doc['mahalanobis'])}</p>
<h2>RMSE per channel</h2>
<table><tr><th>channel</th><th>fitting before</th><th>fitting after</th>
<th>held-out before</th><th>held-out after</th><th>noise floor</th><th>noise from</th></tr>
{''.join(rows)}</table>
<h2>Candidates</h2>
<table><tr><th>round</th><th>rank</th><th>candidate</th><th>evidence</th><th>available</th>
<th>fit</th></tr>{''.join(cands)}</table>
<h2>Notes</h2><ul>{notes or '<li>none</li>'}</ul>
<h2>Figures</h2>{imgs or '<p>(matplotlib is not installed: no figures)</p>'}
</body></html>
"""
    Path(path).write_text(page, encoding="utf-8")


def save_pngs(r: DiscoverResult, folder: Path | str) -> list[Path]:
    """Write the figures as PNG files (for inspection)."""
    out = []
    for k, v in figures(r).items():
        p = Path(folder) / f"discover_{k}.png"
        p.write_bytes(base64.b64decode(v))
        out.append(p)
    return out
