"""The `dynval` command: a thin argparse front over the sub-command modules cmd_<name>.py."""
from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import typing
from collections.abc import Sequence

from dynval import __version__
from dynval.errors import DynvalError

log = logging.getLogger("dynval")

# Each name maps to dynval.cmd_<name>, which defines add_parser(sub) and run(args) -> int.
COMMANDS = ("features", "simulate", "residual", "replay", "log", "run", "inspect", "discover",
            "validate", "calibrate", "recover", "convert")


# Third-party libraries whose INFO lines ("NumExpr defaulting to 2 threads", font caches) are
# noise in a dynval run: WARNING and above unless -v.
QUIET_LIBRARIES = ("matplotlib", "numexpr", "PIL", "asammdf", "canmatrix", "h5py", "pyuff",
                   "distributed", "fsspec", "can")


class _Parser(argparse.ArgumentParser):
    """argparse with the usage-error exit code EXIT_USAGE (its own is 2, dynval's bad input)."""

    def error(self, message: str) -> typing.NoReturn:
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="dynval", description="Structural-dynamics model "
                                "validation: features, replay, logging, validation.")
    p.add_argument("--version", action="version", version=f"dynval {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="more log output (-vv: tracebacks)")
    p.add_argument("--debug", action="store_true",
                   help="show the traceback of any error (as -vv does)")
    p.add_argument("-q", "--quiet", action="store_true", help="warnings and errors only, no bars")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"dynval.cmd_{name}").add_parser(sub)
    for sp in sub.choices.values():  # `dynval CMD ... --debug` as well as `dynval --debug CMD`
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of any error")
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
    for name in QUIET_LIBRARIES:
        logging.getLogger(name).setLevel(logging.WARNING if level >= logging.INFO and
                                         not args.verbose else logging.NOTSET)
    if not getattr(args, "run", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    return _run_reporting(args)


# exit codes: 2 bad input (a DynvalError, one line naming the file), 3 an internal error (a bug
# in dynval: one line, --debug shows the traceback), 64 a usage error (unknown option, missing
# argument: sysexits' EX_USAGE, argparse's usage line), 130 interrupted, 141 stdout closed (the
# shell's code for a SIGPIPE death, as when piped into `head`). A command's verdict (a FAIL,
# an effect found) has its own codes, documented with the command.
EXIT_INPUT, EXIT_INTERNAL, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_PIPE = 2, 3, 64, 130, 141


def _run_reporting(args: argparse.Namespace) -> int:
    """Run the sub-command; every exception becomes one log line and an exit code."""
    tracebacks = args.debug or args.verbose >= 2
    try:
        rc = int(args.run(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return rc
    except DynvalError as exc:
        if tracebacks:
            log.exception("dynval failed")
        # one line whatever a library's text quoted in it holds (a damaged file's names)
        log.error("%s", _one_line(str(exc), limit=None))
        return EXIT_INPUT
    except KeyboardInterrupt:
        log.error("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_PIPE
    except OSError as exc:  # the machine, not the input: a full disk, a permission
        if tracebacks:
            log.exception("dynval failed")
        log.error("%s: %s", exc.filename or "I/O error", exc.strerror or exc)
        return EXIT_INPUT
    except Exception as exc:  # noqa: BLE001 - the one top-level handler of unexpected errors
        if tracebacks:
            log.exception("internal error")
        log.error("internal error: %s: %s (a bug in dynval; rerun with --debug for the "
                  "traceback)", type(exc).__name__, _one_line(str(exc)))
        return EXIT_INTERNAL


def _one_line(text: str, limit: int | None = 200) -> str:
    """text on one line (its whitespace runs, newlines too, as one space), cut to limit."""
    t = " ".join(text.split())
    return t if limit is None or len(t) <= limit else t[: limit - 3] + "..."


def _silence_stdout() -> None:
    """The reader of stdout went away (`dynval ... | head`): send what is still buffered to
    /dev/null, so the interpreter's flush at exit neither fails nor prints a traceback."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout without a descriptor (captured in a test)
        pass
