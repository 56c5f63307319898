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
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dynval import labels as lb
from dynval import plotting as plot
from dynval.discover import effects as fx
from dynval.discover import parallel
from dynval.discover import residual as rs
from dynval.discover import trace as tr
from dynval.discover.loop import DiscoverResult, Round

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
                        "held_out_gain_without_best_test": _f(info["held_gain_replicated"]),
                        "fitting_gain": _f(info["fit_gain"]),
                        "delta_bic": _f(info["delta_bic"]), "accepted": info["accepted"],
                        "reference": info["reference"], "n_evaluations": res.nfev}
        out.append(d)
    return out


TIES_NAMED = 3  # alternatives named in the verdict; the effect's entry lists them all


def _with_ties(effect: dict[str, Any]) -> str:
    """An effect's label, with the effects these tests do not tell from it (alternatives)."""
    alt = [a["label"] for a in effect.get("alternatives", [])]
    if not alt:
        return str(effect["label"])
    more = f" and {len(alt) - TIES_NAMED} more" if len(alt) > TIES_NAMED else ""
    return (f"{effect['label']} (or, as well supported by these tests: "
            f"{' or '.join(alt[:TIES_NAMED])}{more})")


def _verdict(effects: list[dict[str, Any]], unexplained: dict[str, Any],
             last: Round | None) -> str:
    """The report's one-line verdict from the effects found, the traits of a residual left
    and the last round (its ratios and decision). The worst channel is the largest finite
    RMSE / noise: a channel without a floor (NaN) is left out wherever it sits."""
    if effects:
        structure = fx.structural(effects)
        chain = [e for e in effects if e not in structure]
        return ("the model lacks: " + "; ".join(_with_ties(e) for e in structure)
                + ("; " if structure and chain else "")
                + ("in its measurements: " + "; ".join(_with_ties(e) for e in chain)
                   if chain else "")
                + (f" (a residual above the noise floor remains: {unexplained['summary']})"
                   if unexplained else ""))
    worst = rs.worst_ratio(last.ratio, math.nan) if last is not None else math.nan
    if last is not None and last.decision.startswith("residual at the noise floor"):
        # the worst channel's figure with it: "at the floor" means under the significance
        # ratio, and a reader must see how far under (a small effect at 1.4 x reads the same)
        return ("no effect: the declared model explains the tests to the noise floor "
                f"(worst channel {worst:.3g} x its floor"
                + (f"; {len(last.fits)} candidates fitted, none improved the held-out "
                   "tests enough to be accepted)" if last.fits else ")"))
    return ("no effect in the library improves the held-out tests significantly, but "
            f"the residual is {worst:.3g} x the noise floor: the model lacks something "
            "this library cannot represent"
            + (f"; the residual: {unexplained['summary']}" if unexplained else ""))


def to_json(r: DiscoverResult, model_path: str = "", model_out: str = "",
            units: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The JSON document; ``units``: channel -> unit as the recordings declare them (missing
    ones: the SI unit of what the model predicts there)."""
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
    verdict = _verdict(r.effects, r.unexplained, r.rounds[-1] if r.rounds else None)
    doc: dict[str, Any] = _clean({
        "format": SCHEMA,
        "model": model_path,
        "model_out": model_out,
        "verdict": verdict,
        "tests": {"fitting": r.fit_names, "held_out": r.held_names},
        "channels": r.chans,
        "units": {c: lab.unit for c, lab in labels_of(r, units).items()},
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
# Figures. Each figure function returns (matplotlib figure, caption); figures() encodes them.
ZOOM_S = 0.5  # the zoomed residual window around the largest event, seconds
LEVEL = 0.05  # the paired feature test's level the report reads p-values against


@dataclass
class Figure:
    name: str
    caption: str
    png_b64: str


def _plt() -> Any:
    try:
        return plot.pyplot()
    except ImportError:
        return None


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    fig.clf()
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _worst_test(r: DiscoverResult) -> str:
    return max(r.before.nsse, key=lambda k: r.before.nsse[k])


def labels_of(r: DiscoverResult, units: Mapping[str, str] | None = None
              ) -> dict[str, lb.ChannelLabel]:
    """The output channels' labels: units as given (the recordings'), else the model's SI."""
    return lb.channel_labels(r.chans, r.model0, units=units)


