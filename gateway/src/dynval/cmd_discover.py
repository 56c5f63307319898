"""`dynval discover MODEL TESTS... --json OUT.json --html OUT.html --model-out UPDATED`:
find what the declared model lacks, add it, and report the error before and after."""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    add_test_options,
    check_writable,
    nonnegative_int,
    number_in,
    read_tests,
)
from dynval.errors import ConfigError, InputFileError
from dynval.io import Recording

log = logging.getLogger(__name__)

# exit codes CI gates on (2 is bad input, 3 an internal error, as every command's)
EXIT_EXPLAINED = 0  # no effect: the declared model explains the tests to the noise floor
EXIT_LACKS = 1  # the declared model lacks an effect (found and fitted, or none in the library)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("discover", help="find the effect a declared model lacks, add it, "
                       "report the error before and after",
                       epilog=f"exit code: {EXIT_EXPLAINED} the declared model explains the "
                       f"tests to the noise floor, {EXIT_LACKS} it lacks something (the "
                       "effects found, or a residual no effect in the library explains), 2 bad "
                       "input")
    p.add_argument("model", type=Path, help="declared model (dynval format or declared_model)")
    p.add_argument("tests", type=Path, nargs="+", help="measured tests (files or folders)")
    p.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="JSON report")
    p.add_argument("--html", type=Path, default=None, metavar="OUT.html", help="HTML report")
    p.add_argument("--model-out", type=Path, default=None, metavar="UPDATED",
                   help="write the model with the accepted effects (dynval format)")
    p.add_argument("--max-effects", type=nonnegative_int, default=3,
                   help="at most this many effects")
    p.add_argument("--min-gain", type=number_in(0.0, 1.0, hi_open=True), default=0.10,
                   help="held-out SSE reduction an effect must bring (default 0.10)")
    p.add_argument("--noise", default=None, metavar="FRACTION|CH=RMS,...",
                   help="stated sensor noise: one number is a fraction of each channel's RMS; "
                        "CH=RMS pairs give a channel's noise RMS in its own units (default: "
                        "estimated from the data: repeated or periodic inputs, input-off "
                        "stretches, or the residual outside the input band)")
    p.add_argument("--uncertain", default="", metavar="P1,P2",
                   help="declared parameters that are uncertain (model parameter names, e.g. "
                        "zeta2,zeta4 or k1,beta): calibrated first, then re-adjusted jointly "
                        "with every candidate effect")
    p.add_argument("--no-readjust", action="store_true",
                   help="keep the declared stiffness, mass and damping fixed while testing "
                        "effects (default: re-adjust those at each candidate's location and "
                        "the modal damping, as a best-linear declared model needs)")
    p.add_argument("--workers", type=nonnegative_int, default=0, metavar="N",
                   help="processes for the candidate fits (default: $DYNVAL_WORKERS, else every "
                        "available core; the results do not depend on it)")
    p.add_argument("--declared-simulation", action="store_true",
                   help="simulate with the declared model's input interpolation and "
                        "oversampling (default: the core's cubic input hold at the sample "
                        "rate where it is as good on the declared model, several times "
                        "faster; the report says which)")
    add_test_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Exit code: EXIT_EXPLAINED or EXIT_LACKS, the verdict's."""
    from dynval import model as mdl
    from dynval.discover import loop, report

    t0 = time.perf_counter()
    check_writable(args.model_out, args.json, args.html)
    m = mdl.load(args.model)
    recs = read_tests(args.tests, args, besides=args.model)
    for rec in recs:
        _preflight(m, rec)
    noise = _stated_noise(args.noise, m, recs) if args.noise is not None else None
    unc = tuple(x.strip() for x in args.uncertain.split(",") if x.strip())
    opts = loop.Options(max_effects=args.max_effects, min_gain=args.min_gain, noise=noise,
                        uncertain=unc, readjust=not args.no_readjust,
                        workers=args.workers, declared_simulation=args.declared_simulation)
    try:
        res = loop.discover(m, recs, opts, on_progress=lambda s: log.debug("%s", s))
    except Exception:
        for rec in recs:  # a declared model that diverges on a test: the element and the file
            mdl.simulate_recording(m, rec)
        raise
    units = {c.name: c.unit for rec in recs for c in rec.channels if c.unit}
    doc = report.to_json(res, str(args.model), str(args.model_out or ""), units=units)
    written = {what: str(path) for what, path in (
        ("updated model", args.model_out), ("JSON report", args.json),
        ("HTML report", args.html)) if path is not None}
    if args.model_out is not None:
        mdl.save(res.model, args.model_out)
        log.info("wrote %s (updated model)", args.model_out)
    if args.json is not None:
        report.write_json(doc, args.json)
        log.info("wrote %s (JSON report)", args.json)
    if args.html is not None:
        report.write_html(res, doc, args.html, written=written)
        log.info("wrote %s (HTML report)", args.html)
    print(doc["verdict"])
    for e in doc["effects"]:
        ps = ", ".join(f"{k} = {v['value']:.5g} +/- {v['uncertainty'] or float('nan'):.2g}"
                       f"{_unit(v['unit'])}" for k, v in e["parameters"].items())
        print(f"  {e['label']}: {ps}")
        for k, v in e.get("readjusted", {}).items():
            print(f"    re-adjusted {k}: {v['before']:.5g} -> {v['value']:.5g}{_unit(v['unit'])} "
                  f"({100 * v['change_rel']:+.1f} %)")
    width = max(8, *(len(c) for c in res.chans))
    uw = max(4, *(len(units.get(c, "")) for c in res.chans))
    print(f"  {'channel':<{width}} {'unit':<{uw}} {'held-out rmse before':>21} {'after':>12} "
          f"{'noise':>10}  noise from")
    for c in res.chans:
        b = doc["rmse_before"]["held_out"][c]
        a = doc["rmse_after"]["held_out"][c]
        how = doc["noise_method"].get(c, {}).get("method", "")
        print(f"  {c:<{width}} {units.get(c, ''):<{uw}} {b:>21.5g} {a:>12.5g} "
              f"{doc['noise_floor'][c]:>10.4g}  {how}")
    mah = doc["mahalanobis"]
    print(f"  Mahalanobis (paired) before {_g(mah.get('before'))}, after "
          f"{_g(mah.get('after'))}; paired test p before {_g(mah.get('p_before'))}, after "
          f"{_g(mah.get('p_after'))}")
    log.info("discover: %d tests in %.1f s", len(recs), time.perf_counter() - t0)
    sys.stdout.flush()
    explained = not doc["effects"] and doc["verdict"].startswith("no effect: ")
    return EXIT_EXPLAINED if explained else EXIT_LACKS


