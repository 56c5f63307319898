"""One figure per catalogue feature (report Figures 27-29, 32-35, 40, 48-53 in kind), for
records given as label -> samples ('measured' drawn black, the others in the model colours
of dynval.plotting), each figure with its metric in the title."""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from dynval import plotting as plot
from dynval.catalogue import holder, spectral, waveform

Series = Mapping[str, np.ndarray]
_OTHERS = (plot.MODEL, plot.NEUTRAL, plot.BEST, plot.WORST, plot.AFTER)


def _colours(series: Series) -> list[tuple[str, np.ndarray, str]]:
    others = iter(_OTHERS)
    return [(k, v, plot.MEASURED if k == "measured" else next(others))
            for k, v in series.items()]


def _ref(series: Series) -> np.ndarray:
    return series["measured"] if "measured" in series else next(iter(series.values()))


def _finish(fig: Any, ax: Any, title: str, xlabel: str, ylabel: str) -> Any:
    ax.set_title(title, fontsize=9, loc="left")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.subplots_adjust(wspace=0.35)  # two panels side by side: room for the right's label
    plot.untangle_ticks(fig)
    return fig


def plot_distribution(series: Series, unit: str = "m/s^2") -> Any:
    """Normal probability plots and KDEs (5.2.2); KS distance to the measured in the legend."""
    fig, (a1, a2) = plot.pyplot().subplots(1, 2, figsize=(9, 3.4))
    ref = _ref(series)
    lo, hi = min(float(v.min()) for v in series.values()), max(float(v.max())
                                                              for v in series.values())
    grid = np.linspace(lo, hi, 400)
    for k, v, c in _colours(series):
        q, xs = waveform.npp(v)
        a1.plot(xs, q, ".", ms=1.5, color=c, label=k)
        a2.semilogy(grid, waveform.kde(v, grid), color=c,
                    label=f"{k}: KS {waveform.pdf_distance(v, ref):.3f}")
    a1.set_ylabel("standard normal quantile")
    a1.set_xlabel(f"amplitude ({unit})")
    a2.set_ylim(bottom=1e-5 / max(hi - lo, 1e-30))
    return _finish(fig, a2, "normal probability plot (left), kernel density (right)",
                   f"amplitude ({unit})", f"density (1/({unit}))")


def plot_decay(x: np.ndarray, fs_hz: float, unit: str = "m/s^2") -> Any:
    """A transient, its Hilbert envelope, the fitted y0 exp(a t) and the 10 % duration (5.2.4,
    Fig. 32 and 34)."""
    fig, ax = plot.pyplot().subplots(figsize=(8, 3.4))
    t = np.arange(x.size) / fs_hz
    i0 = int(np.argmax(np.abs(x)))
    y0, a = waveform.decay_fit(x, fs_hz)
    d10 = waveform.duration10(x, fs_hz)
    ax.plot(t, x, color=plot.MEASURED, lw=0.7, label="record")
    ax.plot(t, waveform.envelope(x), color=plot.NEUTRAL, lw=0.9, label="Hilbert envelope")
    ax.plot(t[i0:], y0 * np.exp(a * (t[i0:] - t[i0])), color=plot.MODEL,
            label=f"y0 exp(a t): y0 {y0:.3g}, a {a:.3g} 1/s")
    ax.axvspan(t[i0], t[i0] + d10, color=plot.BEST, alpha=0.15, label=f"10 % duration {d10:.3g} s")
    return _finish(fig, ax, "transient decay", "time (s)", f"acceleration ({unit})")


def plot_acf(series: Series, fs_hz: float, max_lag: int | None = None) -> Any:
    """Autocorrelation functions (5.2.6, Fig. 40) with their correlation to the measured's."""
    fig, ax = plot.pyplot().subplots(figsize=(8, 3.4))
    ref = _ref(series)
    for k, v, c in _colours(series):
        r = waveform.acf(v, max_lag)
        ax.plot(np.arange(r.size) / fs_hz, r, color=c, lw=0.9,
                label=f"{k}: r {waveform.acf_corr(v, ref, max_lag):.4f}")
    return _finish(fig, ax, "autocorrelation", "lag (s)", "R_xx")


def plot_harmonics(series: Series, fs_hz: float) -> Any:
    """Whole-record Hann PSDs with the harmonic peaks marked (5.3.2, Fig. 48-49)."""
    fig, ax = plot.pyplot().subplots(figsize=(8, 3.4))
    for k, v, c in _colours(series):
        f, p = spectral.psd(v, fs_hz)
        h = spectral.harmonic_peaks(v, fs_hz)
        ax.semilogy(f, p, color=c, lw=0.8,
                    label=f"{k}: {h.count} harmonics, THD {h.thd_db:.1f} dB")
        idx = np.round(h.freqs_hz / (f[1] - f[0])).astype(int)
        ax.semilogy(h.freqs_hz, p[idx], "o", mfc="none", color=c, ms=5)
    ax.set_xlim(0, fs_hz / 2)
    return _finish(fig, ax, "PSD and harmonic peaks", "frequency (Hz)", "PSD (unit^2/Hz)")


