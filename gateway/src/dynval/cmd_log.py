"""`dynval log -o FILE.mcap`: record the dynval bus to MCAP until Ctrl-C / SIGTERM (or
--duration / --idle-timeout); the file is finalised on exit. `-o FILE.blf` (.asc, .trc,
candump .log) writes the raw frames with python-can's writer for that format instead. The bus
is any python-can interface (--interface/--channel/--bitrate, CAN_INTERFACE, ~/.canrc)."""
from __future__ import annotations

import argparse
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dynval.cli_common import (
    add_bus_options,
    add_test_options,
    bus_config_of,
    number_in,
    positive_int,
    read_with_options,
    stop_signals,
)
from dynval.errors import InputFileError


def add_parser(sub: Any) -> None:
    p = sub.add_parser("log", help="record the CAN bus to an MCAP file (or a CAN log)")
    p.add_argument("-o", "--output", type=Path, required=True, help="file to write: .mcap "
                   "(decoded, for dynval and Foxglove) or a CAN log .asc, .blf, .trc, .log "
                   "(raw frames)")
    add_bus_options(p)
    p.add_argument("--test", type=Path, default=None,
                   help="the recorded test being replayed: its name, channel map, rate, units "
                   "and hash go into the metadata record")
    p.add_argument("--model", type=Path, default=None, help="model file (metadata only)")
    p.add_argument("--duration", type=number_in(0.0, math.inf), default=None,
                   help="stop after S seconds (0: when stopped)")
    p.add_argument("--idle-timeout", type=number_in(0.0, math.inf), default=None,
                   help="stop after S seconds without a frame")
    p.add_argument("--chunk-kb", type=positive_int, default=4096,
                   help="MCAP chunk size, KiB uncompressed (%(default)s; a chunk is also closed "
                   "every 0.5 s)")
    add_test_options(p)  # of --test
    p.set_defaults(run=run)


def _until(stop: threading.Event, t_end: float | None) -> Callable[[], bool]:
    """Log until a stop signal or, with --duration, its end."""
    return lambda: stop.is_set() or (t_end is not None and time.monotonic() > t_end)


def run(args: argparse.Namespace) -> int:
    from dynval import bus, canlog
    from dynval.mcap_log import McapLog, log_bus
    from dynval.runloop import recording_meta

    cfg = bus_config_of(args)
    t_end = time.monotonic() + args.duration if args.duration else None
    if args.output.suffix.lower() != ".mcap":
        if args.output.suffix.lower() not in canlog.LOG_SUFFIXES:
            raise InputFileError(args.output, "the output is an .mcap or a CAN log "
                                 f"({', '.join(canlog.LOG_SUFFIXES)})")
        b = bus.open_bus(cfg)
        n = 0
        try:
            with stop_signals() as stop:
                n = canlog.record(b, args.output, idle_timeout_s=args.idle_timeout,
                                  stop=_until(stop, t_end))
        except KeyboardInterrupt:  # a second signal
            pass
        finally:
            b.shutdown()
        print(f"{args.output}: {n} frames from {bus.describe(cfg)}")
        return 0
    meta: dict[str, Any] = {}
    names: list[str] = []
    if args.test is not None:
        rec = read_with_options(args.test, args)
        meta = recording_meta(rec, bus.make_plan(rec))
        names = [c.name for c in rec.channels]
    if args.model is not None:
        from dynval import model

        meta["model"] = model.to_dict(model.load(args.model))
    b = bus.open_bus(cfg)
    out = McapLog(args.output, meta=meta, channel_names=names, chunk_size=args.chunk_kb * 1024)

    n = 0
    try:
        with stop_signals() as stop:
            n = log_bus(b, out, stop=_until(stop, t_end), idle_timeout_s=args.idle_timeout)
    except KeyboardInterrupt:  # a second signal
        pass
    finally:
        s = out.close()
        b.shutdown()
    total = sum(s["messages"].values())
    print(f"{args.output}: {total} messages ({s['messages'].get('/can/raw', n)} frames), "
          f"events {s['events'] or 'none'}")
    return 0
