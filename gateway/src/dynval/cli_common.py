"""Shared pieces of the sub-commands: the progress bar (tqdm, only on a terminal and without
--quiet), test-reading options."""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dynval.io import Recording, load_channel_map, read_test


def progress(total: int, desc: str, args: argparse.Namespace) -> tuple[
        Callable[[int], None] | None, Callable[[], None]]:
    """(on_progress, close) for a tqdm bar on stderr, or (None, no-op) when stderr is not a
    TTY or --quiet was given."""
    if getattr(args, "quiet", False) or not sys.stderr.isatty():
        return None, lambda: None
    import importlib

    bar: Any = importlib.import_module("tqdm").tqdm(total=total, desc=desc, unit="fr",
                                                    unit_scale=True, leave=False)
    return bar.update, bar.close


def add_test_options(p: Any) -> None:
    p.add_argument("--fs", type=float, default=None, metavar="HZ",
                   help="sampling rate of whitespace text tests (no time column)")
    p.add_argument("--channel-map", type=Path, default=None, metavar="FILE",
                   help="JSON/YAML channel map: column, name, unit, scale, role, dof")
    p.add_argument("--lenient", action="store_true",
                   help="turn recoverable file problems into counted warnings")


def read_with_options(path: Path, args: argparse.Namespace) -> Recording:
    cmap = load_channel_map(args.channel_map) if args.channel_map else None
    return read_test(path, lenient=args.lenient, fs_hz=args.fs, channel_map=cmap)


def fmt_timing(t: dict[str, float]) -> str:
    return (f"{int(t['frames'])} frames timed: send-time error mean {t['mean_us']:.1f} us, "
            f"p95 {t['p95_us']:.0f} us, max {t['max_us']:.0f} us, drift "
            f"{t['drift_us_per_s']:+.2f} us/s ({t['drift_us_over_run']:+.1f} us over "
            f"{t['duration_s']:.1f} s)")
