"""The `dynval` command: a thin argparse front over the sub-command modules cmd_<name>.py."""
from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from dynval import __version__
from dynval.errors import DynvalError

log = logging.getLogger("dynval")

# Each name maps to dynval.cmd_<name>, which defines add_parser(sub) and run(args) -> int.
COMMANDS = ("features", "simulate", "residual", "replay", "log", "run", "inspect", "discover",
            "validate", "calibrate")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dynval", description="Structural-dynamics model "
                                "validation: features, replay, logging, validation.")
    p.add_argument("--version", action="version", version=f"dynval {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="more log output (-vv: tracebacks)")
    p.add_argument("-q", "--quiet", action="store_true", help="warnings and errors only, no bars")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"dynval.cmd_{name}").add_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose else logging.INFO)
    root = logging.getLogger()
    if not root.handlers:  # keep handlers a host application (or pytest) installed
        h = logging.StreamHandler(sys.stderr)
        h.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        root.addHandler(h)
    root.setLevel(level)
    if not getattr(args, "run", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.run(args))
    except DynvalError as exc:
        if args.verbose >= 2:
            log.exception("dynval failed")
        log.error("%s", exc)
        return 2
    except KeyboardInterrupt:
        log.error("interrupted")
        return 130
