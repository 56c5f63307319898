"""The noise floor of each channel: the residual level a right model would leave.

It is taken from what the data offers, best evidence first, and the method is reported:

1. ``stated``: the user's noise RMS per channel (channel units);
2. ``repeats``: tests driven by the same input (a repeated run): whatever the structure does,
   it does twice, so half the variance of the difference of the two outputs is noise;
3. ``periods``: a periodic input in steady state: half the variance of the difference of
   the output one period apart (the first period, the start-up transient, left out);
4. ``input off``: stretches where the input is off (pre-trigger, run-out) once the response
   has died away: the output there is noise (hum and offset included);
5. ``cross-channel``: with three sensors or more, the residual's part coherent with the input
   (a linear parameter error) is removed, and at each frequency the rest is split into what
   the channels share (a missing force, whatever its law, drives every sensor through the
   structure: a few sources) and what each channel has alone (sensor and DAQ noise, which is
   independent per channel): a factor analysis of the residual's cross-spectral matrix, the
   method of the three-channel self-noise test of seismometers generalised to p channels.
   It holds in band and out of it, for any noise colour, anti-alias filter or effect that
   spreads energy outside the input band (friction's jumps, an appendage's resonance), where
   the out-of-band view counts that energy as noise. Noise shared by the channels (a common
   ground loop) is counted as structure: the floor then reads low and the held-out guard
   rejects what noise cannot explain;
6. ``out of band``: the declared model's residual outside the input band (where its
   prediction errors are small, but not beside one of its modes: the input's skirt drives
   it there) is noise; across the band its PSD is interpolated as a power
   law between the two sides, so 1/f noise counts at its in-band level; where the upper side
   may be rolled off by an anti-alias filter, the level below the band is used flat. On a
   grid of 27 cases (white, 1/f and both; no filter, 2nd- and 8th-order anti-alias at 0.4 fs;
   input bands 20-200, 21-241 and 10-100 Hz at 640 Hz) it reads 0.83-1.47 x the true RMS,
   where the top band alone read 0.00-1.01 x; ``top band`` (0.45-0.5 fs, white-equivalent)
   when there is no room below the input band.
"""
from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

log = logging.getLogger(__name__)
signal: Any = importlib.import_module("scipy.signal")
next_fast_len: Any = importlib.import_module("scipy.fft").next_fast_len
_ndimage: Any = importlib.import_module("scipy.ndimage")

REPEAT_CORR = 0.999  # inputs this correlated (and of equal RMS within 1 %) are repeats
PERIOD_CORR = 0.995  # a lag whose input autocorrelation reaches this is a period
QUIET_FRACTION = 0.02  # input off: windowed input RMS below this share of the record's RMS
QUIET_MIN_S = 0.25  # input-off stretches shorter than this (after settling) are not used
TOP_BAND = (0.45, 0.5)  # fraction of fs
AA_CORNER = 0.4  # fraction of fs above which a DAQ's anti-alias filter may cut the noise


class Test(Protocol):
    name: str
    fs_hz: float
    u: np.ndarray
    y: dict[str, np.ndarray]


@dataclass
class Floor:
    """Noise RMS of one channel (channel units), how it was found, and a caveat if any."""

    rms: float
    method: str
    detail: str = ""


def estimate(tests: Sequence[Test], chans: Sequence[str],
             residuals: Mapping[str, Mapping[str, np.ndarray]],
             band_hz: tuple[float, float], settle_s: float,
             stated: Mapping[str, float] | None = None,
             respond: Respond | None = None, modes_hz: Sequence[float] = ()
             ) -> dict[str, Floor]:
    """The noise floor of every channel (see the module comment for the order).
    ``residuals``: the declared model's residual records (one per test, for method 5);
    ``settle_s``: how long the structure rings after the input stops (method 4);
    ``respond``: the model's response to an added input (input_noise_response);
    ``modes_hz``: the model's modes (method 6 reads the noise beside them)."""
    out: dict[str, Floor] = {}
    by_input: Mapping[str, np.ndarray] | None = None  # the spectral view's, beside modes
    # the input of each residual record, by record (the residuals are keyed by record)
    by_record = {str(id(t.u)): t.u for t in tests}
    keys = list(residuals)
    inputs = [by_record.get(k, tests[0].u) for k in keys]
    shared = cross_channel([residuals[k] for k in keys], inputs, chans, tests[0].fs_hz)
    if shared is not None:  # the input sensor's noise reaches every channel through the model
        by_test = {str(id(t.u)): t for t in tests}
        via_input = input_noise_response([by_test[k] for k in keys if k in by_test],
                                         [residuals[k] for k in keys if k in by_test],
                                         list(shared), respond)
        shared = {c: v + via_input.get(c, 0.0) for c, v in shared.items()}
    for c in chans:
        if stated and c in stated:
            out[c] = Floor(float(stated[c]), "stated", "given by the user")
            continue
        mine = [k for k in keys if c in residuals[k]]
        floor = (from_repeats(tests, c) or from_periods(tests, c)
                 or from_input_off(tests, c, settle_s)
                 or _cross_floor(shared, c, [residuals[k][c] for k in mine],
                                 [by_record.get(k, tests[0].u) for k in mine], tests[0].fs_hz))
        if floor is None:
            if by_input is None and modes_hz:
                by_input = input_noise_records(tests, respond) or {}
            floor = spectral([residuals[k][c] for k in mine], tests[0].fs_hz, band_hz,
                             [by_record.get(k, tests[0].u) for k in mine], modes_hz,
                             (by_input or {}).get(c))
        out[c] = floor
        log.info("noise floor of %s: %.4g (%s%s)", c, floor.rms, floor.method,
                 f"; {floor.detail}" if floor.detail else "")
    return out


