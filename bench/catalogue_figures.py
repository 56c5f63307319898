"""Issue 19: the catalogue's figures in kind (report Figures 28-29, 34, 40, 49-53) on the
generator's data: 'measured' is the report's structure with the shared data's bumper
(dynval.synth, truth at 64 x fs, 1 % sensor noise); 'linear model' and 'bumper model' are the
declared model without and with that bumper, driven by the measured force (the validation's
simulation, with 1 % sensor noise). One PNG per feature and an index.md of the metrics.

    PYTHONPATH=gateway/src python bench/catalogue_figures.py --out build/catalogue-figures
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path

import numpy as np

from dynval import model as mdl
from dynval import synth
from dynval.catalogue import signal_plots as plots
from dynval.validate import measurement as meas
from dynval.validate import montecarlo as mc

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
        out[name] = meas.add_noise({CH: y[CH]}, noise, 0)[CH]
    return out, on[0]


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
    figs = {"distribution (Fig. 28-29), random": plots.plot_distribution(rnd),
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
    log.info("wrote %d figures to %s", len(figs), a.out)


if __name__ == "__main__":
    main()