MIN_SAMPLES = 64  # the input band and the noise floor need spectra of some length
MAX_ABS = 1e150  # squares and sums of squares of a test's samples stay finite (double)


def _preflight(m: Any, rec: Recording) -> None:
    """What discover needs of a test, as one-line errors naming the file: enough samples, a
    measured input that is not zero throughout, samples whose squares are finite and none
    missing (a NaN --lenient kept). (A declared
    model that diverges is named by run() when the loop fails, not simulated twice here.)"""
    import numpy as np

    from dynval import model as mdl
    from dynval.io.arrays import release_pages

    where = rec.source or rec.name
    if rec.n_samples < MIN_SAMPLES:
        raise InputFileError(where, f"discover needs at least {MIN_SAMPLES} samples, found "
                             f"{rec.n_samples}")
    for c in rec.channels:
        for a in range(0, c.data.size, 1 << 20):  # a long record: a block at a time
            block = c.data[a:a + (1 << 20)]
            big = np.flatnonzero(np.abs(block) > MAX_ABS)
            if big.size:
                raise InputFileError(where, f"channel {c.name}: sample {a + int(big[0])} is "
                                     f"{c.data[a + big[0]]:.3g}, beyond what discover's least "
                                     f"squares take (|x| <= {MAX_ABS:g}); rescale the channel")
            gap = np.flatnonzero(~np.isfinite(block))
            if gap.size:  # kept by --lenient: the simulations and spectra need every sample
                missing = int(np.count_nonzero(~np.isfinite(c.data)))
                raise InputFileError(where, f"channel {c.name}: {missing} missing sample(s), "
                                     f"the first at sample {a + int(gap[0])}: discover needs "
                                     "complete records (cut the test around them)")
        release_pages(c.data)  # a memory-mapped record: its pages go once checked
    u = rec.channel(mdl.input_channel(m, rec)).data
    if not np.any(np.nan_to_num(u) != 0):
        raise InputFileError(where, "the input channel is zero throughout (an ambient or "
                             "free-decay test): discover needs a measured input")


def _unit(u: str) -> str:
    """' m/s^2' after a number; nothing for a dimensionless one (the reports' '1')."""
    return "" if u in ("", "1") else f" {u}"


def _g(x: Any) -> str:
    return f"{x:.3g}" if isinstance(x, float) else "n/a"


def _stated_noise(text: str, m: Any, recs: Any) -> dict[str, float]:
    """--noise: a fraction of each channel's RMS, or CH=RMS pairs in channel units."""
    import numpy as np

    def number(s: str) -> float:
        try:
            v = float(s)
        except ValueError:
            raise ConfigError(f"--noise: '{s}' is not a number") from None
        if not (v > 0 and np.isfinite(v)):
            raise ConfigError(f"--noise must be > 0 and finite, got {s}")
        return v

    if "=" not in text:
        frac = number(text)
        out = {}
        for c in m.outputs:
            vals = [r.channel(c).data for r in recs if c in r.names]
            if vals:
                out[c] = frac * float(np.sqrt(np.mean(np.concatenate(vals) ** 2)))
        return out
    out = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        name = name.strip()
        if name not in m.outputs:
            raise ConfigError(f"--noise: '{name}' is not an output channel of the model "
                              f"(outputs: {', '.join(m.outputs)})")
        out[name] = number(value)
    return out
