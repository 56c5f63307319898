"""Shared pieces of the sub-commands: the options and the reading of recorded tests (every
command that reads tests takes --fs, --channel-map and --lenient and collects folders with
io.collect_tests), the options of the validation studies, progress bars and timing text.

Nothing here (nor at the top of a cmd_<name> module) loads the C core: commands import what
needs it inside run(), so `dynval --help` works without the compiled core and a missing core is
one error line and exit 2."""
from __future__ import annotations

import argparse
import importlib
import logging
import math
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any

from dynval.errors import InputFileError
from dynval.io import Recording, collect_tests, load_channel_map, read_test

log = logging.getLogger(__name__)


def int_in(lo: int, hi: int | None = None) -> Callable[[str], int]:
    """argparse type of an integer in lo..hi (no upper end when hi is None): a usage error
    naming the option otherwise, never a value wrapped or clipped later."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"must be >= {lo}: {v}" if hi is None
                                             else f"must be {lo}..{hi}: {v}")
        return v
    return parse


def number_in(lo: float, hi: float, *, lo_open: bool = False,
              hi_open: bool = False) -> Callable[[str], float]:
    """argparse type of a finite number in [lo, hi] (either end open as asked)."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        above = v > lo if lo_open else v >= lo
        below = v < hi if hi_open else v <= hi
        if not (math.isfinite(v) and above and below):
            raise argparse.ArgumentTypeError(
                f"must be in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}: "
                f"{text}")
        return v
    return parse


nonnegative_int = int_in(0)  # counts such as --workers (0: the default's choice)
positive_int = int_in(1)  # counts such as --runs
open_unit = number_in(0.0, 1.0, lo_open=True, hi_open=True)  # a level such as --level
positive_number = number_in(0.0, math.inf, lo_open=True, hi_open=True)  # a rate such as --fs


def check_writable(*paths: Path | None) -> None:
    """Refuse, before any work, an output path whose folder does not exist or that is a
    folder (discover wrote its reports after a minute's run, then failed)."""
    for path in paths:
        if path is None:
            continue
        if path.is_dir():
            raise InputFileError(path, "cannot write: is a folder")
        if not path.parent.is_dir():
            raise InputFileError(path, f"cannot write: no folder {path.parent}")


def add_test_options(p: Any) -> None:
    """--fs, --channel-map, --lenient: how recorded tests are read."""
    p.add_argument("--fs", type=positive_number, default=None, metavar="HZ",
                   help="sampling rate of whitespace text tests (no time column)")
    p.add_argument("--channel-map", type=Path, default=None, metavar="FILE",
                   help="JSON/YAML channel map: column, name, unit, scale, role, dof")
    p.add_argument("--lenient", action="store_true",
                   help="turn recoverable file problems into counted warnings")


def read_with_options(path: Path, args: argparse.Namespace) -> Recording:
    """One test, read with the options of add_test_options."""
    return read_tests([path], args)[0]


def test_files(paths: Sequence[Path], besides: Path | None = None) -> list[Path]:
    """The test files the paths name (files, folders: io.collect_tests); besides: a file that
    is not a test although it sits in a tests folder (the model)."""
    files = collect_tests(paths)
    if besides is not None:
        files = [f for f in files if f.resolve() != besides.resolve()]
        if not files:
            raise InputFileError(paths[0], f"no tests besides the model file {besides}")
    return files


def read_tests(paths: Sequence[Path], args: argparse.Namespace, *,
               besides: Path | None = None) -> list[Recording]:
    """The tests of test_files(paths, besides), read with the options of add_test_options."""
    files = test_files(paths, besides)
    cmap = load_channel_map(args.channel_map) if args.channel_map else None
    return [read_test(f, lenient=args.lenient, fs_hz=args.fs, channel_map=cmap) for f in files]


