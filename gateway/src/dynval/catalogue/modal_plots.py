"""Figures of the modal and FRF features (dynval.plotting conventions: measured black, the
model purple, a failed check red, a passed one green; tick labels untangled): the FRF and
coherence overlay of the report's Fig. 43-47 with the check's scalars in the title, the mode
shapes of Fig. 22 and the MAC matrix of Fig. 23. Each returns the matplotlib figure."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dynval import plotting as plot
from dynval.catalogue.frf import Comparison, Frf
from dynval.catalogue.modal import ModalComparison, Modes


def plot_frf(curves: Sequence[tuple[str, Frf, int, str]], band_hz: tuple[float, float],
             check: Comparison | None = None, unit: str = "(m/s^2)/N") -> Any:
    """|H1| (log) over coherence for each (label, frf, output index, colour), the band
    shaded; check: its scalars and verdict in the title (linearity / reciprocity)."""
    plt = plot.pyplot()
    fig, (ax_h, ax_c) = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True,
                                     gridspec_kw={"height_ratios": [2, 1]})
    for label, frf, j, colour in curves:
        ax_h.semilogy(frf.f_hz, np.abs(frf.h1[:, j]), color=colour, lw=1.0, label=label)
        ax_c.plot(frf.f_hz, frf.coh[:, j], color=colour, lw=1.0)
    for ax in (ax_h, ax_c):
        ax.axvspan(*band_hz, color=plot.NEUTRAL, alpha=0.08, lw=0)
        ax.grid(True, which="both", alpha=0.3)
    ax_h.set_ylabel(f"|H1| ({unit})")
    ax_c.set_ylabel("coherence")
    ax_c.set_ylim(0.0, 1.05)
    ax_c.set_xlabel("frequency (Hz)")
    ax_h.legend(fontsize=8, loc="upper right")
    if check is not None:
        ax_h.set_title(f"{'holds' if check.passed else 'fails'}: z2(H1) {check.z2:.2f}, "
                       f"z2(coherence) {check.z2_coh:.2f}, mean |dB| {check.db:.2f} over "
                       f"{band_hz[0]:g}-{band_hz[1]:g} Hz", fontsize=9,
                       color=plot.BEST if check.passed else plot.WORST)
    plot.untangle_ticks(fig)
    return fig


def plot_modes(exp: Modes, num: Modes, cmp: ModalComparison) -> Any:
    """The EMA's mode shapes (black) over the model's (purple) at the sensors, one panel per
    model mode in the band, each with its frequency error and diagonal MAC (Fig. 22)."""
    plt = plot.pyplot()
    k = cmp.f_model_hz.size
    fig, axs = plt.subplots(1, k, figsize=(2.4 * k + 0.8, 3.6), sharey=True, squeeze=False)
    pos = np.arange(1, len(num.sensors) + 1)
    for i, ax in enumerate(axs[0]):
        n_idx = int(np.argmin(np.abs(num.f_hz - cmp.f_model_hz[i])))
        e_idx = int(np.argmin(np.abs(exp.f_hz - cmp.f_model_hz[i])))
        phi_n = num.shapes[:, n_idx]
        phi_e = exp.shapes[:, e_idx]
        phi_e = -phi_e if float(phi_n @ phi_e) < 0 else phi_e  # a shape's sign is arbitrary
        ax.plot(phi_n, pos, "-o", color=plot.MODEL, label="model")
        ax.plot(phi_e, pos, "--s", color=plot.MEASURED, mfc="none", label="EMA")
        ax.axvline(0.0, color=plot.NEUTRAL, lw=0.6)
        ax.set_title(f"{cmp.f_model_hz[i]:.2f} Hz\nf err {100 * cmp.f_rel_err[i]:+.2f} %, "
                     f"MAC {cmp.mac_diag[i]:.4f}", fontsize=8)
        ax.set_xlabel("shape (max = 1)")
        ax.grid(True, alpha=0.3)
    axs[0][0].set_yticks(pos, [s.split("_")[0] for s in num.sensors])
    axs[0][0].legend(fontsize=8, loc="lower left")
    plot.untangle_ticks(fig)
    return fig


def plot_mac(cmp: ModalComparison, exp: Modes) -> Any:
    """The MAC matrix (eq. 8): model modes in the band x EMA modes, values printed (Fig. 23)."""
    plt = plot.pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 4.2))
    im = ax.imshow(cmp.mac, vmin=0.0, vmax=1.0, cmap="Greys", origin="lower")
    for (i, j), v in np.ndenumerate(cmp.mac):
        ax.text(j, i, f"{v:.3f}", ha="center", va="center", fontsize=8,
                color="white" if v > 0.5 else "black")
    ax.set_xticks(range(exp.f_hz.size), [f"{f:.1f}" for f in exp.f_hz])
    ax.set_yticks(range(cmp.f_model_hz.size), [f"{f:.1f}" for f in cmp.f_model_hz])
    ax.set_xlabel("EMA mode (Hz)")
    ax.set_ylabel("model mode (Hz)")
    fig.colorbar(im, ax=ax, label="MAC")
    plot.untangle_ticks(fig)
    return fig
