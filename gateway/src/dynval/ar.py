"""AR / ARX / AR-ARX models over numpy arrays, computed by the C core (dv_ar, dv_arx,
dv_arstats): the same numbers the firmware produces (report Section 5.4.1).

Sign convention (as the C headers): x_hat_i = sum_j a_j (x_{i-j} - mean), e_i = (x_i - mean) -
x_hat_i; ``a[j-1]`` holds a_j and ``refl[m-1]`` the partial autocorrelation phi_mm. Residual
arrays are packed like the C block API: one value per accepted sample once ``order`` samples
precede it (NaN/Inf samples are dropped and counted, see ``nonfinite``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np

from dynval._core import as_doubles, check, ffi, lib, ptr
from dynval.features import Stats, _stats

Method = Literal["yule_walker", "burg"]

DV_OK = 0
DV_DONE = 1
DV_ENUMERIC = -4
def _new(ctype: str, init: Any = None) -> Any:
    """ffi.new, typed as Any (cffi's stubs know no struct fields)."""
    return ffi.new(ctype, init)


def _max_order() -> int:
    m = _new("dv_ar_model_t *")
    return int(ffi.sizeof(m.a) // ffi.sizeof("double"))


MAX_ORDER = _max_order()


def _method(method: Method) -> int:
    if method == "yule_walker":
        return int(lib.DV_AR_YULE_WALKER)
    if method == "burg":
        return int(lib.DV_AR_BURG)
    raise ValueError(f"method must be 'yule_walker' or 'burg', not {method!r}")


def _work_len(n: int, p: int) -> int:
    return 2 * n + 4 * (p + 1)  # DV_AR_WORK_LEN


def _arr(c: Any, k: int) -> np.ndarray:
    """The first k elements of a C double array, as a new float64 array."""
    if k == 0:
        return np.empty(0)
    return np.frombuffer(cast(Any, ffi.buffer(c, 8 * k)), dtype=np.float64).copy()


@dataclass(frozen=True)
class ARModel:
    """A fitted AR(p) model (dv_ar_model_t)."""

    order: int
    n: int
    mean: float
    sigma2: float
    a: np.ndarray
    refl: np.ndarray

    def _c(self) -> Any:
        c = _new("dv_ar_model_t *")
        c.order, c.n, c.mean, c.sigma2 = self.order, self.n, self.mean, self.sigma2
        for j in range(self.order):
            c.a[j] = float(self.a[j])
            c.refl[j] = float(self.refl[j])
        return c


@dataclass(frozen=True)
class OrderSelection:
    """AIC and PACF curves for orders 1..pmax and the chosen orders (dv_ar_order_t)."""

    pmax: int
    n: int
    p_aic: int
    p_pacf: int
    band: float
    aic: np.ndarray
    pacf: np.ndarray
    sigma2: np.ndarray


@dataclass(frozen=True)
class ARXModel:
    """A fitted ARX(na, nb, nk) model (dv_arx_model_t)."""

    na: int
    nb: int
    nk: int
    n_rows: int
    alpha: np.ndarray
    beta: np.ndarray
    sigma2: float
    rcond: float

    def _c(self) -> Any:
        c = _new("dv_arx_model_t *")
        c.na, c.nb, c.nk, c.n_rows = self.na, self.nb, self.nk, self.n_rows
        c.sigma2, c.rcond = self.sigma2, self.rcond
        for j in range(self.na):
            c.alpha[j] = float(self.alpha[j])
        for j in range(self.nb):
            c.beta[j] = float(self.beta[j])
        return c


def _ar_model(c: Any) -> ARModel:
    p = int(c.order)
    return ARModel(p, int(c.n), float(c.mean), float(c.sigma2), _arr(c.a, p), _arr(c.refl, p))


def _arx_model(c: Any) -> ARXModel:
    return ARXModel(int(c.na), int(c.nb), int(c.nk), int(c.n_rows), _arr(c.alpha, int(c.na)),
                    _arr(c.beta, int(c.nb)), float(c.sigma2), float(c.rcond))


def autocorr(x: Any, maxlag: int) -> np.ndarray:
    """Biased autocorrelation r_k = (1/n) sum x_i x_{i+k}, k = 0..maxlag (no mean removed)."""
    a = as_doubles(x)
    r = np.empty(maxlag + 1)
    check(lib.dv_ar_autocorr(ptr(a), a.size, maxlag, ptr(r)), "dv_ar_autocorr")
    return r


def fit(x: Any, order: int, method: Method = "yule_walker") -> ARModel:
    """Fit AR(order) to the record x (mean removed first): Yule-Walker (Levinson-Durbin on the
    biased autocorrelation, eq. 27) or Burg. CoreError DV_ENUMERIC for a constant, non-finite or
    perfectly predictable record, DV_EINVAL for order >= len(x) or > MAX_ORDER."""
    a = as_doubles(x)
    wl = _work_len(a.size, order)
    work = _new("double[]", wl)
    m = _new("dv_ar_model_t *")
    check(lib.dv_ar_fit(m, _method(method), order, ptr(a), a.size, work, wl), "dv_ar_fit")
    return _ar_model(m)


def yule_walker(x: Any, order: int) -> ARModel:
    """AR(order) by Yule-Walker / Levinson-Durbin (see fit)."""
    return fit(x, order, "yule_walker")


def burg(x: Any, order: int) -> ARModel:
    """AR(order) by Burg's method (see fit)."""
    return fit(x, order, "burg")


def select_order(x: Any, pmax: int, method: Method = "yule_walker") -> OrderSelection:
    """AIC (eq. 28) and PACF (eq. 30, band 2/sqrt(n)) curves for orders 1..pmax, and the orders
    each rule picks. pmax in the result is lower than asked if the recursion stopped early."""
    a = as_doubles(x)
    wl = _work_len(a.size, pmax)
    work = _new("double[]", wl)
    o = _new("dv_ar_order_t *")
    check(lib.dv_ar_order(o, _method(method), pmax, ptr(a), a.size, work, wl), "dv_ar_order")
    k = int(o.pmax)
    return OrderSelection(k, int(o.n), int(o.p_aic), int(o.p_pacf), float(o.band),
                          _arr(o.aic, k), _arr(o.pacf, k), _arr(o.sigma2, k))


def arx_fit(x: Any, f: Any, na: int, nb: int, nk: int = 1) -> ARXModel:
    """ARX(na, nb, nk) by least squares (eq. 32; Givens QR): x_i ~ sum alpha_j x_{i-j} +
    sum beta_t f_{i-nk-t}. No mean is removed. CoreError DV_ENUMERIC for a singular problem."""
    a, b = as_doubles(x), as_doubles(f)
    if a.size != b.size:
        raise ValueError(f"arx_fit needs equally long x and f, got {a.size} and {b.size}")
    q = na + nb
    wl = q * q + 3 * q + 1 + q  # DV_ARX_WORK_LEN
    work = _new("double[]", wl)
    cfg = _new("dv_arx_cfg_t *", {"na": na, "nb": nb, "nk": nk})
    m = _new("dv_arx_model_t *")
    check(lib.dv_arx_fit(m, cfg, ptr(a), ptr(b), a.size, work, wl), "dv_arx_fit")
    return _arx_model(m)


def ararx_fit(x: Any, p: int, na: int, nb: int, nk: int = 0) -> tuple[ARXModel, ARModel]:
    """AR-ARX two-stage estimate (eq. 37-38): AR(p) residuals stand in for the input of an
    ARX(na, nb, nk) of the centred record. Needs p >= na + nb. Returns (ARX, stage-1 AR)."""
    a = as_doubles(x)
    q = na + nb
    wl = 2 * a.size + 4 * (p + 1) + q * q + 3 * q + 1 + q  # DV_ARARX_WORK_LEN
    work = _new("double[]", wl)
    cfg = _new("dv_arx_cfg_t *", {"na": na, "nb": nb, "nk": nk})
    m = _new("dv_arx_model_t *")
    ar = _new("dv_ar_model_t *")
    check(lib.dv_ararx_fit(m, ar, cfg, p, ptr(a), a.size, work, wl), "dv_ararx_fit")
    return _arx_model(m), _ar_model(ar)


class ARResidual:
    """Streaming AR residual (dv_ar_resid_t, eq. 31). update() takes any number of samples and
    returns the residuals of the accepted samples that had p predecessors (packed)."""

    def __init__(self, model: ARModel) -> None:
        self._m = model._c()
        n_buf = int(lib.dv_ar_resid_buf_len(model.order))  # coefficients + history
        self._buf = _new("double[]", max(n_buf, 1))
        self._s = _new("dv_ar_resid_t *")
        check(lib.dv_ar_resid_init(self._s, self._m, self._buf, n_buf), "dv_ar_resid_init")

    def update(self, x: Any) -> np.ndarray:
        """Block API (dv_ar_resid_update_block): a multi-output kernel over the whole array."""
        a = as_doubles(x)
        e = np.empty(a.size)
        n_out = _new("size_t *")
        st = lib.dv_ar_resid_update_block(self._s, ptr(a), a.size, ptr(e), n_out)
        if st != DV_ENUMERIC:  # DV_ENUMERIC: some samples dropped and counted, not an error
            check(st, "dv_ar_resid_update_block")
        return e[: int(n_out[0])].copy()

    def update_each(self, x: Any) -> np.ndarray:
        """Per-sample API (dv_ar_resid_update), one call per sample: the firmware's path."""
        out = _new("double *")
        res: list[float] = []
        for v in as_doubles(x).tolist():
            if lib.dv_ar_resid_update(self._s, v, out) == DV_OK:
                res.append(float(out[0]))
        return np.asarray(res, dtype=np.float64)

    def reset(self) -> None:
        lib.dv_ar_resid_reset(self._s)

    @property
    def nonfinite(self) -> int:
        """NaN/Inf samples dropped since construction/reset."""
        return int(lib.dv_ar_resid_nonfinite(self._s))


def ar_residual(model: ARModel, x: Any, per_sample: bool = False) -> np.ndarray:
    """Residual of x under model, packed (len(x) - order - dropped values); per_sample=True runs
    the firmware's per-sample API instead of the block kernel (equal up to round-off)."""
    r = ARResidual(model)
    return r.update_each(x) if per_sample else r.update(x)


class ARXResidual:
    """Streaming ARX residual given the input channel (dv_arx_resid_t)."""

    def __init__(self, model: ARXModel) -> None:
        self._m = model._c()
        blen = 2 * model.na + 2 * (model.nb + model.nk)
        self._buf = _new("double[]", max(blen, 1))
        self._s = _new("dv_arx_resid_t *")
        check(lib.dv_arx_resid_init(self._s, self._m, self._buf, blen), "dv_arx_resid_init")

    def update(self, x: Any, f: Any) -> np.ndarray:
        """Push (x_i, f_i) pairs; the residuals of the ready, accepted pairs (packed)."""
        a, b = as_doubles(x), as_doubles(f)
        if a.size != b.size:
            raise ValueError(f"ARXResidual.update needs equal lengths, got {a.size} and {b.size}")
        out = _new("double *")
        res: list[float] = []
        for u, v in zip(a.tolist(), b.tolist(), strict=True):
            if lib.dv_arx_resid_update(self._s, u, v, out) == DV_OK:
                res.append(float(out[0]))
        return np.asarray(res, dtype=np.float64)

    def reset(self) -> None:
        lib.dv_arx_resid_reset(self._s)

    @property
    def nonfinite(self) -> int:
        return int(lib.dv_arx_resid_nonfinite(self._s))


def arx_residual(model: ARXModel, x: Any, f: Any) -> np.ndarray:
    """ARX residual of (x, f) under model, packed."""
    return ARXResidual(model).update(x, f)


@dataclass(frozen=True)
class ResidualStats:
    """Residual statistics and outliers beyond k_sigma (dv_arstats_out_t + the stored outliers).
    indices: positions in the residual array (record) or stream positions (stream);
    sizes: signed sizes in sigmas. Only the first `capacity` outliers are stored."""

    rec: Stats
    win: Stats | None
    k_sigma: float
    n_outliers: int
    n_overflow: int
    n_nonfinite: int
    indices: np.ndarray
    sizes: np.ndarray


def _res_stats(o: Any, idx: Any, size: Any) -> ResidualStats:
    k = int(o.n_stored)
    ind = np.frombuffer(cast(Any, ffi.buffer(idx, 4 * k)), dtype=np.uint32).copy() if k else \
        np.empty(0, dtype=np.uint32)
    return ResidualStats(_stats(o.rec), _stats(o.win) if o.win_ready else None, float(o.k_sigma),
                         int(o.n_outliers), int(o.n_overflow), int(o.n_nonfinite), ind,
                         _arr(size, k))


def residual_stats(e: Any, k_sigma: float = 4.0, capacity: int = 4096) -> ResidualStats:
    """RMS, skewness, kurtosis of a residual record and its outliers |e_i - mean| > k_sigma std
    (the impact detector). NaN/Inf samples are skipped and counted."""
    a = as_doubles(e)
    o = _new("dv_arstats_out_t *")
    idx = _new("uint32_t[]", max(capacity, 1))
    size = _new("double[]", max(capacity, 1))
    st = lib.dv_arstats_record(o, k_sigma, ptr(a), a.size, idx, size, capacity)
    if st != DV_ENUMERIC:
        check(st, "dv_arstats_record")
    return _res_stats(o, idx, size)


class ResidualMonitor:
    """Streaming residual statistics with a windowed k-sigma outlier test (dv_arstats_t): each
    sample is tested against the mean/STD of the win_len samples before it."""

    def __init__(self, k_sigma: float = 4.0, win_len: int = 256, capacity: int = 4096) -> None:
        blen = max(int(lib.dv_sliding_buf_len(win_len)), 1)  # DV_ARSTATS_BUF_LEN; 0: bad length
        self._buf = _new("double[]", blen)
        self._idx = _new("uint32_t[]", max(capacity, 1))
        self._size = _new("double[]", max(capacity, 1))
        self._s = _new("dv_arstats_t *")
        check(lib.dv_arstats_init(self._s, k_sigma, win_len, self._buf, blen, self._idx,
                                  self._size, capacity), "dv_arstats_init")

    def update(self, e: Any) -> int:
        """Push residual samples; returns how many of them were flagged as outliers."""
        flagged = 0
        for v in as_doubles(e).tolist():
            flagged += lib.dv_arstats_update(self._s, v) == DV_DONE
        return flagged

    def get(self) -> ResidualStats:
        o = _new("dv_arstats_out_t *")
        check(lib.dv_arstats_get(self._s, o), "dv_arstats_get")
        return _res_stats(o, self._idx, self._size)

    def reset(self) -> None:
        lib.dv_arstats_reset(self._s)
