"""Modal properties (report 5.1): experimental modal analysis of measured FRFs, the model's
numerical modes from the C core, and their comparison (relative frequency error, damping
error, MAC matrix of eq. 8 and its diagonal).

The estimator is a compact least-squares complex frequency (LSCF) fit: a common-denominator
rational model of all outputs' FRFs on a z-domain basis, its poles over a range of model
orders, the poles that stay put from order to order kept (a stabilisation diagram read
automatically), then the residues by a least-squares frequency-domain (LSFD) fit with lower
and upper residuals. Written here rather than taken from sdypy-EMA: that package imports
pyplot and prints at import, and its automatic pole selection needs approximate natural
frequencies (which here would be the model's: the check would lean on what it checks).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dynval import model as mdl
from dynval.catalogue.frf import Frf, estimate
from dynval.errors import ConfigError

log = logging.getLogger(__name__)

MAX_ORDER = 32  # highest LSCF denominator order of the stabilisation diagram
DF_STABLE = 0.01  # a pole is stable from one order to the next within 1 % in frequency
DZ_STABLE = 0.10  # and 10 % in damping ratio
ZETA_MAX = 0.3  # poles damped more than this are noise poles


@dataclass(frozen=True)
class Modes:
    """Modes in ascending frequency: natural frequencies (Hz, |pole| / 2 pi), damping ratios,
    real mode shapes at the sensors (n_sensor x n_mode, unit max-magnitude) and the sensor
    names; complex_shapes the residues they come from (EMA only)."""

    f_hz: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    sensors: tuple[str, ...]
    complex_shapes: np.ndarray | None = None


def _normal_blocks(w: np.ndarray, h: np.ndarray, ts: float, order: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R, S_o, T_o of the LSCF normal equations (Peeters et al., 2004) for the basis z^r,
    z = exp(j w ts), r = 0..order: those of a lower order are their leading blocks."""
    omega = np.exp(1j * np.outer(w, ts * np.arange(order + 1)))  # n_freq x (n+1)
    r = (omega.conj().T @ omega).real
    s = np.stack([-(omega.conj().T @ (h[:, o:o + 1] * omega)).real for o in range(h.shape[1])])
    t = np.stack([(omega.conj().T @ (np.abs(h[:, o:o + 1]) ** 2 * omega)).real
                  for o in range(h.shape[1])])
    return r, s, t


def _lscf_poles(blocks: tuple[np.ndarray, np.ndarray, np.ndarray], ts: float, order: int
                ) -> np.ndarray:
    """Continuous-time poles of the order-n common denominator of all outputs: the reduced
    normal equations M = sum_o T_o - S_o^T R^-1 S_o, the highest coefficient fixed to 1."""
    n1 = order + 1
    r, s, t = blocks[0][:n1, :n1], blocks[1][:, :n1, :n1], blocks[2][:, :n1, :n1]
    m = np.sum(t, axis=0) - sum(so.T @ np.linalg.solve(r, so) for so in s)
    alpha = np.append(np.linalg.solve(m[:order, :order], -m[:order, order]), 1.0)
    z = np.roots(alpha[::-1])
    return np.asarray(np.log(z.astype(complex)) / ts)


