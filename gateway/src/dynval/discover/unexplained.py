"""What is left when nothing in the library explains a significant residual: where it sits
in frequency and among the channels, how it grows with the excitation level, and whether it
is linearly related to the input. A user reads what the model lacks from these traits
instead of a confident wrong label.

* band: the frequencies holding the middle 80 % of the residual's energy, its peak, and the
  nearest mode of the model;
* location: the channel whose residual stands furthest above its noise floor;
* level dependence: the slope b of log(residual RMS) against log(input RMS) over the tests:
  b ~ 1 scales with the input (a linear error), b > 1.3 grows faster (stiffening, impacts),
  b < 0.7 slower (friction-like, saturating); needs inputs at levels 20 % apart;
* linearity: the residual's coherence with the input, weighted by the residual's spectrum:
  near 1, a linear error (a missing resonance, a wrong stiffness or damping); near 0, a
  nonlinear one or an unmeasured input.
"""
from __future__ import annotations

import importlib
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dynval.discover.residual import TestData, summed_spectrum

signal: Any = importlib.import_module("scipy.signal")


def band(res: Sequence[np.ndarray], fs_hz: float, modes_hz: Sequence[float]
         ) -> dict[str, Any]:
    f, p_sum = summed_spectrum(res, fs_hz)
    if p_sum is None or not p_sum.sum() > 0:
        return {}
    c = np.cumsum(p_sum) / p_sum.sum()
    i_lo = int(np.searchsorted(c, 0.1))
    i_hi = min(int(np.searchsorted(c, 0.9)), f.size - 1)
    lo, hi = float(f[i_lo]), float(f[i_hi])
    peak = float(f[int(np.argmax(p_sum))])
    out: dict[str, Any] = {"band_hz": [lo, hi], "peak_hz": peak}
    flex = [(i + 1, fm) for i, fm in enumerate(modes_hz) if fm > 1.0]
    if flex:
        k, fm = min(flex, key=lambda m: abs(m[1] - peak))
        out["nearest_mode"] = {"mode": k, "f_hz": fm, "peak_over_mode": peak / fm}
    return out


def level_slope(tests: Sequence[TestData], res: Mapping[str, Mapping[str, np.ndarray]],
                chans: Sequence[str]) -> float | None:
    """Slope of log(residual RMS) on log(input RMS) over the records (None without levels
    20 % apart)."""
    pts = []
    seen = set()
    for t in tests:
        if id(t.u) in seen or t.name not in res:
            continue
        seen.add(id(t.u))
        u = float(np.std(t.u))
        rr = float(np.sqrt(np.mean([np.mean(res[t.name][c] ** 2) for c in chans])))
        if u > 0 and rr > 0:
            pts.append((math.log(u), math.log(rr)))
    if len(pts) < 2 or max(p[0] for p in pts) - min(p[0] for p in pts) < math.log(1.2):
        return None
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def coherence(tests: Sequence[TestData], res: Mapping[str, Mapping[str, np.ndarray]],
              chans: Sequence[str]) -> float | None:
    """The residual's coherence with the input, weighted by the residual's PSD."""
    num = den = 0.0
    for t in tests:
        if t.name not in res:
            continue
        for c in chans:
            r = res[t.name][c]
            n = min(1024, r.size // 4)
            if n < 64:
                continue
            with np.errstate(invalid="ignore", divide="ignore"):
                f, coh = signal.coherence(t.u, r, fs=t.fs_hz, nperseg=n)
            _, p = signal.welch(r, fs=t.fs_hz, nperseg=n)
            # no coherence where the input or the residual has no power (a constant input)
            num += float(np.sum(np.nan_to_num(coh, nan=0.0, posinf=0.0) * p))
            den += float(np.sum(p))
    return num / den if den > 0 else None


def characterise(tests: Sequence[TestData], res: Mapping[str, Mapping[str, np.ndarray]],
                 chans: Sequence[str], noise: Mapping[str, float], modes_hz: Sequence[float]
                 ) -> dict[str, Any]:
    """The traits of the residual left (see the module comment), and one sentence."""
    if not res or not chans:
        return {}
    fs = tests[0].fs_hz
    ratio = {c: float(np.sqrt(np.mean(np.concatenate([r[c] for r in res.values()]) ** 2)))
             / noise[c] if noise.get(c, 0) > 0 else math.inf for c in chans}
    where = max(chans, key=lambda c: ratio[c])
    out: dict[str, Any] = {"channel": where, "rmse_over_noise": ratio[where],
                           **band([r[where] for r in res.values()], fs, modes_hz)}
    slope = level_slope(tests, res, chans)
    coh = coherence(tests, res, chans)
    out["level_slope"] = slope
    out["input_coherence"] = coh
    words = [f"largest on {where} ({ratio[where]:.3g} x its noise floor)"]
    if "band_hz" in out:
        lo, hi = out["band_hz"]
        words.append(f"80 % of its energy in {lo:.3g}-{hi:.3g} Hz, peak at "
                     f"{out['peak_hz']:.3g} Hz")
        nm = out.get("nearest_mode")
        if nm and abs(nm["peak_over_mode"] - 1) < 0.06:
            words.append(f"at mode {nm['mode']} ({nm['f_hz']:.3g} Hz)")
    if slope is not None:
        kind = ("scales with the input: a linear error" if 0.7 <= slope <= 1.3 else
                "grows faster than the input: stiffening or impacts" if slope > 1.3 else
                "grows slower than the input: friction-like or saturating")
        words.append(f"level slope {slope:.2f} ({kind})")
    if coh is not None:
        words.append(f"coherence with the input {coh:.2f} ("
                     + ("linearly related: a missing resonance or a wrong linear parameter"
                        if coh > 0.6 else "not linearly related: a nonlinearity or an "
                        "unmeasured input") + ")")
    out["summary"] = "; ".join(words)
    return out