class Progress:
    """tqdm bars on stderr, only on a terminal and without --quiet (else no callbacks); every
    bar is closed when the `with` block ends."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.on = not getattr(args, "quiet", False) and sys.stderr.isatty()
        self._bars: list[Any] = []

    def _bar(self, **kw: Any) -> Any:
        bar = importlib.import_module("tqdm").tqdm(leave=False, **kw)
        self._bars.append(bar)
        return bar

    def counter(self, desc: str, total: int) -> Callable[[int], None] | None:
        """on_progress(n): n more frames done."""
        if not self.on:
            return None
        return self._bar(total=total, desc=desc, unit="fr", unit_scale=True).update  # type: ignore[no-any-return]

    def stage(self, desc: str) -> Callable[[int, int], None] | None:
        """A bar per stage of a study (validate.study's progress factory): cb(done, total)."""
        if not self.on:
            return None
        bar = self._bar(desc=desc)

        def cb(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()
        return cb

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, t: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        for b in self._bars:
            b.close()


def add_bus_options(p: Any) -> None:
    """-i/--interface, -c/--channel, -b/--bitrate, --bus-option: a python-can bus as can.Bus
    takes it; what is not given comes from python-can's configuration (CAN_INTERFACE,
    CAN_CHANNEL, CAN_BITRATE, ~/.canrc, can.ini), else socketcan on vcan0."""
    g = p.add_argument_group("CAN bus (python-can configuration)")
    g.add_argument("-i", "--interface", "--bus", dest="interface", default=None,
                   metavar="NAME", help="python-can interface: socketcan, virtual, pcan, "
                   "kvaser, vector, slcan, gs_usb, udp_multicast, ... (default: CAN_INTERFACE "
                   "or ~/.canrc, else socketcan)")
    g.add_argument("-c", "--channel", default=None, help="bus channel, e.g. vcan0, "
                   "PCAN_USBBUS1, 0 (default: CAN_CHANNEL or ~/.canrc, else vcan0)")
    g.add_argument("-b", "--bitrate", type=positive_int, default=None, help="bit rate in bit/s")
    g.add_argument("--bus-option", action="append", default=[], metavar="KEY=VALUE",
                   help="more can.Bus keyword arguments (repeat), e.g. fd=true, "
                   "app_name=CANalyzer, tty_baudrate=115200")


def bus_config_of(args: argparse.Namespace) -> dict[str, Any]:
    """The bus configuration of add_bus_options (bus.bus_config)."""
    from can.util import cast_from_string

    from dynval.bus import bus_config
    from dynval.errors import ConfigError

    opts: dict[str, Any] = {}
    for item in args.bus_option:
        key, eq, val = item.partition("=")
        if not eq or not key.strip():
            raise ConfigError(f"--bus-option {item!r}: expected KEY=VALUE")
        opts[key.strip()] = cast_from_string(val.strip())
    channel: Any = args.channel
    if channel is not None:
        channel = cast_from_string(channel)
    return bus_config(args.interface, channel, args.bitrate, opts)


def add_study_options(p: Any) -> None:
    """Options shared by validate and calibrate."""
    p.add_argument("--model", type=Path, required=True, help="model file (dynval format or "
                   "declared_model.json)")
    p.add_argument("--experiments", type=Path, nargs="+", required=True, metavar="TEST",
                   help="recorded tests (files or folders), the experimental baseline")
    p.add_argument("--features", required=True, metavar="SPEC",
                   help="feature vector, e.g. 'peak,std@acc3,acc4' or 'segstd64@acc4' "
                   "(see gateway/docs/validate-schema.md)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=LO:HI",
                   help="uncertain parameter with a uniform range (repeat), e.g. zeta2=0.01:0.08")
    p.add_argument("--rmse-channel", action="append", default=None, metavar="CH",
                   help="channel(s) of the RMSE (eq. 47) (default: the feature channels)")
    p.add_argument("--seed", type=nonnegative_int, default=0,
                   help="design / MCMC seed (%(default)s)")
    p.add_argument("--workers", type=nonnegative_int, default=None,
                   help="worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the sweeps on a Dask distributed scheduler (tcp://host:8786)")
    p.add_argument("--shrink", choices=("auto", "always", "never"), default="auto",
                   help="Ledoit-Wolf covariance shrinkage (auto: when tests <= features + 1)")
    p.add_argument("--noise", default="auto", metavar="auto|none|FRAC|CH=RMS,...",
                   help="sensor noise the simulated features get, as the measured ones carry "
                   "it: estimated from the tests (auto), none, a fraction of each channel's "
                   "RMS (0.01) or an RMS per channel (%(default)s)")
    p.add_argument("--level", type=open_unit, default=0.95,
                   help="confidence level of the verdict: an exactly right model fails in "
                   "1 - level of studies (%(default)s)")
    p.add_argument("--json", dest="json_out", type=Path, default=None, metavar="OUT",
                   help="write the JSON result here")
    p.add_argument("--html", dest="html_out", type=Path, default=None, metavar="OUT",
                   help="write the self-contained HTML report here")
    add_test_options(p)


def study_inputs(args: argparse.Namespace) -> tuple[Any, list[Recording], list[Any]]:
    """(model, tests, parameter ranges) of validate / calibrate."""
    from dynval import model as mdl
    from dynval.validate.doe import parse_param

    check_writable(args.json_out, args.html_out, getattr(args, "model_out", None))
    m = mdl.load(args.model)
    recs = read_tests(args.experiments, args, besides=args.model)
    return m, recs, [parse_param(t) for t in args.param]


def write_study_reports(args: argparse.Namespace, res: Any, art: Any) -> None:
    """--json and --html of validate / calibrate."""
    from dynval.validate import report

    if args.json_out:
        report.write_json(res, args.json_out)
        log.info("wrote %s (JSON report)", args.json_out)
    if args.html_out:
        report.write_html(res, art, args.html_out)
        log.info("wrote %s (HTML report)", args.html_out)


def runner_for(args: argparse.Namespace) -> Any:
    """The sweep runner of validate / calibrate (--workers, --scheduler)."""
    from dynval.validate.doe import Runner

    return Runner(workers=args.workers, scheduler=args.scheduler)


@contextmanager
def stop_signals() -> Iterator[threading.Event]:
    """SIGINT and SIGTERM ask the work inside to stop: the first sets the event it yields,
    which the loops check between frames (bus.replay's hold, the receive loops, the waits
    after a replay), so the `finally` blocks that finish an MCAP log run on either. No
    exception lands inside a library's critical section (a KeyboardInterrupt raised in the
    middle of python-can's send could leave its bus lock held, and the shutdown then waits
    forever). A second signal raises KeyboardInterrupt at once, for a user who insists."""
    requested = threading.Event()

    def _ask(signum: int, frame: Any) -> None:
        if requested.is_set():
            raise KeyboardInterrupt
        requested.set()
        log.info("%s: stopping at the next safe point", signal.Signals(signum).name)

    main = threading.current_thread() is threading.main_thread()  # only there (cli.main in
    # a thread, as a test or an embedding application runs it, keeps the process's handlers)
    old = {sig: signal.signal(sig, _ask) for sig in (signal.SIGINT, signal.SIGTERM)
           if main and signal.getsignal(sig) is not signal.SIG_IGN}  # background: ignored
    try:
        yield requested
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def stop_point(stop: threading.Event) -> None:
    """Where a requested stop (stop_signals) ends the work: between frames or batches, never
    inside a bus call."""
    if stop.is_set():
        raise KeyboardInterrupt


def fmt_timing(t: dict[str, float]) -> str:
    return (f"{int(t['frames'])} frames timed: send-time error mean {t['mean_us']:.1f} us, "
            f"p95 {t['p95_us']:.0f} us, max {t['max_us']:.0f} us, drift "
            f"{t['drift_us_per_s']:+.2f} us/s ({t['drift_us_over_run']:+.1f} us over "
            f"{t['duration_s']:.1f} s)")
