"""`dynval convert IN -o OUT`: between dynval MCAP logs and standard CAN logs, through
python-can's own readers and writers: an MCAP's raw frames to candump -L (.log), Vector ASC
(.asc) or BLF (.blf), PEAK TRC (.trc) at their log times; a CAN log's frames decoded by the C
codec into a dynval MCAP, as `dynval log` would have written it."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from dynval.errors import InputFileError


def add_parser(sub: Any) -> None:
    p = sub.add_parser("convert", help="MCAP log <-> CAN log (candump .log, .asc, .blf, .trc)")
    p.add_argument("input", type=Path, help="a dynval .mcap, or a CAN log")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the file to write; its suffix picks the format")
    p.add_argument("--can-channel", default="can0",
                   help="interface name written on candump lines (%(default)s)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dynval import canlog

    src, out = args.input, args.output
    if not src.is_file():
        raise InputFileError(src, "no such file")
    if src.suffix.lower() == ".mcap":
        n = canlog.mcap_to_log(src, out, channel=args.can_channel)
        print(f"{out}: {n} frames from {src}")
        return 0
    if not canlog.is_can_log(src):
        raise InputFileError(src, "neither a dynval .mcap nor a CAN log "
                             f"({', '.join(canlog.LOG_SUFFIXES)})")
    if out.suffix.lower() == ".mcap":
        s = canlog.log_to_mcap(src, out)
        print(f"{out}: {sum(s['messages'].values())} messages from {src}, events "
              f"{s['events'] or 'none'}")
        return 0
    w = canlog.open_writer(out)
    n = 0
    try:
        for m in canlog.frames(src):
            w.on_message_received(m)
            n += 1
    finally:
        w.stop()
    print(f"{out}: {n} frames from {src}")
    return 0