def _physical(p: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    p = p[p.imag > 0]
    f = np.abs(p) / (2 * np.pi)
    zeta = -p.real / np.abs(p)
    return np.asarray(p[(zeta > 0) & (zeta < ZETA_MAX) & (f >= band[0]) & (f <= band[1])])


def _close(a: complex, b: complex) -> bool:
    fa, fb = abs(a), abs(b)
    za, zb = -a.real / fa, -b.real / fb
    return abs(fa - fb) <= DF_STABLE * fa and abs(za - zb) <= DZ_STABLE * za


def stable_poles(w: np.ndarray, h: np.ndarray, band: tuple[float, float],
                 max_order: int = MAX_ORDER) -> list[complex]:
    """The stabilisation diagram read automatically: poles of each order from 2 to max_order
    stable against the previous order, grouped by frequency (1 %); a group counts when it is
    stable at a third of the orders or more; its pole is the group's median."""
    ts = np.pi / w.max()  # the band's top at the Nyquist of the basis
    blocks = _normal_blocks(w, h, ts, max_order)
    prev: np.ndarray = np.zeros(0, complex)
    groups: list[list[complex]] = []
    for n in range(2, max_order + 1):
        try:
            cur = _physical(_lscf_poles(blocks, ts, n), band)
        except np.linalg.LinAlgError:  # a degenerate order (e.g. an FRF of zeros): no poles
            cur = np.zeros(0, complex)
        for p in cur:
            if not any(_close(p, q) for q in prev):
                continue
            for g in groups:
                if abs(abs(g[-1]) - abs(p)) <= DF_STABLE * abs(p):
                    g.append(p)
                    break
            else:
                groups.append([p])
        prev = cur
    need = max(2, (max_order - 1) // 3)
    return sorted((_median_pole(g) for g in groups if len(g) >= need), key=abs)


def _median_pole(g: Sequence[complex]) -> complex:
    """The pole of median frequency and median damping ratio of a stable group (high orders
    fit noise and wander; the median of the orders does not)."""
    w = float(np.median(np.abs(g)))
    zeta = float(np.median([-p.real / abs(p) for p in g]))
    return complex(-zeta * w, w * np.sqrt(1.0 - zeta * zeta))


def lsfd(w: np.ndarray, h: np.ndarray, poles: Sequence[complex]) -> np.ndarray:
    """Residues (n_out x n_mode) of h = sum_k R_k / (jw - p_k) + conj(R_k) / (jw - conj p_k)
    + LR / (jw)^2 + UR, least squares over the lines, every output on its own."""
    jw = 1j * w
    cols = []
    for p in poles:
        cols += [1 / (jw - p) + 1 / (jw - np.conj(p)), 1j / (jw - p) - 1j / (jw - np.conj(p))]
    cols += [1 / jw ** 2, np.ones_like(jw)]
    a = np.column_stack(cols)
    a_ri = np.vstack([a.real, a.imag])
    b_ri = np.vstack([h.real, h.imag])
    x = np.linalg.lstsq(a_ri, b_ri, rcond=None)[0]  # R_k = x[2k] + j x[2k + 1]
    n = len(poles)
    return np.asarray((x[0:2 * n:2] + 1j * x[1:2 * n:2]).T)


def real_shape(r: np.ndarray) -> np.ndarray:
    """The real vector closest to a complex mode shape: rotated by the angle that makes it
    most real (half the angle of sum r^2), scaled to unit largest magnitude."""
    v = (r * np.exp(-0.5j * np.angle(np.sum(r * r)))).real
    big = v[np.argmax(np.abs(v))]
    return np.asarray(v / big if big != 0 else v)


def ema(frf: Frf, band_hz: tuple[float, float], n_modes: int | None = None, *,
        derivative: int = 2, max_order: int = MAX_ORDER) -> Modes:
    """Experimental modal analysis of frf's H1 over the band: LSCF poles read from the
    stabilisation diagram, LSFD residues; n_modes: keep the strongest (largest modal peak
    sum |R| / sigma over the outputs), else every stable mode. derivative: the outputs'
    order over displacement (2: accelerations), removed before the residue fit."""
    sel = frf.band(band_hz) & (frf.f_hz > 0)
    w = 2 * np.pi * frf.f_hz[sel]
    h = frf.h1[sel] / (1j * w[:, None]) ** derivative
    if not np.isfinite(h).all():
        raise ConfigError("EMA: the FRF is not finite in the band (no input power there?)")
    if w.size < max_order:
        raise ConfigError(f"EMA: {band_hz[0]:g}-{band_hz[1]:g} Hz holds {w.size} FRF lines, "
                          f"the fit up to order {max_order} needs {max_order} (a wider band "
                          "or a longer window)")
    poles = stable_poles(w, h, band_hz, max_order)
    if not poles:
        raise ConfigError(f"EMA: no stable mode in {band_hz[0]:g}-{band_hz[1]:g} Hz")
    res = lsfd(w, h, poles)
    if n_modes is not None:
        if len(poles) < n_modes:
            raise ConfigError(f"EMA: {len(poles)} stable modes in {band_hz[0]:g}-"
                              f"{band_hz[1]:g} Hz, {n_modes} asked")
        peak = np.sum(np.abs(res), axis=0) / np.array([-p.real for p in poles])
        keep = sorted(np.argsort(peak)[::-1][:n_modes])
        poles, res = [poles[k] for k in keep], res[:, keep]
    p = np.array(poles)
    shapes = np.column_stack([real_shape(res[:, k]) for k in range(p.size)])
    return Modes(np.abs(p) / (2 * np.pi), -p.real / np.abs(p), shapes, frf.names, res)


def numerical(m: mdl.Model, sensors: Sequence[str]) -> Modes:
    """The model's modes at the sensors (output names of m, motions): undamped frequencies and
    shapes from the C core's eigen-solution (dv_model_get_modes), damping ratios from the
    complex eigenvalues of the core's M, C, K (exact for non-proportional damping too; an
    overdamped mode's from the modal projection of C)."""
    lin = mdl.linear(m)
    n = m.n_dof
    minv = np.diag(1.0 / lin.mass)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-minv @ lin.k, -minv @ lin.c]])
    lam = np.linalg.eigvals(a)
    lam = lam[lam.imag > 0]
    zeta = np.empty(n)
    for k, f in enumerate(lin.f_hz):
        w = 2 * np.pi * f
        near = lam[np.argmin(np.abs(np.abs(lam) - w))] if lam.size else 0j
        if abs(abs(near) - w) <= 0.1 * w:
            zeta[k] = -near.real / abs(near)
        else:  # overdamped (no oscillating pole): the modal projection phi' C phi / 2 w
            p = lin.phi[:, k]
            zeta[k] = p @ lin.c @ p / (2 * w) if w > 0 else np.nan
    rows = []
    for s in sensors:
        o = m.outputs.get(s)
        if o is None or o.kind not in ("acc", "vel", "disp"):
            raise ConfigError(f"modes at '{s}': not a motion output of the model")
        rows.append(lin.phi[o.index - 1])
    shapes = np.array(rows)
    shapes = np.column_stack([real_shape(shapes[:, k].astype(complex)) for k in range(n)])
    return Modes(lin.f_hz.copy(), zeta, shapes, tuple(sensors))


