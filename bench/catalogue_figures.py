"""Issue 19: the report's Tables 13-14 and Figures 43-53 in kind (and its Figures 28-29, 34,
40) on independent simulations of its structure, in one self-contained HTML page: Tables 13-14
(EMA of models L1 and L2 against the numerical modes), the FRF / coherence of the linearity
(two levels) and reciprocity (force and response swapped) checks with and without the bumper
(Fig. 43-47), and the signal features on random, 54 Hz harmonic and hammer tests (Fig.
49-53): 'measured' is the report's structure with the shared data's bumper (dynval.synth,
truth at 64 x fs, 1 % sensor noise); 'linear model' and 'bumper model' are the declared model
without and with that bumper, driven by the measured force (the validation's simulation, with
1 % sensor noise). Also one PNG per figure and an index.md.

    PYTHONPATH=gateway/src python bench/catalogue_figures.py --out build/catalogue-figures
    (writes build/catalogue-figures/catalogue.html)
"""
from __future__ import annotations

import argparse
import base64
import dataclasses
import html
import io
import logging
import sys
from pathlib import Path
from typing import Any

import numpy as np
from dynval import model as mdl
from dynval import synth
from dynval.catalogue import signal_plots as plots
from dynval.validate import checks as chk
from dynval.validate import measurement as meas
from dynval.validate import montecarlo as mc
from dynval.validate import report

sys.path.insert(0, str(Path(__file__).resolve().parent))
from catalogue_modal_frf import declared, tables_13_14

log = logging.getLogger("catalogue_figures")
MODEL = (Path(__file__).resolve().parents[1].parent / "shared" / "data" / "synthetic"
         / "lanl4dof-clean" / "declared_model.json")
CH = "acc4_mps2"


def _series(m: mdl.Model, exc: synth.Sine | synth.Hammer | None, fs: float, n: int,
            level: float, truth: synth.Truth) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The measured top-floor record and both models' predictions, and the contact onsets."""
    on: list[np.ndarray] = []
    rec = synth.generate(m, truth, n_tests=1, levels_n_rms=(level,), fs_hz=fs, n_samples=n,
                         excitation=exc, fine=mc.FINE, seed=7, onsets=on)[0]
    x = rec.channel(CH).data
    noise = {CH: 0.01 * float(np.std(x))}
    out = {"measured": x}
    for name, mm in (("linear model", m),
                     ("bumper model", dataclasses.replace(m, elements=truth.elements))):
        y = meas.simulate(mm, rec.channel("force_N").data, fs)
        out[name] = meas.add_noise({CH: y[CH]}, noise, rec.channel("force_N").data)[CH]
    return out, on[0]


def check_figures() -> dict[str, Any]:
    """Fig. 43-47 in kind: the linearity (10 tests, 12 / 7.2 N) and reciprocity (3 + 3 tests,
    force at DOF 1 / 4) checks of the linear model L2 on clean and bumper data."""
    m = declared()
    figs = {}
    for label, truth in (("without the bumper", synth.Truth()),
                         ("with the bumper", synth.Truth(elements=(mc.BUMPER,), label="b"))):
        recs = synth.generate(m, truth, n_tests=10, seed=21, fine=mc.FINE)
        (lin,) = chk.run(m, recs, chk.parse(["linearity@acc4"], m, list(m.outputs)),
                         "force_N")
        sa, sb = synth.reciprocal(m, truth, 4, n_tests=3, levels_n_rms=(12.0,), seed=22,
                                  fine=mc.FINE)
        (rec,) = chk.run(m, sa, chk.parse(["reciprocity@acc4"], m, list(m.outputs)),
                         "force_N", swapped=sb)
        for o in (lin, rec):
            figs[f"{o.check.kind} check {label} (Fig. 43-47 in kind). "
                 f"{report._check_caption(o)}"] = report.plot_check(o)
    return figs


def _table_html(md: list[str]) -> str:
    rows = [[c.strip() for c in r.strip("|").split("|")] for r in md if not r.startswith("|--")]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                   for r in rows[1:])
    return f"<table><tr>{head}</tr>{body}</table>"


def write_html(path: Path, figs: dict[str, Any], tables: list[str]) -> None:
    parts = ["<h1>dynval: the report's feature catalogue in kind (issue 19)</h1>",
             f"<p>{html.escape(__doc__.split(chr(10) + chr(10))[0])}</p>",
             ("<h2>Tables 13-14: modal frequencies and damping, EMA of ten records of models "
              "L1 (zeta 1 %) and L2 (zeta2 5 %) against the numerical modes</h2>"),
             _table_html(tables)]
    for cap, fig in figs.items():
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
        b64 = base64.b64encode(buf.getvalue()).decode()
        parts.append(f"<figure><img src=\"data:image/png;base64,{b64}\" alt=\""
                     f"{html.escape(cap)}\"><figcaption>{html.escape(cap)}</figcaption>"
                     "</figure>")
    path.write_text("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>dynval "
                    "catalogue</title><style>body{font-family:sans-serif;max-width:980px;"
                    "margin:auto;padding:1em}table{border-collapse:collapse}td,th{border:1px "
                    "solid #ccc;padding:2px 6px}img{max-width:100%}figcaption{font-size:90%;"
                    "color:#444}</style></head><body>" + "\n".join(parts) + "</body></html>\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    a.out.mkdir(parents=True, exist_ok=True)
    m = mdl.load(a.model)
    bump = synth.Truth(elements=(mc.BUMPER,), label="bumper")
    hard = synth.Truth(elements=(dataclasses.replace(mc.BUMPER, delta_m=1e-7),), label="hard")
    rnd, _ = _series(m, None, 640.0, 8192, 12.0, bump)
    sine, _ = _series(m, synth.Sine(54.0, lead_s=0.0), 2560.0, 8192, 7.0, bump)
    hard_sine, onsets = _series(m, synth.Sine(54.0, lead_s=0.0), 2560.0, 8192, 7.0, hard)
    mh = dataclasses.replace(m, input=mdl.Input("force", 2, "force_N"))
    ham, _ = _series(mh, synth.Hammer(), 320.0, 1024, 300.0, bump)
    figs = {**check_figures(),
            "distribution (Fig. 28-29), random": plots.plot_distribution(rnd),
            "decay (Fig. 32, 34), hammer": plots.plot_decay(ham["measured"], 320.0),
            "autocorrelation (Fig. 40), random": plots.plot_acf(rnd, 640.0, 256),
            "harmonic PSD (Fig. 49), 54 Hz": plots.plot_harmonics(sine, 2560.0),
            "response spectra (Fig. 50), random": plots.plot_srs(rnd, 640.0),
            "cepstrum (Fig. 51-52), 54 Hz": plots.plot_cepstrum(sine, 2560.0),
            "Holder exponent (Fig. 53), 54 Hz, hard bumper":
                plots.plot_holder(hard_sine["measured"][:2560], 2560.0,
                                  onsets[onsets < 1.0])}
    lines = ["# Catalogue figures (bench/catalogue_figures.py)", ""]
    for i, (cap, fig) in enumerate(figs.items()):
        name = f"catalogue_{i + 1}.png"
        fig.savefig(a.out / name, dpi=100, bbox_inches="tight")
        lines += [f"## {cap}", "", f"![{cap}]({name})", ""]
    (a.out / "index.md").write_text("\n".join(lines))
    write_html(a.out / "catalogue.html", figs, tables_13_14(declared()))
    log.info("wrote %d figures and %s", len(figs), a.out / "catalogue.html")


if __name__ == "__main__":
    main()