def _cross_floor(shared: Mapping[str, float] | None, c: str, res: Sequence[np.ndarray],
                 inputs: Sequence[np.ndarray], fs_hz: float) -> Floor | None:
    """Method 5's floor of one channel, with the mains hum (shared by the channels, so counted
    as structure by the factor model) added back."""
    if shared is None or c not in shared:
        return None
    hum, lines = mains_hum(res, inputs, fs_hz)
    with_hum = f"; plus mains hum at {', '.join(f'{x:g}' for x in lines)} Hz" if lines else ""
    return Floor(math.sqrt(shared[c] + hum), "cross-channel",
                 "the residual's part no other channel shares and the input does not explain "
                 "(noise is independent per sensor, a missing effect drives them all)" + with_hum)


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b) / den) if den > 0 else 0.0


def from_repeats(tests: Sequence[Test], c: str) -> Floor | None:
    """Half the variance of output differences between tests with the same input."""
    halves = []
    pairs = 0
    for i, a in enumerate(tests):
        for b in tests[i + 1:]:
            if a.u.size != b.u.size or c not in a.y or c not in b.y or a.u.size < 64:
                continue
            sa, sb = float(np.std(a.u)), float(np.std(b.u))
            if sa <= 0 or abs(sa - sb) > 0.01 * sa or _corr(a.u, b.u) < REPEAT_CORR:
                continue
            d = a.y[c] - b.y[c]
            halves.append(float(np.var(d)) / 2.0)
            pairs += 1
    if not halves:
        return None
    return Floor(math.sqrt(float(np.mean(halves))), "repeats",
                 f"{pairs} pair(s) of tests with the same input")


def period_of(u: np.ndarray) -> int | None:
    """The input's period in samples, when it repeats at least 3 times (else None)."""
    n = u.size
    if n < 96:
        return None
    x = u - u.mean()
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: n // 3 + 1]
    if ac[0] <= 0:
        return None
    ac = ac / ac[0] * n / (n - np.arange(ac.size))  # unbiased: a repeat reaches 1
    lags = np.flatnonzero(ac[16:] >= PERIOD_CORR)
    return int(lags[0] + 16) if lags.size else None


def from_periods(tests: Sequence[Test], c: str) -> Floor | None:
    """Half the variance of the output's period-to-period difference in steady state."""
    halves = []
    for t in tests:
        p = period_of(t.u)
        if p is None or c not in t.y:
            continue
        y = t.y[c][p:]  # the first period carries the start-up transient
        if y.size < 2 * p:
            continue
        halves.append(float(np.var(y[p:] - y[:-p])) / 2.0)
    if not halves:
        return None
    return Floor(math.sqrt(float(np.mean(halves))), "periods",
                 f"periodic input in {len(halves)} test(s)")


def quiet_mask(u: np.ndarray, fs_hz: float, settle_s: float) -> np.ndarray:
    """Samples where the input has been off for at least ``settle_s`` (and stays off)."""
    w = max(8, int(0.02 * fs_hz))
    ref = float(np.sqrt(np.mean(u * u)))
    if ref <= 0:
        return np.zeros(u.size, dtype=bool)
    ms = np.convolve(u * u, np.ones(w) / w, mode="same")
    off = ms < (QUIET_FRACTION * ref) ** 2
    settle = int(settle_s * fs_hz) + w
    out = np.zeros(u.size, dtype=bool)
    # a stretch counts from settle samples after the input stopped to where it restarts
    edges = np.flatnonzero(np.diff(np.concatenate(([0], off.astype(np.int8), [0]))))
    for start, stop in zip(edges[0::2], edges[1::2], strict=True):
        first = start + (settle if start > 0 else w)  # a pre-trigger stretch needs no settling
        last = stop - w
        if last - first >= QUIET_MIN_S * fs_hz:
            out[first:last] = True
    return out


def from_input_off(tests: Sequence[Test], c: str, settle_s: float) -> Floor | None:
    """The output's RMS (about its mean: an offset is not noise) where the input is off."""
    parts = []
    for t in tests:
        if c not in t.y:
            continue
        q = quiet_mask(t.u, t.fs_hz, settle_s)
        if q.any():
            parts.append(t.y[c][q] - float(np.mean(t.y[c][q])))
    if not parts:
        return None
    v = np.concatenate(parts)
    return Floor(float(np.sqrt(np.mean(v * v))), "input off",
                 f"{v.size} samples where the input is off and the response has died away")


CROSS_MIN_CHANNELS = 3  # a shared source and each channel's own noise are told apart from 3
CROSS_SEG = 2048  # at most this many samples per spectral segment (half-overlapping, Hann):
# long ones keep the slow part of 1/f noise (a third of it lies below 1.25 Hz in an 8192-sample
# record at 640 Hz), 8 segments a record at least keep the estimate's scatter down