def figure_residual(r: DiscoverResult, labels: Mapping[str, lb.ChannelLabel]) -> tuple[Any, str]:
    """The worst test's residual before / after per channel, the detected events marked;
    long records drawn as a min/max envelope (the caption says how much)."""
    plt = plot.pyplot()
    fs = r.tests[0].fs_hz
    tname = _worst_test(r)
    rb, ra = r.res_before.get(tname, {}), r.res_after.get(tname, {})
    fig, axs = plt.subplots(len(r.chans), 1, figsize=(10, 1.9 * len(r.chans)), sharex=True,
                            squeeze=False, layout="constrained")
    per = 1
    for ax, c in zip(axs[:, 0], r.chans, strict=True):
        for data, colour, lab in ((rb.get(c), plot.BEFORE, "before (declared model)"),
                                  (ra.get(c), plot.AFTER, "after (updated model)")):
            if data is None:
                continue
            idx, y, per = plot.envelope(data)
            ax.plot(idx / fs, y, lw=0.5, color=colour, label=lab)
        if c in rb:
            for ts in tr.events(rb[c], fs).times_s:
                ax.axvline(ts, color="k", alpha=0.15, lw=0.8)
        ax.set_title(labels[c].title, fontsize=8, loc="left")
        ax.set_ylabel(f"residual\n({labels[c].unit_text})", fontsize=9)
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend(loc="upper right", fontsize=8)
    axs[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"residual (measured - predicted), test {tname}; grey: detected events",
                 fontsize=10)
    plot.untangle_ticks(fig)
    n = max((v.size for v in rb.values()), default=0)
    drawn = (f"each line is the minimum and maximum of every {per} samples ({n} samples per "
             "channel; every peak is kept)" if per > 1 else "every sample drawn")
    return fig, (f"Residual of test {tname} (the test with the largest error before) in each "
                 f"channel's unit, before (red) and after (blue) the effects found; {drawn}.")