def plot_srs(series: Series, fs_hz: float, unit: str = "m/s^2") -> Any:
    """Peak and RMS response spectra at 2 % damping (5.3.3, Fig. 50), with the dB distance to
    the measured's."""
    fig, ax = plot.pyplot().subplots(figsize=(8, 3.4))
    _, pk_ref, _ = spectral.response_spectrum(_ref(series), fs_hz)
    for k, v, c in _colours(series):
        fn, pk, rms = spectral.response_spectrum(v, fs_hz)
        ax.loglog(fn, pk, color=c, label=f"{k} peak: {spectral.db_distance(pk, pk_ref):.2f} dB")
        ax.loglog(fn, rms, "--", color=c, lw=0.8)
    return _finish(fig, ax, "response spectra, 2 % damping (solid peak, dashed RMS)",
                   "oscillator frequency (Hz)", f"absolute acceleration ({unit})")


def plot_cepstrum(series: Series, fs_hz: float) -> Any:
    """Cepstra (5.3.4, Fig. 51) and liftered log spectra (Fig. 52) with the envelope metric."""
    fig, (a1, a2) = plot.pyplot().subplots(1, 2, figsize=(10, 3.4))
    ref = _ref(series)
    for k, v, c in _colours(series):
        cep = spectral.cepstrum(v)
        a1.plot(np.arange(1, cep.size // 2), np.abs(cep[1:cep.size // 2]), color=c, lw=0.6,
                label=k)
        f, env = spectral.liftered_envelope(v, fs_hz)
        a2.plot(f, env, color=c,
                label=f"{k}: {spectral.cepstral_distance(v, ref, fs_hz):+.2f} dB")
    a1.set_xlabel("quefrency (samples)")
    a1.set_ylabel("|cepstrum|")
    a1.set_yscale("log")
    return _finish(fig, a2, "cepstrum (left), liftered log spectrum (right)", "frequency (Hz)",
                   "dB")


def plot_holder(x: np.ndarray, fs_hz: float, events_s: Sequence[float] = ()) -> Any:
    """The record, its Holder exponent with the drop-offs (circles) and known impacts (dots)
    (5.3.5, Fig. 53)."""
    fig, (a1, a2) = plot.pyplot().subplots(2, 1, figsize=(8, 5), sharex=True)
    t = np.arange(x.size) / fs_hz
    h = holder.holder_exponent(x)
    d = holder.drop_offs(h, fs_hz, ok=holder.readable(x))
    a1.plot(t, x, color=plot.MEASURED, lw=0.6)
    ev = np.asarray(events_s)
    a1.plot(ev, np.interp(ev, t, x), ".", color=plot.WORST, label="impacts")
    a1.plot(d.times_s, x[d.index], "o", mfc="none", color=plot.MODEL, label="drop-offs")
    a1.set_ylabel("record")
    a1.legend(fontsize=8)
    a2.plot(t, h, color=plot.NEUTRAL, lw=0.6)
    a2.plot(d.times_s, h[d.index], "o", mfc="none", color=plot.MODEL,
            label=f"{d.count} drop-offs")
    a2.axhline(d.threshold, color=plot.WORST, lw=0.8, ls="--", label="threshold")
    return _finish(fig, a2, "", "time (s)", "Holder exponent")


Figure = Callable[[Series, float, str], Any]


def _one(draw: Callable[[np.ndarray, float, str], Any]) -> Figure:
    return lambda series, fs_hz, unit: draw(_ref(series), fs_hz, unit)


# the figure of each catalogue grammar name (dynval.catalogue.signal_terms.TERMS) for records
# label -> samples at fs_hz in a unit: what the validate report draws for a term it computed
FIGURES: dict[str, Figure] = {
    **dict.fromkeys(("ks", "ad"), lambda s, fs, unit: plot_distribution(s, unit)),
    **dict.fromkeys(("d10", "decay", "decay_y0"), _one(plot_decay)),
    "acf_corr": lambda s, fs, unit: plot_acf(s, fs),
    **dict.fromkeys(("harm_n", "thd"), lambda s, fs, unit: plot_harmonics(s, fs)),
    **dict.fromkeys(("srs_peak", "srs_rms"), plot_srs),
    "cep_env": lambda s, fs, unit: plot_cepstrum(s, fs),
    **dict.fromkeys(("holder_drops", "holder_min"),
                    _one(lambda x, fs, unit: plot_holder(x, fs))),
}