def _segment_spectra(x: np.ndarray, seg: int) -> np.ndarray:
    """Hann-windowed FFTs of half-overlapping segments of the rows of ``x`` (channels x
    samples): (channels, segments, frequencies), scaled so that the mean of |X|^2 summed over
    the one-sided frequencies is each row's variance."""
    w = np.hanning(seg)
    frames = np.lib.stride_tricks.sliding_window_view(x, seg, axis=1)[:, ::seg // 2, :]
    frames = frames - frames.mean(axis=2, keepdims=True)
    spec = np.fft.rfft(frames * w, axis=2) * math.sqrt(2.0 / float(np.sum(w * w)) / seg)
    spec[:, :, 0] /= math.sqrt(2.0)
    return spec


def _unique_power(s: np.ndarray, q: int, iters: int = 60) -> np.ndarray:
    """Each channel's own power at each frequency: the diagonal D with S - D of rank q and
    positive semi-definite (principal-axis factor analysis of Hermitian matrices; S is
    frequencies x channels x channels). D stays within [0, diag S]. It starts from each
    channel's part the others cannot predict (1 / (S^-1)_ii, an upper bound of its own
    power), so a channel with no shared part keeps all its power."""
    diag = np.real(np.einsum("fii->fi", s))
    inv = np.linalg.pinv(s, hermitian=True)
    d = np.clip(1.0 / np.maximum(np.real(np.einsum("fii->fi", inv)), 1e-300), 0.0, diag)
    for _ in range(iters):
        a = s - d[:, :, None] * np.eye(s.shape[1])[None]
        val, vec = np.linalg.eigh(a)
        val = np.clip(val[:, -q:], 0.0, None)
        shared = np.einsum("fiq,fq,fiq->fi", vec[:, :, -q:], val, np.conj(vec[:, :, -q:])).real
        d = np.clip(diag - shared, 0.0, diag)
    return np.asarray(d, dtype=float)


def shared_sources(p: int) -> int:
    """How many shared sources a factor model of p channels can hold and still tell each
    channel's own noise apart ((p - q)^2 >= p + q): 1 for 3-4 channels, 2 for 5-6."""
    q = 1
    while (p - q - 1) ** 2 >= p + q + 1:
        q += 1
    return q


def cross_channel(res: Sequence[Mapping[str, np.ndarray]], inputs: Sequence[np.ndarray],
                  chans: Sequence[str], fs_hz: float) -> dict[str, float] | None:
    """Noise variance of each channel from the part of the residuals no other channel shares
    and the input does not explain (the module comment, method 5); None with fewer than
    CROSS_MIN_CHANNELS channels or records too short for 8 segments."""
    use = [c for c in chans if all(c in r for r in res)]
    if len(use) < CROSS_MIN_CHANNELS or not res:
        return None
    n = min(min(r[c].size for c in use) for r in res)
    seg = min(CROSS_SEG, 1 << int(math.log2(max(n // 8, 2))))
    if seg < 64:
        return None
    acc = None
    for r, u in zip(res, inputs, strict=True):
        x = np.vstack([np.asarray(r[c][:n], dtype=float) for c in use]
                      + [np.asarray(u[:n], dtype=float)])
        spec = _segment_spectra(x, seg)
        part = np.einsum("isf,jsf->fij", spec, np.conj(spec))
        acc = part if acc is None else acc + part
    assert acc is not None
    p = len(use)
    s_rr, s_ru, s_uu = acc[:, :p, :p], acc[:, :p, p], np.real(acc[:, p, p])
    keep = s_uu > 1e-12 * max(float(np.max(s_uu)), 1e-300)
    cond = s_rr.copy()
    cond[keep] -= (s_ru[keep, :, None] * np.conj(s_ru[keep, None, :])) / s_uu[keep, None, None]
    segs = len(res) * ((n - seg) // (seg // 2) + 1)
    own = _unique_power(cond[1:] / segs, shared_sources(p))  # the mean (offset) bin left out
    return {c: float(np.sum(own[:, i])) for i, c in enumerate(use)}


INPUT_QUIET = 1e-2  # the input's quietest band must lie this far below its loudest to be noise


Respond = Callable[[Test, np.ndarray], Mapping[str, np.ndarray] | None]


def input_noise_psd(tests: Sequence[Test], seg: int = 512) -> float | None:
    """The input sensor's own noise as a white one-sided PSD (input units^2 / Hz): the level of
    the input's quietest band (smoothed Welch PSD minimum), where the excitation is off; None
    when records are shorter than 4 segments or the input has no band INPUT_QUIET below its
    loudest (full-band excitation: its noise cannot be told apart). Its variance per sample
    is the level x fs / 2."""
    if not tests or min(t.u.size for t in tests) < 4 * seg:
        return None
    fs = tests[0].fs_hz
    s_uu = np.mean([signal.welch(t.u, fs=fs, nperseg=seg)[1] for t in tests], axis=0)[1:]
    smooth = np.array([np.median(s_uu[max(0, i - 4):i + 5]) for i in range(s_uu.size)])
    level = float(np.min(smooth))
    return level if level < INPUT_QUIET * float(np.max(smooth)) else None


def input_noise_response(tests: Sequence[Test], res: Sequence[Mapping[str, np.ndarray]],
                         chans: Sequence[str], respond: Respond | None = None
                         ) -> dict[str, float]:
    """Variance each channel gets from the input sensor's own noise (the true model driven by
    the measured input leaves it; a factor model counts it as structure: it reaches every
    channel). The input noise is white at input_noise_psd's level; it reaches a channel
    through the model: ``respond(test, e)``, the change of the model's prediction when white
    noise e of that level is added to the test's input as its simulations take it (every mode
    resolved, a lightly damped or nearly rigid one included, the elements acting as in the
    test; in observer mode the change of the one-step errors), else the prediction's PSD over
    the input's. Nothing when the input's noise cannot be told apart."""
    seg = 512
    level = input_noise_psd(tests, seg)
    if level is None:
        return {}
    fs = tests[0].fs_hz
    d = input_noise_records(tests, respond, level)
    if d is not None:
        return {c: float(np.mean(np.square(d[c]))) for c in chans if c in d}
    s_uu = np.mean([signal.welch(t.u, fs=fs, nperseg=seg)[1] for t in tests], axis=0)[1:]
    out: dict[str, float] = {}
    df = fs / seg
    for c in chans:
        pred = [t.y[c] - r[c] for t, r in zip(tests, res, strict=True) if c in r and c in t.y]
        if len(pred) != len(tests):
            continue
        s_pp = np.mean([signal.welch(p, fs=fs, nperseg=seg)[1] for p in pred], axis=0)[1:]
        out[c] = float(np.sum(s_pp / np.maximum(s_uu, 1e-300)) * level * df)
    return out


def input_noise_records(tests: Sequence[Test], respond: Respond | None,
                        level: float | None = None) -> Mapping[str, np.ndarray] | None:
    """The model's response, per channel, to the input sensor's own noise (white at
    input_noise_psd's level, or ``level``) added to the first test's input: ``respond``'s
    records; None when the input's noise cannot be told apart or there is no ``respond``."""
    if respond is None or not tests:
        return None
    level = input_noise_psd(tests) if level is None else level
    if level is None:
        return None
    e = (np.random.default_rng(0).standard_normal(tests[0].u.size)
         * math.sqrt(level * tests[0].fs_hz / 2))
    return respond(tests[0], e)


SUB_BAND_SNR = 2.0  # under its band, an input within this x the noise's level is more noise
SUB_BAND_MEAN = 3.0  # ... and its mean is the sensor's when within this x the noise's RMS there
SUB_BAND_KINDS = ("force", "ground_acc")  # a prescribed displacement's slow part is real motion


@dataclass(frozen=True)
class SubBandCut:
    """Where a band-limited input's sensor noise under its band is cut (sub_band_cut): all
    of it up to ``corner_hz``, none above ``corner_hz + ramp_hz`` (a linear ramp between,
    one bin of the spectrum the corner was read on)."""

    corner_hz: float
    ramp_hz: float


def sub_band_cut(u: np.ndarray, fs_hz: float) -> SubBandCut | None:
    """Where a band-limited input is its sensor's noise under its band (the band holding
    98 % of its power). Read per frequency at the input's loudest moment (the highest of
    its Hann segments' spectra: a sweep's start skirts frequencies under its band for one
    segment, a steady input is as loud in all), smoothed over 5 bins: the noise's level is
    the lowest that has reached from DC up (a 1/f sensor's falls towards the band, a white
    one's is flat; where the force rises out of it, the noise stays at its last level), and
    the corner the highest frequency under the band within SUB_BAND_SNR of it (more noise
    than force). Blind sweeps cut from a run, their band starting above the lowest modes:
    the true model driven by the cleaned input left 56-92 x its output noise with the
    former 4th-order high-pass capped an octave under the band, 0.08-0.98 x with this;
    band-limited random inputs within -10 %/+18 % of it. None when the input is not
    band-limited at its low end (real content down to DC, an impulse; its quietest level
    not INPUT_QUIET below its loudest) or the record is too short to tell."""
    if u.size < 1024:
        return None
    seg = min(u.size, max(1024, u.size // 8))
    f, _, sg = signal.spectrogram(u, fs=fs_hz, window="hann", nperseg=seg, noverlap=seg // 2)
    p = sg.mean(axis=1)  # Welch's PSD
    if not p.sum() > 0:  # a constant input (a static load): no band
        return None
    c = np.cumsum(p) / p.sum()
    below = (f > 0) & (f < float(f[np.searchsorted(c, 0.01)]))
    if np.count_nonzero(below) < 3:
        return None
    smooth = _median5(p)
    if not float(np.min(smooth[below])) < INPUT_QUIET * float(np.max(smooth)):
        return None
    loudest = _median5(sg.max(axis=1))
    level = np.minimum.accumulate(np.where(f > 0, loudest, np.inf))
    noisy = np.flatnonzero(below & (loudest <= SUB_BAND_SNR * level))
    return SubBandCut(float(f[noisy.max()]), float(f[1] - f[0]))


def sub_band_corner(u: np.ndarray, fs_hz: float) -> float | None:
    """The frequency under which a band-limited input is its sensor's noise, taken out
    (sub_band_cut); None where it has none."""
    cut = sub_band_cut(u, fs_hz)
    return None if cut is None else cut.corner_hz


def _median5(p: np.ndarray) -> np.ndarray:
    """The running median of p over 5 bins (fewer at either end, as far as p goes)."""
    out = np.empty_like(p)
    out[2:-2] = np.median(np.lib.stride_tricks.sliding_window_view(p, 5), axis=1)
    for i in (0, 1, p.size - 2, p.size - 1):
        out[i] = np.median(p[max(0, i - 2):i + 3])
    return out


EDGE_AR_ORDER = 32  # the model that carries a record's excitation on past its ends
EDGE_GROWTH = 4.0  # ... refused where its prediction outgrows the end it was fitted to


def _filtered(x: np.ndarray, fs_hz: float, cut: SubBandCut) -> np.ndarray:
    """x without its mean nor its content under cut: zero phase, in the frequency domain, the
    record carried on past either end for as long as the cut rings (1 / ramp_hz: one
    spectrum segment) by _carried_on. Zero-padded instead, a record cut from a running sweep
    starts with a jump, whose content under the band the sharp cut takes out too, and the
    input left drives the modes there for a second: the true model of blind sweep 402
    (cut from a run at 89-173 Hz) left twice its held-out error; carried on, 4 % under the
    former high-pass's an octave lower."""
    n = x.size
    e = min(n, int(round(fs_hz / cut.ramp_hz)))
    x = x - np.mean(x)
    ext = np.concatenate([_carried_on(x[::-1], e)[::-1], x, _carried_on(x, e)])
    nf = next_fast_len(2 * ext.size, real=True)
    h = np.clip((np.fft.rfftfreq(nf, 1.0 / fs_hz) - cut.corner_hz) / cut.ramp_hz, 0.0, 1.0)
    return np.asarray(np.fft.irfft(np.fft.rfft(ext, nf) * h, nf)[e:e + n])


def _carried_on(x: np.ndarray, e: int) -> np.ndarray:
    """e samples after x's end: the prediction of an EDGE_AR_ORDER autoregressive model
    (least squares over x's last 2 e samples), faded out to zero over its second half;
    zeros (the plain padding) where x ends silent or the prediction grows past EDGE_GROWTH
    x the end's largest value (an unstable model)."""
    p = EDGE_AR_ORDER
    w = x[-min(x.size, 2 * e):]
    scale = float(np.max(np.abs(w)))
    if w.size < 4 * p or not scale > 0:
        return np.zeros(e)
    rows = np.lib.stride_tricks.sliding_window_view(w / scale, p + 1)
    a, *_ = np.linalg.lstsq(rows[:, :p], rows[:, p], rcond=None)
    den = np.r_[1.0, -a[::-1]]  # y[k] = sum_j a[j] y[k - p + j]
    zi = signal.lfiltic([1.0], den, (w[::-1][:p] / scale))
    pred = signal.lfilter([1.0], den, np.zeros(e), zi=zi)[0]
    if not np.all(np.isfinite(pred)) or float(np.max(np.abs(pred))) > EDGE_GROWTH:
        return np.zeros(e)
    return np.asarray(pred * scale * signal.windows.tukey(2 * e, 0.5)[e:])


def without_sub_band_noise(u: np.ndarray, fs_hz: float) -> np.ndarray:
    """The input with its sensor's noise under the band taken out (sub_band_cut); u itself
    when there is none. The mean goes with it when it is no larger than SUB_BAND_MEAN x the
    RMS of what was taken out (a 1/f sensor's slow wander leaves a mean of that size; a real
    static force, larger, is kept). The measured input drives every prediction: on a weakly
    restrained structure (a position loop, a soft suspension) a cheap force sensor's 1/f
    noise under the band drives the low mode, and its mean deflects it, far more than
    anything in the band, and a wrong model that stiffens it wins."""
    cut = sub_band_cut(u, fs_hz)
    return u if cut is None else _kept(u, fs_hz, cut)


def _kept(u: np.ndarray, fs_hz: float, cut: SubBandCut) -> np.ndarray:
    """u above cut (without_sub_band_noise), its mean kept where it is a real static
    force."""
    mean = float(np.mean(u))
    kept = _filtered(u, fs_hz, cut)
    slow = float(np.std(u - mean - kept))
    return np.asarray(kept + (mean if abs(mean) > SUB_BAND_MEAN * slow else 0.0))


IDLE_SEG = 256  # samples per STFT segment (Hann, half-overlapping): 0.4 s at 640 Hz
IDLE_CONTRAST = 100.0  # a frequency whose input level over time spans this (98th over 20th
# percentile) is switched on and off (a sweep passes it, a hammer hits); a stationary input
# spans 2-3 x at every frequency, in its band and out of it
IDLE_FLOOR = 4.0  # a cell within this x its frequency's idle level is the sensor's noise


def idle_gain(u: np.ndarray, fs_hz: float) -> np.ndarray | None:
    """The gain over the input's STFT cells (IDLE_SEG) that takes out its sensor's noise where
    the excitation is idle: at each frequency the input switches on and off over time
    (IDLE_CONTRAST), the cells within IDLE_FLOOR of its idle level (the 20th percentile over
    time of the 3 x 3-cell smoothed power) go to 0, louder ones towards 1 (1 - IDLE_FLOOR x
    idle / power); 1 at the other frequencies and in the two frames at either end. None when
    no frequency switches (a random or harmonic input), the record is shorter than 8 segments
    or not finite. Between a sweep's passes, the
    measured input's noise drives every mode the simulations resolve for the whole record,
    the true structure's only as long as the sweep is near: the true model lost to a
    better-damped wrong one."""
    top = float(np.max(np.abs(u))) if u.size >= 8 * IDLE_SEG else 0.0
    if not (math.isfinite(top) and top > 0):  # short, empty, or a NaN the core counts
        return None
    _, _, z = signal.stft(u / top, fs=fs_hz, nperseg=IDLE_SEG)  # huge values: no overflow
    power = _ndimage.uniform_filter(np.abs(z) ** 2, size=3, mode="nearest")
    inner = power[:, 2:-2]  # the end frames hold the record's cut (every frequency jumps)
    idle = np.percentile(inner, 20, axis=1)
    on_off = np.percentile(inner, 98, axis=1) > IDLE_CONTRAST * np.maximum(idle, 1e-300)
    if not on_off.any():
        return None
    gain = np.clip(1.0 - IDLE_FLOOR * idle[:, None] / np.maximum(power, 1e-300), 0.0, 1.0)
    gain[~on_off] = 1.0
    gain[:, :2] = gain[:, -2:] = 1.0
    return np.asarray(gain)


def _gated(x: np.ndarray, fs_hz: float, gain: np.ndarray | None) -> np.ndarray:
    """x through an STFT gain (idle_gain; the same cells as its STFT); x when None."""
    if gain is None:
        return x
    _, _, z = signal.stft(x, fs=fs_hz, nperseg=IDLE_SEG)
    _, y = signal.istft(z * gain, fs=fs_hz, nperseg=IDLE_SEG)
    return np.asarray(y[:x.size])


def simulated_input(kind: str, u: np.ndarray, fs_hz: float) -> np.ndarray:
    """The measured input of kind ``kind`` (Model.input.kind) as discover's simulations take
    it: a force or table acceleration without_sub_band_noise and without its noise where the
    excitation is idle (idle_gain), a displacement as measured."""
    return _as_simulated(kind, u, fs_hz, ())[0]


def simulated_input_and_noise(kind: str, u: np.ndarray, e: np.ndarray, fs_hz: float
                              ) -> tuple[np.ndarray, np.ndarray]:
    """(simulated_input of u, a noise record e added to u as the simulations take it:
    without its part under u's band where u's is taken out, and through u's idle gain)."""
    x, (en,) = _as_simulated(kind, u, fs_hz, (e,))
    return x, en


def _as_simulated(kind: str, u: np.ndarray, fs_hz: float, noises: tuple[np.ndarray, ...]
                  ) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """u as the simulations take it and ``noises`` through the same filters (u's sub-band
    corner and idle gain, each found once)."""
    if kind not in SUB_BAND_KINDS:
        return u, noises
    u = without_mains(u, fs_hz)
    sub = sub_band_cut(u, fs_hz)
    if sub is not None:
        u, noises = _kept(u, fs_hz, sub), tuple(_filtered(e, fs_hz, sub) for e in noises)
    gain = idle_gain(u, fs_hz)
    return _gated(u, fs_hz, gain), tuple(_gated(e, fs_hz, gain) for e in noises)


def _level(f: np.ndarray, p: np.ndarray, lo: float, hi: float) -> float | None:
    sel = (f >= lo) & (f <= hi)
    return float(np.median(p[sel])) if np.count_nonzero(sel) >= 4 else None


# a model's mode outside the input band is still driven by the input's skirt, and with its
# quality factor a model error there is no small prediction error: the residual within this
# share of the mode's frequency is not read as noise (blind two-effect 432, a first mode at
# 13.6 Hz under a 20-240 Hz input, 2 sensors: the floor read 23-30 x the sensors' noise and
# discover answered "no effect" at 165 x the true model's held-out error)
MODE_SPAN = 0.2


def out_of_band_power(f: np.ndarray, p: np.ndarray, band_hz: tuple[float, float],
                      modes_hz: Sequence[float] = (), via_input: np.ndarray | None = None
                      ) -> float | None:
    """Noise power (variance) from the residual's PSD outside the input band: the measured
    PSD outside it, and inside it a power law between the levels just below and just above
    the band (so 1/f noise counts at the level it has inside the band). Above AA_CORNER x fs,
    or where the top band lies below half the level just above the input band, an anti-alias
    filter may roll the noise off: the level below the band is then taken flat across it.
    Near a mode outside the band (MODE_SPAN, ``modes_hz``: the model's) the level of that
    side stands in for the measured PSD, plus ``via_input`` there (the PSD of the model's
    response to the input sensor's noise, on f: the input drives the mode), and the levels
    are read beside such modes (below the band, down to 0 Hz if need be). None without 3
    bins below the band."""
    lo, hi = band_hz
    fs = 2.0 * float(f[-1])
    near = np.zeros(f.size, dtype=bool)
    for fm in modes_hz:
        near |= np.abs(f - fm) <= MODE_SPAN * fm
    beside = (f >= 0.5 * lo) & (f <= 0.8 * lo) & (f > 0)
    below = beside & ~near
    if np.count_nonzero(below) < 3 and np.any(beside & near):
        below = (f <= 0.8 * lo) & (f > 0) & ~near
    above = (f >= 1.25 * hi) & (f <= min(1.6 * hi, AA_CORNER * fs)) & ~near
    top = f >= TOP_BAND[0] * fs
    if np.count_nonzero(below) < 3:
        return None
    fb, lb = float(np.median(f[below])), float(np.median(p[below]))
    model = p.copy()
    la = float(np.median(p[above])) if np.count_nonzero(above) >= 3 else 0.0
    if la <= 0 or lb <= 0 or float(np.median(p[top])) < 0.5 * la:
        model[(f >= lo) & (f <= hi)] = lb
    else:
        fa = float(np.median(f[above]))
        inside = (f > fb) & (f < fa)
        model[inside] = lb * (f[inside] / fb) ** (math.log(la / lb) / math.log(fa / fb))
    out = near & ((f < lo) | (f > hi))
    model[out] = np.where(f[out] < lo, lb, la if la > 0 else lb)
    if via_input is not None:
        model[out] += via_input[out]
    return float(np.sum(model[1:]) * float(f[1] - f[0]))


MAINS_HZ = (50.0, 60.0)
LINE_RATIO = 10.0  # a mains line stands this far above the residual's local spectrum


def _mains_bins(f: np.ndarray) -> list[tuple[float, int, np.ndarray]]:
    """Each harmonic of MAINS_HZ (up to the 5th) a Welch grid f can judge: its frequency,
    its bin, and its neighbours' bins (12 either side, the line's own 5 left out)."""
    df = float(f[1] - f[0])
    out = []
    for f0 in MAINS_HZ:
        for h in range(1, 6):
            k = int(round(h * f0 / df))
            if k >= 12 and k + 12 < f.size:
                out.append((h * f0, k, np.r_[k - 12:k - 2, k + 3:k + 13]))
    return out


def mains_hum(res: Sequence[np.ndarray], inputs: Sequence[np.ndarray], fs_hz: float
              ) -> tuple[float, list[float]]:
    """Power (variance) of mains-hum lines in the residuals: narrow peaks at the harmonics of
    50 or 60 Hz that the input does not have (an electrical pick-up, not the structure's
    response), and their frequencies. A right model leaves them: they are noise."""
    power, lines = [], set()
    for r, u in zip(res, inputs, strict=True):
        f, p = signal.welch(r, fs=fs_hz, nperseg=min(1024, r.size))
        _, pu = signal.welch(u, fs=fs_hz, nperseg=min(1024, r.size))
        total = 0.0
        for line, k, side in _mains_bins(f):
            base, base_u = float(np.median(p[side])), float(np.median(pu[side]))
            if (p[k] > LINE_RATIO * base and pu[k] < 3 * base_u
                    and tone_contrast(r, fs_hz, line) >= TONE_CONTRAST):
                total += float(np.sum(p[k - 2:k + 3]) - 5 * base) * float(f[1] - f[0])
                lines.add(line)
        power.append(total)
    return (float(np.median(power)) if power else 0.0), sorted(lines)


MAINS_FIT_SPAN_HZ = 0.2  # a line's frequency is found within this of its harmonic's, on a
MAINS_FIT_STEPS_HZ = (0.01, 0.0005)  # grid, then a finer one around the best (a sine fitted
# over a 25 s record 0.001 Hz off leaves 1.5 % of it)


def without_mains(u: np.ndarray, fs_hz: float) -> np.ndarray:
    """The measured input without the mains-hum lines outside its excitation band (the band
    holding 98 % of its power): at a harmonic of 50 or 60 Hz there, a steady tone
    (tone_contrast) LINE_RATIO above its neighbours is the sensor's pick-up, not a force,
    and its sine (least squares, over the whole record) is taken out. Driven by it, the
    simulations shake every mode near the line that the structure never felt: blind sweep
    400 (a cheap DAQ's 50 Hz on the force sensor, a sweep cut from a run at 87-162 Hz) put
    an absorber tuned to 50.06 Hz at the driven DOF to cancel it. u when there is none or
    when u is not all finite. Worked on u over its largest magnitude: the spectra neither
    overflow nor underflow whatever the channel's units."""
    lines = input_mains_lines(u, fs_hz)
    if not lines:
        return u
    scale = float(np.max(np.abs(u)))
    out = u / scale
    for line in lines:
        out = out - _fitted_sine(out, fs_hz, line)
    return out * scale


def input_mains_lines(u: np.ndarray, fs_hz: float) -> list[float]:
    """The mains harmonics (Hz) without_mains takes out of u (none when u is short or not
    all finite)."""
    if u.size < 1024 or not np.all(np.isfinite(u)) or not np.any(u):
        return []
    u = u / float(np.max(np.abs(u)))  # no overflow or underflow whatever the units
    f, p = signal.welch(u, fs=fs_hz, nperseg=min(1024, u.size))
    if not p.sum() > 0:
        return []
    c = np.cumsum(p) / p.sum()
    f_lo, f_hi = float(f[np.searchsorted(c, 0.01)]), float(f[np.searchsorted(c, 0.99)])
    return [line for line, k, side in _mains_bins(f)
            if not f_lo <= line <= f_hi and p[k] > LINE_RATIO * float(np.median(p[side]))
            and tone_contrast(u, fs_hz, line) >= TONE_CONTRAST]


def _fitted_sine(u: np.ndarray, fs_hz: float, f0: float) -> np.ndarray:
    """The least-squares sine in u at the frequency within MAINS_FIT_SPAN_HZ of f0 that
    takes out the most of u's power."""
    t = np.arange(u.size) / fs_hz
    # weighted by a Hann window: the excitation's leakage onto a record-long sine is 1e-4 of
    # its level 40 Hz away, 2 % of a hum at 2 % of it
    w = np.sqrt(signal.windows.hann(u.size))
    centre, span, fit = f0, MAINS_FIT_SPAN_HZ, np.zeros_like(u)
    for step in MAINS_FIT_STEPS_HZ:
        best = -1.0
        for fr in centre + step * np.arange(-round(span / step), round(span / step) + 1):
            basis = np.column_stack([np.cos(2 * np.pi * fr * t), np.sin(2 * np.pi * fr * t)])
            coef, *_ = np.linalg.lstsq(basis * w[:, None], u * w, rcond=None)
            y = basis @ coef
            if float(y @ y) > best:
                best, fit, found = float(y @ y), y, float(fr)
        centre, span = found, step
    return fit


TONE_CONTRAST = 20.0  # a tone's peak over its neighbours at 0.1 Hz; random bins reach ~5
TONE_SPAN_HZ = 0.4  # the neighbourhood (either side) the contrast is taken over
TONE_SEG_S = 10.0  # segments of at most this long: 0.1 Hz bins hold a mains line that drifts


def tone_contrast(r: np.ndarray, fs_hz: float, f0: float) -> float:
    """The highest bin near f0 over the median of its neighbours (+-TONE_SPAN_HZ, the peak's
    own 3 bins left out), at a fine resolution (Hann segments of up to TONE_SEG_S): mains
    hum is a steady sine, all in those 3 bins, far above its neighbours; a resonance of the
    residual that sits at 50 or 60 Hz (a mode an effect moved, driven by a random input)
    spreads over its bandwidth 2 zeta f, and its bins scatter as random ones do (inf when
    the record is too short to tell: the line is then taken for hum, as before)."""
    f, x = signal.welch(r, fs=fs_hz, nperseg=min(r.size, int(TONE_SEG_S * fs_hz)))
    df = float(f[1] - f[0])
    k0, span = int(round(f0 / df)), max(4, int(round(TONE_SPAN_HZ / df)))
    if k0 - span < 1 or k0 + span >= x.size:
        return math.inf
    kp = k0 - span + int(np.argmax(x[k0 - span:k0 + span + 1]))
    side = np.r_[x[k0 - span:kp - 1], x[kp + 2:k0 + span + 1]]
    base = float(np.median(side)) if side.size else 0.0
    return float(x[kp] / base) if base > 0 else math.inf


def spectral(res: Sequence[np.ndarray], fs_hz: float, band_hz: tuple[float, float],
             inputs: Sequence[np.ndarray] | None = None, modes_hz: Sequence[float] = (),
             via_input: np.ndarray | None = None) -> Floor:
    """The residual's noise power outside the input band (out_of_band_power, beside the
    model's modes ``modes_hz``; ``via_input``: the model's response to the input sensor's
    noise, input_noise_records', which near a mode is part of the floor), or, when the band
    leaves too little room on either side, the top band's white-equivalent level."""
    oob, tops = [], []
    for r in res:
        seg = min(1024, r.size)
        f, p = signal.welch(r, fs=fs_hz, nperseg=seg)
        top = _level(f, p, TOP_BAND[0] * fs_hz, TOP_BAND[1] * fs_hz)
        if top is not None:
            tops.append(top * fs_hz / 2)
        q = (signal.welch(via_input, fs=fs_hz, nperseg=seg)[1]
             if via_input is not None and via_input.size >= seg else None)
        o = out_of_band_power(f, p, band_hz, modes_hz, q)
        if o is not None:
            oob.append(o)
    hum, lines = mains_hum(res, inputs, fs_hz) if inputs is not None else (0.0, [])
    with_hum = (f"; plus mains hum at {', '.join(f'{x:g}' for x in lines)} Hz"
                if lines else "")
    if oob and len(oob) == len(res):
        return Floor(math.sqrt(float(np.median(oob)) + hum), "out of band",
                     "the residual's spectrum outside the input band, across it as a power "
                     "law between its two sides (or the lower side's level where an "
                     "anti-alias filter rolls the upper side off)" + with_hum)
    if tops:
        return Floor(math.sqrt(float(np.median(tops))), "top band",
                     "0.45-0.5 fs, white-equivalent: assumes white noise and a steep "
                     "anti-alias filter (the input band leaves no room on either side)")
    return Floor(math.nan, "none", "records too short for a spectrum")
