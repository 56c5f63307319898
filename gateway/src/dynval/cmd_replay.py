"""`dynval replay TEST`: send a recorded test as dynval CAN frames, paced by its sample clock
(or --speed N times faster, or --asap), then report the timing fidelity. A CAN log (.asc, .blf,
.trc, candump .log) is sent as recorded, frame by frame at its own timestamps. The bus is any
python-can interface (--interface/--channel/--bitrate, CAN_INTERFACE, ~/.canrc). On SocketCAN a
recorded test is paced by dv_pacer (firmware_sim/pacer.c) when it is built; elsewhere, and for
CAN logs, by Python (dynval.pacing)."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    Progress,
    add_bus_options,
    add_test_options,
    bus_config_of,
    fmt_timing,
    int_in,
    read_with_options,
    stop_point,
    stop_signals,
)

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("replay", help="send a recorded test (DBC sample frames) or a CAN log "
                       "on a CAN bus")
    p.add_argument("test", type=Path, help="recorded test (csv, txt, json, mcap) or CAN log "
                   "(asc, blf, trc, candump log)")
    add_bus_options(p)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--speed", type=float, default=1.0,
                   help="replay N times faster than recorded (%(default)s)")
    g.add_argument("--asap", action="store_true", help="as fast as the bus takes frames")
    p.add_argument("--realtime", action="store_true",
                   help="pace at SCHED_FIFO priority (root, CAP_SYS_NICE or an rtprio limit): "
                   "other processes cannot delay the frames")
    p.add_argument("--pacer", choices=("auto", "python", "c"), default="auto",
                   help="who keeps time: c = dv_pacer (SocketCAN only; found as $DV_PACER, on "
                   "PATH or in build/*/firmware_sim), python = dynval.pacing, auto = c on "
                   "SocketCAN when dv_pacer is found (%(default)s)")
    p.add_argument("--record-id", type=int_in(0, 0xFFFFFFFF), default=1,
                   help="DV_CTRL record_id (%(default)s)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    add_test_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dynval import bus, canlog, pacing

    cfg = bus_config_of(args)
    if canlog.is_can_log(args.test):
        return _replay_log(args, cfg)
    rec = read_with_options(args.test, args)
    plan = bus.make_plan(rec, args.record_id)
    exe = _c_pacer(args, cfg)
    if exe is not None:
        bus.open_bus(cfg).shutdown()  # a bus that cannot be opened: python-can's error and hint
        with Progress(args) as bars:
            res = pacing.run_pacer(exe, plan.batches(), interface=str(cfg["channel"]),
                                   speed=args.speed, realtime=args.realtime,
                                   on_progress=bars.counter(rec.name, plan.n_frames))
        res.sample_frames = max(0, res.frames_sent - len(plan.setup) - len(plan.stop))
    else:
        b = bus.open_bus(cfg)
        try:
            with Progress(args) as bars, stop_signals() as stop:
                res = bus.replay(b, plan, speed=args.speed, asap=args.asap,
                                 on_progress=bars.counter(rec.name, plan.n_sample_frames),
                                 realtime=args.realtime, hold=lambda _off: stop_point(stop))
        finally:
            b.shutdown()
    if args.json:
        json.dump({"test": rec.name, "frames_sent": res.frames_sent,
                   "sample_frames": res.sample_frames, "wall_s": res.wall_s,
                   "frames_per_s": res.frames_per_s, "send_errors": res.send_errors,
                   "timing": res.timing, "warnings": len(rec.warnings)}, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0 if res.send_errors == 0 else 1
    log.info("paced by %s", exe if exe is not None else "python (dynval.pacing)")
    print(f"{rec.name}: {res.frames_sent} frames ({res.sample_frames} sample frames, "
          f"{len(rec.channels)} ch x {rec.n_samples} samples at {rec.fs_hz:g} Hz) in "
          f"{res.wall_s:.2f} s = {res.frames_per_s:.0f} frames/s on {bus.describe(cfg)}")
    if not args.asap:
        print(f"timing vs the recorded clock (x{args.speed:g}): {fmt_timing(res.timing)}")
    if res.send_errors:
        print(f"{res.send_errors} frames could not be sent")
    if rec.warnings:
        print(f"{len(rec.warnings)} reader warnings (see the log)")
    return 0 if res.send_errors == 0 else 1


def _c_pacer(args: argparse.Namespace, cfg: dict[str, Any]) -> Path | None:
    """dv_pacer when --pacer asks for it (or auto finds it on SocketCAN), else None."""
    from dynval.errors import ConfigError
    from dynval.pacing import find_pacer

    socketcan = cfg.get("interface") == "socketcan"
    if args.pacer == "python" or args.asap or (args.pacer == "auto" and not socketcan):
        return None
    if not socketcan:
        raise ConfigError(f"--pacer c sends on SocketCAN only, not on {cfg.get('interface')}")
    exe = find_pacer()
    if exe is None and args.pacer == "c":
        raise ConfigError("--pacer c: dv_pacer not found (build with -DDV_BUILD_SIM=ON, or set "
                          "DV_PACER to its path)")
    return exe


def _replay_log(args: argparse.Namespace, cfg: dict[str, Any]) -> int:
    """A CAN log, frame by frame at its recorded times."""
    from dynval import bus, canlog
    from dynval.pacing import tight_timing

    b = bus.open_bus(cfg)
    try:
        with Progress(args) as bars, tight_timing(args.realtime and not args.asap):
            res = canlog.replay_log(b, args.test, speed=args.speed, asap=args.asap,
                                    on_progress=bars.counter(args.test.name, 0))
    finally:
        b.shutdown()
    if args.json:
        json.dump({"log": str(args.test), "frames_sent": res.frames_sent, "wall_s": res.wall_s,
                   "frames_per_s": res.frames_per_s, "send_errors": res.send_errors,
                   "timing": res.timing}, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(f"{args.test}: {res.frames_sent} frames in {res.wall_s:.2f} s = "
              f"{res.frames_per_s:.0f} frames/s on {bus.describe(cfg)}")
        if not args.asap and res.timing.get("frames"):
            print(f"timing vs the log's timestamps (x{args.speed:g}): "
                  f"{fmt_timing(res.timing)}")
        if res.send_errors:
            print(f"{res.send_errors} frames could not be sent")
    return 0 if res.send_errors == 0 else 1
