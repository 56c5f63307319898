"""Shared conventions of the reports' matplotlib figures: one colour meaning across reports
(best / pass green, worst / fail red), SI prefixes instead of long tick labels, tick labels
that never overlap, and long records drawn as a min/max envelope with the decimation stated."""
from __future__ import annotations

import importlib
import math
from typing import Any

import numpy as np

# Colours by role. Red marks what is worse (the worst runs, the error before a fix), green
# what is better (the best runs, an accepted effect); measured data is black, neutral grey.
BEST = "tab:green"
WORST = "tab:red"
MEASURED = "black"
NEUTRAL = "tab:gray"
BEFORE = "tab:red"  # the declared model's error
AFTER = "tab:blue"  # the updated model's error: better, but not a verdict
MODEL = "tab:purple"  # the model under test (neither a best nor a worst run)

# records longer than this many samples are drawn as a min/max envelope (a PNG cannot show
# more points than it has pixel columns; the envelope keeps every peak)
MAX_POINTS = 4000

_PREFIXES = ((1e-9, "n"), (1e-6, "\u00b5"), (1e-3, "m"), (1.0, ""), (1e3, "k"), (1e6, "M"))


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (no display), or ImportError."""
    mpl = importlib.import_module("matplotlib")
    mpl.use("Agg")
    return importlib.import_module("matplotlib.pyplot")


def si_scale(values: np.ndarray, unit: str) -> tuple[float, str]:
    """(factor, unit) that puts the values' largest magnitude in [1, 1000): metres of 1e-4
    become 100 µm; ticks then read '100' instead of '0.00010'. Only plain SI units (m, N)
    take a prefix; anything else keeps factor 1."""
    if unit not in ("m", "N"):
        return 1.0, unit
    big = float(np.nanmax(np.abs(values))) if np.size(values) else 0.0
    if not (big > 0 and math.isfinite(big)):
        return 1.0, unit
    for scale, prefix in reversed(_PREFIXES):
        if big >= scale:
            return 1.0 / scale, prefix + unit
    return 1.0 / _PREFIXES[0][0], _PREFIXES[0][1] + unit


def envelope(y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray, int]:
    """(sample index, value, samples per bin) to draw y with at most ~max_points points: the
    minimum and maximum of each bin in time order (so every peak stays visible); bin 1 when
    y is short enough to draw as it is."""
    y = np.asarray(y)
    n = y.size
    if n <= max_points:
        return np.arange(n), y, 1
    per = math.ceil(2 * n / max_points)
    m = math.ceil(n / per)
    # pad the last bin with its own last sample: it neither adds a peak nor moves one
    blocks = np.concatenate([y, np.full(m * per - n, y[-1])]).reshape(m, per)
    lo, hi = np.argmin(blocks, axis=1), np.argmax(blocks, axis=1)
    base = np.arange(m) * per
    idx = np.empty(2 * m, dtype=np.int64)
    idx[0::2], idx[1::2] = base + np.minimum(lo, hi), base + np.maximum(lo, hi)
    idx = np.minimum(idx, n - 1)
    return idx, y[idx], per


def _overlaps(boxes: list[Any]) -> bool:
    return any(a.overlaps(b) for a, b in zip(boxes, boxes[1:], strict=False))


def visible_tick_boxes(fig: Any, ax: Any, which: str) -> list[Any]:
    """Window extents of an axis's non-empty tick labels that lie within the axis, in order."""
    renderer = fig.canvas.get_renderer()
    axis = ax.xaxis if which == "x" else ax.yaxis
    lo, hi = sorted(ax.get_xlim() if which == "x" else ax.get_ylim())
    boxes = []
    for tick in axis.get_major_ticks():
        lab = tick.label1
        if lab.get_visible() and lab.get_text() and lo <= tick.get_loc() <= hi:
            boxes.append(lab.get_window_extent(renderer))
    return boxes


def overlapping_ticks(fig: Any) -> list[str]:
    """'axes i: x' for every axis of fig whose tick labels overlap (nothing: none do)."""
    fig.canvas.draw()
    bad = []
    for i, ax in enumerate(fig.axes):
        for which in ("x", "y"):
            if _overlaps(visible_tick_boxes(fig, ax, which)):
                bad.append(f"axes {i}: {which}")
    return bad


def untangle_ticks(fig: Any, max_bins: int = 6) -> None:
    """Thin the tick labels of every axis of fig until neighbours do not overlap (fewer bins
    with MaxNLocator, then labels rotated 30 degrees), checked on the rendered figure."""
    ticker = importlib.import_module("matplotlib.ticker")
    fig.canvas.draw()
    for ax in fig.axes:
        for which in ("x", "y"):
            axis = ax.xaxis if which == "x" else ax.yaxis
            if axis.get_scale() != "linear" or not _overlaps(visible_tick_boxes(fig, ax, which)):
                continue
            for bins in range(max_bins, 1, -1):
                axis.set_major_locator(ticker.MaxNLocator(nbins=bins, steps=[1, 2, 2.5, 5, 10]))
                fig.canvas.draw()
                if not _overlaps(visible_tick_boxes(fig, ax, which)):
                    break
            else:
                if which == "x":
                    for lab in ax.get_xticklabels():
                        lab.set_rotation(30)
                        lab.set_horizontalalignment("right")
                    fig.canvas.draw()
