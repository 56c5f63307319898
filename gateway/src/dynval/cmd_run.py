"""`dynval run TEST|FOLDER -o OUTDIR`: for each recorded test, the firmware loop, the MCAP
logger and the replay on one bus; one MCAP per test with the raw frames, the decoded samples,
the firmware's features and residuals; then a summary.

--bus auto (default): vcan0 with the firmware_sim program when this kernel has vcan and the
program is found, else the same firmware loop in-process over python-can's virtual bus."""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    Progress,
    add_test_options,
    fmt_timing,
    nonnegative_int,
    number_in,
    positive_int,
    read_with_options,
    stop_signals,
    test_files,
)
from dynval.errors import ConfigError
from dynval.io.mcapfile import iter_messages
from dynval.topics import T_RESID


def add_parser(sub: Any) -> None:
    p = sub.add_parser("run", help="replay tests through the firmware loop, log one MCAP each")
    p.add_argument("tests", type=Path, nargs="+", help="recorded test files or folders")
    p.add_argument("-o", "--output", type=Path, required=True, help="output folder")
    p.add_argument("--bus", choices=("auto", "socketcan", "virtual"), default="auto",
                   help="auto: vcan0 + firmware_sim when available, else in-process "
                   "(%(default)s)")
    p.add_argument("--channel", default="vcan0", help="SocketCAN interface (%(default)s)")
    p.add_argument("--firmware", default=None, help="firmware_sim program (default: "
                   "$DV_FIRMWARE_SIM, PATH, build/*/firmware_sim/firmware_sim)")
    p.add_argument("--model", type=Path, default=None, help="model driving the firmware's "
                   "observer (default: declared_model.json beside the test, if any)")
    p.add_argument("--no-model", action="store_true", help="observer off")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--speed", type=float, default=1.0, help="replay speed (%(default)s)")
    g.add_argument("--asap", action="store_true", help="replay as fast as the bus takes it")
    p.add_argument("--win", type=positive_int, default=256, help="firmware window (%(default)s)")
    p.add_argument("--seg", type=positive_int, default=64, help="firmware segment (%(default)s)")
    p.add_argument("--nseg", type=positive_int, default=64,
                   help="segments per record (%(default)s)")
    p.add_argument("--ar-order", type=nonnegative_int, default=0,
                   help="firmware AR stage (%(default)s)")
    p.add_argument("--resid-decim", type=positive_int, default=1,
                   help="a residual frame every N observer steps (%(default)s)")
    p.add_argument("--obs-q", type=number_in(0.0, math.inf), default=0.0,
                   help="observer process noise N^2 (0 = open-loop prediction)")
    p.add_argument("--obs-r", type=number_in(0.0, math.inf), default=0.0,
                   help="observer measurement noise")
    add_test_options(p)
    p.set_defaults(run=run)


def _model_for(test: Path, args: argparse.Namespace) -> Any:
    if args.no_model:
        return None
    path = args.model or (test.parent / "declared_model.json")
    if args.model is None and not path.is_file():
        return None
    from dynval import model as mdl

    return mdl.load(path)


def resid_rms(mcap: Path) -> dict[str, float]:
    acc: dict[str, list[float]] = {}
    for m in iter_messages(mcap, topics={T_RESID}):
        v = m.data["value"]
        a = acc.setdefault(m.data["name"], [0.0, 0.0])
        a[0] += v * v
        a[1] += 1
    return {k: math.sqrt(s / n) for k, (s, n) in acc.items() if n}


def run(args: argparse.Namespace) -> int:
    from dynval import model as mdl
    from dynval import runloop

    tests = test_files(args.tests, besides=args.model)
    choice = runloop.choose_bus(args.bus, args.channel, args.firmware)
    print(f"bus: {choice.interface}:{choice.channel}, firmware: {choice.firmware}")
    fw_kw = {"win_len": args.win, "seg_len": args.seg, "n_seg": args.nseg,
             "ar_order": args.ar_order, "resid_decim": args.resid_decim,
             "obs_q": args.obs_q, "obs_r": args.obs_r}
    rows = []
    for i, test in enumerate(tests, 1):
        rec = read_with_options(test, args)
        m = _model_for(test, args)
        if m is not None and not any(c.role == "input" for c in rec.channels):
            raise ConfigError(f"{test}: the model needs an input channel (use --channel-map)")
        stem = f"{runloop.safe_name(test.parent.name)}_{runloop.safe_name(rec.name)}"
        out = args.output / f"{stem}.mcap"
        with Progress(args) as bars, stop_signals() as stop:  # the log gets its footer
            r = runloop.run_test(rec, out, choice, model=m, stop=stop,
                                 model_meta=mdl.to_dict(m) if m is not None else None,
                                 speed=args.speed, asap=args.asap, fw_kw=fw_kw, record_id=i,
                                 on_progress=bars.counter(
                                     rec.name, rec.n_samples * len(rec.channels) // 3))
        rms = resid_rms(out)
        seq = r.log_summary["sequence"]
        lost = sum(v["lost"] for v in seq.values())
        st = r.log_summary.get("last_status") or {}
        rows.append((test, r, rms, lost))
        print(f"{test}: {r.replay.frames_sent} frames sent in {r.replay.wall_s:.1f} s, "
              f"{r.features} features, {r.residuals} residuals, lost {lost} "
              f"(firmware: lost {st.get('lost', '?')}, dup {st.get('dup', '?')}) -> {out}")
        if not args.asap:
            print(f"  {fmt_timing(r.replay.timing)}")
        if rms:
            print("  residual RMS: " + ", ".join(f"{k} {v:.4g}" for k, v in rms.items()))
        if rec.warnings:
            print(f"  {len(rec.warnings)} reader warnings (see the log)")
    print(f"{len(rows)} test(s), {sum(r.features for _, r, _, _ in rows)} features, "
          f"{sum(r.residuals for _, r, _, _ in rows)} residuals, "
          f"{sum(lost for *_, lost in rows)} frames lost; MCAP files in {args.output}")
    return 0 if all(lost == 0 for *_, lost in rows) else 1