def figure_zoom(r: DiscoverResult, labels: Mapping[str, lb.ChannelLabel]
                ) -> tuple[Any, str] | None:
    """ZOOM_S seconds around the largest residual before, every sample: the detail a reader
    would zoom into on the full record."""
    fs = r.tests[0].fs_hz
    tname = _worst_test(r)
    rb, ra = r.res_before.get(tname, {}), r.res_after.get(tname, {})
    if not rb:
        return None
    c = max(rb, key=lambda k: float(np.max(np.abs(rb[k]))) / (r.scales.get(k) or 1.0))
    i = int(np.argmax(np.abs(rb[c])))
    half = int(ZOOM_S * fs / 2)
    lo, hi = max(0, i - half), min(rb[c].size, i + half)
    if hi - lo >= rb[c].size:
        return None  # the record is no longer than the window: the full plot shows it all
    plt = plot.pyplot()
    fig, ax = plt.subplots(figsize=(10, 2.8))
    t = np.arange(lo, hi) / fs
    ax.plot(t, rb[c][lo:hi], lw=0.8, color=plot.BEFORE, label="before (declared model)")
    if c in ra:
        ax.plot(t, ra[c][lo:hi], lw=0.8, color=plot.AFTER, label="after (updated model)")
    ax.set_title(labels[c].title, fontsize=9, loc="left")
    ax.set_ylabel(f"residual ({labels[c].unit_text})")
    ax.set_xlabel("time (s)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    plot.untangle_ticks(fig)
    return fig, (f"Zoom: {ZOOM_S:g} s of test {tname} around the largest residual before, "
                 f"at t = {i / fs:.3f} s in {labels[c].title}; every sample drawn.")


def _surface_story(rd0: Any) -> int | None:
    """The story of the best-ranked candidate with a story location (the surface to draw)."""
    for e in rd0.evidence:
        if "story" in e.cand.location:
            return int(e.cand.location["story"])
    return None


def figure_surface(r: DiscoverResult) -> tuple[Any, str] | None:
    """The restoring-force surface (missing story force against story drift) of the story of
    the best-ranked story candidate, before and after; SI prefixes keep the ticks short."""
    view = r.rounds[0].view if r.rounds else None
    if view is None or view.propagate is not None:  # the output view has no DOF forces
        return None
    story = _surface_story(r.rounds[0])
    if story is None:
        return None
    plt = plot.pyplot()
    d, g = tr.surface(view, story)
    xs, xu = plot.si_scale(d, "m")
    ys, yu = plot.si_scale(g, "N")
    step = max(1, d.size // 20000)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.plot(xs * d[::step], ys * g[::step], ".", ms=1, alpha=0.4, color=plot.BEFORE,
            label="declared model")
    last = r.rounds[-1].view
    if last is not None and last.propagate is None and len(r.rounds) > 1:
        d2, g2 = tr.surface(last, story)
        ax.plot(xs * d2[::step], ys * g2[::step], ".", ms=1, alpha=0.4, color=plot.AFTER,
                label="updated model")
    ax.set_xlabel(f"story {story} drift x{story} \u2212 x{story - 1} ({xu})")
    ax.set_ylabel(f"missing story force ({yu})")
    ax.set_title(f"restoring-force surface, story {story} (fitting tests)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, markerscale=8)
    plot.untangle_ticks(fig)
    return fig, (f"Restoring-force surface of story {story}: the force the model misses against "
                 "the story drift, over the fitting tests (a contact shows as a force rising "
                 "beyond a gap, friction as a step at zero velocity).")


def figure_spectra(r: DiscoverResult, labels: Mapping[str, lb.ChannelLabel]) -> tuple[Any, str]:
    """PSD of the measured signal and of the residual before / after, one panel per channel,
    in each channel's unit squared per hertz; dotted: the model's natural frequencies."""
    plt = plot.pyplot()
    fs = r.tests[0].fs_hz
    tname = _worst_test(r)
    rb, ra = r.res_before.get(tname, {}), r.res_after.get(tname, {})
    ncol = min(2, len(r.chans))
    nrow = math.ceil(len(r.chans) / ncol)
    fig, axs = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 3.3 * nrow), squeeze=False)
    for ax, c in zip(axs.flat, r.chans, strict=False):
        y = next(t.y[c] for t in r.tests if t.name == tname)
        for data, colour, lab in ((y, plot.MEASURED, "measured"),
                                  (rb.get(c), plot.BEFORE, "residual before"),
                                  (ra.get(c), plot.AFTER, "residual after")):
            if data is None:
                continue
            f, p = signal.welch(data, fs=fs, nperseg=min(1024, data.size))
            ax.semilogy(f, p, color=colour, lw=0.8, label=lab, alpha=0.6 if
                        lab == "measured" else 1.0)
        for fm in r.modes_hz:
            if fm > 1:
                ax.axvline(fm, color="k", ls=":", lw=0.6)
        ax.set_title(labels[c].title, fontsize=9)
        ax.set_xlabel("frequency (Hz)", fontsize=8)
        ax.set_ylabel(labels[c].psd_axis(), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", alpha=0.3)
    for ax in list(axs.flat)[len(r.chans):]:
        ax.axis("off")
    axs[0, 0].legend(fontsize=7)
    fig.tight_layout()
    plot.untangle_ticks(fig)
    return fig, (f"Power spectral densities (Welch) of test {tname}: the measured signal and "
                 "the residual before and after; dotted: the declared model's natural "
                 "frequencies.")


def figure_ranking(r: DiscoverResult) -> tuple[Any, str] | None:
    """Round 1's candidates by evidence: green accepted, red fitted and rejected, blue ranked
    but not fitted, grey unavailable."""
    if not r.rounds:
        return None
    plt = plot.pyplot()
    patches = importlib.import_module("matplotlib.patches")
    rd0 = r.rounds[0]
    fits = {i["candidate"].label: i["accepted"] for i in rd0.fits}
    evs = rd0.evidence[:14]

    def colour(e: Any) -> str:
        if not e.cand.available:
            return plot.NEUTRAL
        if e.cand.label in fits:
            return plot.BEST if fits[e.cand.label] else plot.WORST
        return "tab:blue"

    fig, ax = plt.subplots(figsize=(8, 0.32 * len(evs) + 1.4))
    ax.barh(range(len(evs))[::-1], [e.r2 for e in evs], color=[colour(e) for e in evs])
    ax.set_yticks(list(range(len(evs)))[::-1])
    ax.set_yticklabels([e.cand.label + ("" if e.cand.available else " (unavailable)")
                        for e in evs], fontsize=7)
    ax.set_xlabel("evidence: share of the missing force the candidate explains ('no effect': "
                  "share of the residual the noise explains)", fontsize=7)
    ax.set_title("candidate ranking, round 1", fontsize=10)
    keys = [(plot.BEST, "fitted, accepted"), (plot.WORST, "fitted, rejected"),
            ("tab:blue", "not fitted (evidence too low)"), (plot.NEUTRAL, "unavailable")]
    ax.legend(handles=[patches.Patch(color=c, label=k) for c, k in keys], fontsize=7,
              loc="lower right")
    plot.untangle_ticks(fig)
    return fig, ("Candidates of round 1 ranked by their evidence; only those near the top are "
                 "fitted, and a fit is accepted when it lowers the held-out error.")


def figure_list(r: DiscoverResult, units: Mapping[str, str] | None = None) -> list[Figure]:
    """Every figure of the report with its caption (none without matplotlib), drawn on every
    available core (the same PNGs: each figure is drawn alone; 14.6 s of a 6-DOF case's
    report on one)."""
    if _plt() is None:
        return []
    labels = labels_of(r, units)
    # each with the seconds it took on a 6-DOF case: drawn longest first (the pool waits on
    # its last figure)
    makers: dict[str, tuple[float, Callable[[], tuple[Any, str] | None]]] = {
        "residual": (0.7, lambda: figure_residual(r, labels)),
        "residual_zoom": (0.1, lambda: figure_zoom(r, labels)),
        "surface": (0.25, lambda: figure_surface(r)),
        "spectra": (1.5, lambda: figure_spectra(r, labels)),
        "ranking": (0.25, lambda: figure_ranking(r))}

    def render(name: str) -> Figure | None:
        fc = makers[name][1]()
        if fc is None:
            return None
        fig, caption = fc
        out = Figure(name, caption, _png(fig))
        plot.pyplot().close(fig)
        return out

    drawn = parallel.ordered_map(render, list(makers), parallel.available_workers(),
                                 [cost for cost, _ in makers.values()])
    return [f for f in drawn if f is not None]


def figures(r: DiscoverResult, units: Mapping[str, str] | None = None) -> dict[str, str]:
    """name -> base64 PNG."""
    return {f.name: f.png_b64 for f in figure_list(r, units)}


# ---------------------------------------------------------------------------------------------
# HTML
def _g(x: Any) -> str:
    return "-" if x is None else f"{x:.4g}"


def _with_unit(value: float, sigma: float | None, unit: str) -> str:
    """'111.9 &plusmn; 0.28 µm' for 1.119e-4 m: an SI prefix where the unit takes one."""
    k, u = plot.si_scale(np.array([value]), unit)
    sig = "-" if sigma is None else f"{k * sigma:.2g}"
    return f"{k * value:.4g} &plusmn; {sig} {html.escape(lb.pretty_unit(u))}"


def _html_effects(doc: dict[str, Any]) -> str:
    """Each accepted effect: its parameters, the declared parameters re-adjusted with it."""
    e = html.escape
    out = []
    for x in doc["effects"]:
        ps = ", ".join(f"{k} = {_with_unit(v['value'], v['uncertainty'], v['unit'])}"
                       for k, v in x["parameters"].items())
        ra = ", ".join(f"{e(k)} {v['before']:.4g} &rarr; {v['value']:.4g} "
                       f"({100 * v['change_rel']:+.1f} %)"
                       for k, v in x.get("readjusted", {}).items())
        ties = ", ".join(f"{e(a['label'])} (held-out RMSE {a['held_out_rmse_ratio']:.3f} x)"
                         for a in x.get("alternatives", []))
        bound = ", ".join(e(n) for n in x.get("at_bound", []))
        out.append(f"<li><b>{e(x['label'])}</b>: {ps} (held-out gain "
                   f"{100 * x['held_out_gain']:.1f} %, &Delta;BIC {x['delta_bic']:.0f})"
                   + (f"<br>re-adjusted with it: {ra}" if ra else "")
                   + (f"<br>found as a re-adjustment with {e(', '.join(x['found_as']))}, and a "
                      "change of its own (see the notes)" if x.get("found_as") else "")
                   + (f"<br>at the end of its search range (the fit wanted to go further: "
                      f"the effect may stand in for something else): {bound}"
                      if bound else "")
                   + (f"<br>as well supported by these tests (within half the minimum gain; "
                      f"a test that tells them apart is needed): {ties}" if ties else "")
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


def _p_reading(p: float | None, which: str) -> str:
    """What a paired-test p-value says, in words, at LEVEL."""
    if p is None:
        return f"{which}: not computed"
    if p < LEVEL:
        return (f"{which} p = {p:.3g} < {LEVEL:g}: its features differ from the measured ones "
                "by more than the noise explains")
    return (f"{which} p = {p:.3g} \u2265 {LEVEL:g}: its features agree with the measured ones "
            "within the noise")


def evidence(doc: dict[str, Any], labels: Mapping[str, lb.ChannelLabel]) -> list[str]:
    """The evidence under the verdict, one plain sentence each."""
    out = []
    red = doc.get("held_out_reduction")
    if doc["effects"]:
        out.append(f"Held-out error: the normalised SSE of the held-out tests is "
                   f"{100 * (red or 0):.1f} % lower with the effect(s) added (each was fitted "
                   "on the fitting tests and accepted only for lowering the held-out error).")
    else:
        out.append("Held-out error: no candidate lowered it enough to be accepted.")
    ratios = []
    for c, lab in labels.items():
        a, n = doc["rmse_after"]["held_out"].get(c), doc["noise_floor"].get(c)
        if a is not None and n:
            ratios.append(f"{lab.short} {a / n:.2f} \u00d7 ({a:.4g} against {lab.value(n)})")
    if ratios:
        out.append("Held-out RMSE left against each channel's noise floor (1 \u00d7: nothing "
                   "left to explain): " + "; ".join(ratios) + ".")
    mah = doc["mahalanobis"]
    if mah.get("note"):
        out.append(f"Paired feature test: {mah['note']}.")
    else:
        out.append("Paired feature test (Mahalanobis distance of each test's simulated features "
                   "from its measured ones, in the measured tests' metric): distance before "
                   f"{_g(mah.get('before'))}, after {_g(mah.get('after'))}; "
                   f"{_p_reading(mah.get('p_before'), 'declared model')}; "
                   f"{_p_reading(mah.get('p_after'), 'updated model')}.")
    return out


def agreement(doc: dict[str, Any]) -> str | None:
    """A sentence when the evidence points another way than the verdict; None when it agrees."""
    mah = doc["mahalanobis"]
    p_b, p_a = mah.get("p_before"), mah.get("p_after")
    if doc["effects"] and p_a is not None and p_a < LEVEL:
        return (f"The effect(s) found explain most of the error, not all of it: the updated "
                f"model's features still differ from the measured ones beyond the noise "
                f"(p = {p_a:.3g}); a smaller effect may remain.")
    if not doc["effects"] and p_b is not None and p_b < LEVEL and \
            doc["verdict"].startswith("no effect: "):
        return (f"The error is at the noise floor, yet the paired feature test sees a "
                f"difference (p = {p_b:.3g}): an effect too small for the error to show may "
                "remain.")
    return None


def _html_verdict(doc: dict[str, Any], labels: Mapping[str, lb.ChannelLabel]) -> str:
    e = html.escape
    note = agreement(doc)
    return (f"<h2>Verdict</h2><p class=\"verdict\"><b>{e(doc['verdict'])}</b></p>"
            + (f"<p class=\"note\">{e(note)}</p>" if note else "")
            + "<h3>Evidence</h3><ul>" + "".join(f"<li>{e(x)}</li>" for x in
                                                evidence(doc, labels)) + "</ul>"
            + (f"<h3>Effects found</h3><ul>{_html_effects(doc)}</ul>" if doc["effects"] else ""))


def _html_rmse(doc: dict[str, Any], labels: Mapping[str, lb.ChannelLabel]) -> str:
    e = html.escape
    b, a = doc["rmse_before"], doc["rmse_after"]
    rows = [f"<tr><td>{e(c)}</td><td>{e(lab.what or '-')}</td><td>{e(lab.unit_text)}</td>"
            f"<td>{_g(b['fitting'][c])}</td><td>{_g(a['fitting'][c])}</td>"
            f"<td>{_g(b['held_out'][c])}</td><td>{_g(a['held_out'][c])}</td>"
            f"<td>{_g(doc['noise_floor'][c])}</td>"
            f"<td>{e(doc['noise_method'].get(c, {}).get('method', ''))}</td></tr>"
            for c, lab in labels.items()]
    return ("<h2>RMSE per channel</h2><p>In each channel's unit.</p><table><tr><th>channel</th>"
            "<th>measures</th><th>unit</th><th>fitting before</th><th>fitting after</th>"
            "<th>held-out before</th><th>held-out after</th><th>noise floor</th>"
            "<th>noise from</th></tr>" + "".join(rows) + "</table>")


def _html_candidates(doc: dict[str, Any]) -> str:
    e = html.escape
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
    return ("<h2>Candidates</h2><table><tr><th>round</th><th>rank</th><th>candidate</th>"
            "<th>evidence</th><th>available</th><th>fit</th></tr>" + "".join(cands)
            + "</table>")


def _html_files(written: Mapping[str, str]) -> str:
    if not written:
        return ""
    e = html.escape
    return ("<h2>Files written by this run</h2><ul>" + "".join(
        f"<li>{e(what)}: <code>{e(path)}</code></li>" for what, path in written.items())
        + "</ul>")


def _html_figures(figs: list[Figure]) -> str:
    if not figs:
        return "<p>(matplotlib is not installed: no figures)</p>"
    e = html.escape
    return "".join(f"<figure><img src=\"data:image/png;base64,{f.png_b64}\" alt=\"{e(f.name)}\">"
                   f"<figcaption>{e(f.caption)}</figcaption></figure>" for f in figs)


def write_html(r: DiscoverResult, doc: dict[str, Any], path: Path | str,
               written: Mapping[str, str] | None = None) -> None:
    """The HTML report; ``written``: what -> path of the files this run wrote (listed)."""
    units = doc.get("units")
    labels = labels_of(r, units)
    e = html.escape
    notes = "".join(f"<li>{e(n)}</li>" for n in doc["notes"])
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>dynval discover</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:1em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;font-size:13px}}
img{{max-width:100%}}figure{{margin:1.5em 0}}figcaption{{font-size:90%;color:#444}}
.note{{border-left:4px solid #c80;padding-left:8px}}</style></head><body>
<h1>dynval discover</h1>
<p>Model: <code>{e(doc['model'])}</code>; {e(_html_tests(r, doc))}.</p>
{_html_verdict(doc, labels)}
{_html_rmse(doc, labels)}
{_html_candidates(doc)}
<h2>Notes</h2><ul>{notes or '<li>none</li>'}</ul>
{_html_files(written or {})}
<h2>Figures</h2>{_html_figures(figure_list(r, units))}
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