def mac(phi_n: np.ndarray, phi_e: np.ndarray) -> np.ndarray:
    """MAC_ij between numerical shape i and experimental shape j (report eq. 8; for complex
    shapes the Hermitian form)."""
    num = np.abs(phi_n.conj().T @ phi_e) ** 2
    den = np.outer(np.sum(np.abs(phi_n) ** 2, axis=0), np.sum(np.abs(phi_e) ** 2, axis=0))
    return np.asarray(num / den)


@dataclass(frozen=True)
class ModalComparison:
    """EMA against the model, per model mode in the band (NaN where no EMA mode lies within
    5 % of its frequency): relative frequency error, damping ratio error (EMA - model), the
    diagonal MAC, and the full MAC matrix (model modes x EMA modes)."""

    f_model_hz: np.ndarray
    f_rel_err: np.ndarray
    zeta_err: np.ndarray
    mac_diag: np.ndarray
    mac: np.ndarray


def compare(exp: Modes, num: Modes, band_hz: tuple[float, float]) -> ModalComparison:
    """Each numerical mode in the band paired with the EMA mode nearest in frequency."""
    if exp.sensors != num.sensors:
        raise ConfigError(f"modal comparison: sensors differ ({', '.join(exp.sensors)} vs "
                          f"{', '.join(num.sensors)})")
    inb = np.flatnonzero((num.f_hz >= band_hz[0]) & (num.f_hz <= band_hz[1]))
    mm = mac(num.shapes[:, inb], exp.shapes)
    fe, ze, md = (np.full(inb.size, np.nan) for _ in range(3))
    for i, k in enumerate(inb):
        j = int(np.argmin(np.abs(exp.f_hz - num.f_hz[k])))
        if abs(exp.f_hz[j] - num.f_hz[k]) <= 0.05 * num.f_hz[k]:
            fe[i] = exp.f_hz[j] / num.f_hz[k] - 1.0
            ze[i] = exp.zeta[j] - num.zeta[k]
            md[i] = mm[i, j]
    return ModalComparison(num.f_hz[inb], fe, ze, md, mm)


def record_modes(u: np.ndarray, y: dict[str, np.ndarray], fs_hz: float,
                 band_hz: tuple[float, float], n_modes: int) -> Modes | None:
    """EMA of one record at the report's FRF settings (the feature grammar's modal terms);
    None (logged) when the record does not show n_modes stable modes in the band."""
    try:
        return ema(estimate(u, y, fs_hz), band_hz, n_modes)
    except ConfigError as exc:
        log.warning("modal features: %s", exc)
        return None


def paired_mac(exp: Modes, ref: Modes) -> np.ndarray:
    """MAC of each reference mode with the experimental mode nearest in frequency."""
    mm = mac(ref.shapes, exp.shapes)
    near = [int(np.argmin(np.abs(exp.f_hz - f))) for f in ref.f_hz]
    return np.array([mm[i, j] for i, j in enumerate(near)])
