"""Issue 19: does each waveform / spectral catalogue feature tell the bumper from the linear
model, and how often does it reject the linear model on clean data? For each test type the
generator (dynval.synth, truth at 64 x fs, 1 % sensor noise) makes 10 tests of the report's
structure with the shared data's bumper and 10 without, per seed (random and harmonic tests
also with a hard bumper, Delta 0.1 um: an impact); `dynval validate`'s verdict (the paired
test) on the linear declared model is taken for each feature alone. The harmonic tests' peak counts and the
Holder drop-offs against the contact onsets (within 4 ms) are tallied too, on the recorded
tests (from the switch-on) and on steady-state ones (the sine on 2 s before the record).
The hammer tests are recorded by an alias-free DAQ (synth.daq_filter): the default one lets the
hammer's broadband force alias, a bias of the input that a right model's amplitude features
(decay_y0, rms) show in 7-8 of 20 clean studies. --types picks test types by a substring of
their names, --first-seed the first seed, --daq overrides every type's DAQ.

    PYTHONPATH=gateway/src python bench/catalogue_error_rates.py --seeds 20 \
        --out bench/RESULTS.catalogue.md
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import time
from pathlib import Path

import numpy as np

from dynval import model as mdl
from dynval import synth
from dynval.catalogue import holder, spectral
from dynval.validate import montecarlo as mc
from dynval.validate import study

log = logging.getLogger("catalogue_error_rates")
MODEL = (Path(__file__).resolve().parents[1].parent / "shared" / "data" / "synthetic"
         / "lanl4dof-clean" / "declared_model.json")
# test type -> (excitation, fs, samples, level, input DOF, feature names); the report's
# harmonic test at 2560 Hz (half its 16384 samples; recorded from the switch-on, as the
# validation simulates from rest), its hammer test (1024 at 320 Hz, floor 1)
TYPES = {
    "random 12 N RMS, 640 Hz x 8192": (None, 640.0, 8192, 12.0, 1,
                                       ("ks", "ad", "acf_corr", "srs_peak", "srs_rms")),
    # the bumper closes 16-26 times in a 12 N RMS record, ~260 times at 24 N RMS
    "random 24 N RMS, 640 Hz x 8192": (None, 640.0, 8192, 24.0, 1,
                                       ("ks", "ad", "acf_corr", "srs_peak", "srs_rms")),
    "sine 54 Hz 7 N RMS, 2560 Hz x 8192": (synth.Sine(54.0, lead_s=0.0), 2560.0, 8192, 7.0, 1,
                                           ("thd", "cep_env", "holder_min")),
    "hammer 300 N at floor 1, 320 Hz x 1024": (synth.Hammer(), 320.0, 1024, 300.0, 2,
                                               ("d10", "decay", "decay_y0")),
}
CHANNEL = "acc4"
# the DAQ anti-alias filter of each test type (synth.daq_filter; the others: the default)
DAQ = {"hammer 300 N at floor 1, 320 Hz x 1024": "alias-free"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--types", default="", help="only the test types whose name has this")
    ap.add_argument("--daq", choices=synth.DAQ_KINDS, default=None)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("dynval").setLevel(logging.ERROR)
    m0 = mdl.load(a.model)
    hard = dataclasses.replace(mc.BUMPER, delta_m=1e-7)
    truths = {"bumper": synth.Truth(elements=(mc.BUMPER,), label="bumper"),
              "hard bumper": synth.Truth(elements=(hard,), label="hard"),
              "clean": synth.Truth(label="clean")}
    lines = [("| test | feature | FAIL on bumper data (power) | on hard-bumper data | "
             "on clean data (false alarm) |"), "|---|---|---|---|---|"]
    extra = ["", ("| test | truth | harmonic peaks (mean count) | THD dB | Holder drop-offs "
             "per test | hits / onsets | false alarms |"), "|---|---|---|---|---|---|---|"]
    t0 = time.perf_counter()
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    for tname, (exc, fs, n, level, dof, names) in TYPES.items():
        if a.types not in tname:
            continue
        daq = a.daq or DAQ.get(tname, "butter8")
        m = dataclasses.replace(m0, input=mdl.Input("force", dof, "force_N"))
        fails = {(tr, nm): 0 for tr in truths for nm in names}
        for tr, truth in truths.items():
            if tr == "hard bumper" and isinstance(exc, synth.Hammer):
                continue  # the soft bumper's power is 20 of 20 already
            # per kind of record (0: from the switch-on, 1: steady state)
            counts, thd, drops, hits, ons, fas = ([[], []] for _ in range(6))
            for seed in seeds:
                onsets: list[np.ndarray] = []
                recs = synth.generate(m, truth, n_tests=10, levels_n_rms=(level,), fs_hz=fs,
                                      n_samples=n, excitation=exc, fine=mc.FINE, seed=seed,
                                      onsets=onsets, daq=daq)
                for nm in names:
                    res, _ = study.validate(m, recs, f"{nm}@{CHANNEL}")
                    fails[(tr, nm)] += res["verdict"]["verdict"] == "FAIL"
                if isinstance(exc, synth.Sine):
                    steady: list[np.ndarray] = []
                    recs += synth.generate(m, truth, n_tests=10, levels_n_rms=(level,),
                                           fs_hz=fs, n_samples=n, excitation=synth.Sine(
                                               exc.f_hz), fine=mc.FINE, seed=seed,
                                           onsets=steady, daq=daq)
                    for k, (r, on) in enumerate(zip(recs, onsets + steady, strict=True)):
                        x = r.channel("acc4_mps2").data
                        hp = spectral.harmonic_peaks(x, fs)
                        d = holder.drops_of(x, fs)
                        h, fa = holder.match_events(d.times_s, on, 0.004)
                        for tally, v in zip((counts, thd, drops, hits, ons, fas),
                                            (hp.count, hp.thd_db, d.count, h, on.size, fa),
                                            strict=True):
                            tally[k // 10].append(v)
                log.info("%s %s seed %d (%.0f s)", tname, tr, seed, time.perf_counter() - t0)
            for j, kind in enumerate(("from switch-on", "steady state")):
                if counts[j]:
                    extra.append(f"| {tname}, {kind} | {tr} | {np.mean(counts[j]):.1f} | "
                                 f"{np.mean(thd[j]):.1f} | {np.mean(drops[j]):.1f} | "
                                 f"{sum(hits[j])} / {sum(ons[j])} | {sum(fas[j])} |")
        for nm in names:
            hb = ("-" if isinstance(exc, synth.Hammer)
                  else f"{fails[('hard bumper', nm)]} of {a.seeds}")
            tn = tname if daq == "butter8" else f"{tname}, {daq} DAQ"
            lines.append(f"| {tn} | `{nm}@{CHANNEL}` | {fails[('bumper', nm)]} of {a.seeds} "
                         f"| {hb} | {fails[('clean', nm)]} of {a.seeds} |")
    head = ("# Catalogue features: `dynval validate` verdicts of the linear model "
            "(bench/catalogue_error_rates.py)")
    text = "\n".join([head, "", *lines, *extra, "",
                      f"{a.seeds} seeds ({seeds.start}-{seeds.stop - 1}), 10 tests each; "
                      f"{time.perf_counter() - t0:.0f} s."])
    log.info("%s", text)
    if a.out is not None:
        a.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
