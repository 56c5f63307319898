"""dynval.ar: independent numpy/scipy references (solve_toeplitz, a numpy Burg, lstsq, lfilter),
closed forms, errors, and bit-for-bit equality with the C library (tests/tools/dv_ar_dump.c)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg, signal, stats

from dynval import ar
from dynval.errors import CoreError

A4 = np.array([1.2, -0.9, 0.5, -0.3])  # AR(4), stable


def _ar_process(a: np.ndarray, n: int, seed: int, mean: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return signal.lfilter([1.0], np.r_[1.0, -a], rng.standard_normal(n + 500))[500:] + mean


@pytest.fixture
def x4() -> np.ndarray:
    return _ar_process(A4, 8192, 11, mean=2.5)


@pytest.fixture
def arx_data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    f = rng.standard_normal(4000)
    # equation-error form, so ARX(2, 2, 1) is the true model (output noise would bias it)
    x = signal.lfilter([0, 0.5, -0.2], [1, -1.6, 0.8], f) + \
        signal.lfilter([1.0], [1, -1.6, 0.8], 0.05 * rng.standard_normal(4000))
    return x, f


def _acf(x: np.ndarray, maxlag: int) -> np.ndarray:
    n = x.size
    return np.array([np.dot(x[: n - k], x[k:]) / n for k in range(maxlag + 1)])


def _burg(x: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Plain numpy Burg with the library's sign convention (x_hat = sum a_j x_{i-j})."""
    y = x - x.mean()
    f, b = y[1:].copy(), y[:-1].copy()
    a = np.zeros(0)
    refl = np.zeros(p)
    err = np.dot(y, y) / y.size
    for m in range(p):
        k = 2 * np.dot(f, b) / (np.dot(f, f) + np.dot(b, b))
        a = np.r_[a - k * a[::-1], k]
        refl[m] = k
        err *= 1 - k * k
        f, b = f[1:] - k * b[1:], b[:-1] - k * f[:-1]
    return a, refl, err


def test_autocorr_and_yule_walker_match_solve_toeplitz(x4: np.ndarray) -> None:
    r = ar.autocorr(x4, 10)
    np.testing.assert_allclose(r, _acf(x4, 10), rtol=1e-12)
    for p in (4, 12, 40):
        m = ar.yule_walker(x4, p)
        rc = _acf(x4 - x4.mean(), p)
        want = linalg.solve_toeplitz(rc[:p], rc[1 : p + 1])
        assert m.order == p and m.n == x4.size
        assert m.mean == pytest.approx(x4.mean(), rel=1e-14)
        np.testing.assert_allclose(m.a, want, rtol=0, atol=1e-9 * np.abs(want).max())
        assert m.sigma2 == pytest.approx(rc[0] - np.dot(want, rc[1 : p + 1]), rel=1e-9)
    m4 = ar.yule_walker(x4, 4)
    np.testing.assert_allclose(m4.a, A4, atol=0.03)  # recovers the true process
    assert m4.sigma2 == pytest.approx(1.0, rel=0.05)


def test_burg_matches_numpy_burg(x4: np.ndarray) -> None:
    for p in (4, 30):
        m = ar.burg(x4, p)
        a, refl, err = _burg(x4, p)
        np.testing.assert_allclose(m.a, a, rtol=0, atol=1e-9 * np.abs(a).max())
        np.testing.assert_allclose(m.refl, refl, rtol=1e-9, atol=1e-12)
        assert m.sigma2 == pytest.approx(err, rel=1e-9)


def test_order_selection_picks_true_order(x4: np.ndarray) -> None:
    for method in ("yule_walker", "burg"):
        o = ar.select_order(x4, 20, method)  # type: ignore[arg-type]
        assert o.pmax == 20 and o.n == x4.size
        assert o.p_aic == 4
        assert o.band == pytest.approx(2 / np.sqrt(x4.size), rel=1e-14)
        assert abs(o.pacf[3]) >= o.band and o.p_pacf >= 4
        np.testing.assert_allclose(o.aic, x4.size * np.log(o.sigma2) + 2 * np.arange(1, 21),
                                   rtol=1e-12)
        m = ar.fit(x4, 20, method)  # type: ignore[arg-type]
        np.testing.assert_array_equal(o.pacf, m.refl)  # one recursion: the same numbers
        assert o.sigma2[-1] == m.sigma2


def test_arx_matches_lstsq(arx_data: tuple[np.ndarray, np.ndarray]) -> None:
    x, f = arx_data
    for na, nb, nk in ((2, 2, 1), (4, 3, 1), (3, 4, 0)):
        m = ar.arx_fit(x, f, na, nb, nk)
        i0 = max(na, nk + nb - 1)
        rows = np.array([np.r_[x[i - na : i][::-1], f[i - nk - nb + 1 : i - nk + 1][::-1]]
                         for i in range(i0, x.size)])
        th, *_ = np.linalg.lstsq(rows, x[i0:], rcond=None)
        np.testing.assert_allclose(np.r_[m.alpha, m.beta], th, rtol=1e-9, atol=1e-12)
        rss = np.sum((x[i0:] - rows @ th) ** 2)
        assert m.n_rows == x.size - i0
        assert m.sigma2 == pytest.approx(rss / m.n_rows, rel=1e-9)
        assert 0 < m.rcond <= 1
        e = ar.arx_residual(m, x, f)
        np.testing.assert_allclose(e, x[i0:] - rows @ th, atol=1e-9)
    m = ar.arx_fit(x, f, 2, 2, 1)
    np.testing.assert_allclose(np.r_[m.alpha, m.beta], [1.6, -0.8, 0.5, -0.2], atol=0.01)


def test_ararx_matches_two_stage_lstsq(x4: np.ndarray) -> None:
    p, na, nb = 12, 2, 2
    m, a1 = ar.ararx_fit(x4, p, na, nb, 0)
    assert np.array_equal(a1.a, ar.yule_walker(x4, p).a)
    xc = x4 - a1.mean
    e = signal.lfilter(np.r_[1.0, -a1.a], [1.0], xc)[p:]  # stage-1 residual, i >= p
    y = xc[p:]
    i0 = max(na, nb - 1)
    rows = np.array([np.r_[y[i - na : i][::-1], e[i - nb + 1 : i + 1][::-1]]
                     for i in range(i0, y.size)])
    th, *_ = np.linalg.lstsq(rows, y[i0:], rcond=None)
    np.testing.assert_allclose(np.r_[m.alpha, m.beta], th, rtol=1e-7, atol=1e-9)
    with pytest.raises(CoreError, match="DV_EINVAL"):
        ar.ararx_fit(x4, 3, 2, 2)  # p < na + nb


def test_ar_residual_matches_definition(x4: np.ndarray) -> None:
    m = ar.burg(x4, 8)
    want = signal.lfilter(np.r_[1.0, -m.a], [1.0], x4 - m.mean)[8:]
    eb = ar.ar_residual(m, x4)
    es = ar.ar_residual(m, x4, per_sample=True)
    assert eb.size == es.size == x4.size - 8
    np.testing.assert_allclose(eb, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(es, want, rtol=0, atol=1e-12)
    # whiteness of the residual of a pure AR process: Ljung-Box at 20 lags
    e = es - es.mean()
    rho = _acf(e, 20)[1:] / np.dot(e, e) * e.size
    q = e.size * (e.size + 2) * np.sum(rho**2 / (e.size - np.arange(1, 21)))
    assert stats.chi2.sf(q, 20 - 8) > 0.001
    # streaming in chunks is the same stream; NaN dropped and counted
    r = ar.ARResidual(m)
    y = x4.copy()
    y[[100, 5000]] = np.nan
    parts = [r.update(y[:3000]), r.update(y[3000:])]
    assert r.nonfinite == 2
    ok = np.isfinite(y)
    want2 = signal.lfilter(np.r_[1.0, -m.a], [1.0], y[ok] - m.mean)[8:]
    np.testing.assert_allclose(np.concatenate(parts), want2, atol=1e-12)


def test_residual_stats_find_spikes(x4: np.ndarray) -> None:
    y = x4.copy()
    spikes = [1500, 4000, 6100]
    y[spikes] += 12.0
    m = ar.yule_walker(x4, 4)
    e = ar.ar_residual(m, y)
    rs = ar.residual_stats(e, 5.0)
    hits = set(rs.indices.tolist())
    for s in spikes:
        assert s - 4 in hits  # residual index = sample index - order
    # a spike also enters the next `order` predictions: every outlier lies in those spans
    assert all(any(0 <= i - (s - 4) <= 4 for s in spikes) for i in hits)
    assert rs.indices.dtype == np.uint32 and rs.sizes.size == rs.indices.size
    assert rs.rec.rms == pytest.approx(np.sqrt(np.mean(e * e)), rel=1e-12)
    assert rs.rec.skew == pytest.approx(stats.skew(e), rel=1e-9)
    assert rs.rec.kurt == pytest.approx(stats.kurtosis(e, fisher=False), rel=1e-9)
    d = (e - e.mean()) / e.std()
    np.testing.assert_allclose(rs.sizes, d[rs.indices], rtol=1e-12)
    assert np.all(np.abs(rs.sizes) > 5.0) and rs.n_overflow == 0 and rs.win is None
    few = ar.residual_stats(e, 5.0, capacity=1)
    assert few.indices.size == 1 and few.n_overflow == rs.n_outliers - 1
    mon = ar.ResidualMonitor(5.0, 512)
    assert mon.update(e) >= len(spikes)
    ms = mon.get()
    assert {s - 4 for s in spikes} <= set(ms.indices.tolist())
    assert ms.win is not None and ms.win.count == 512


def test_errors_are_core_errors(x4: np.ndarray) -> None:
    with pytest.raises(CoreError, match="DV_ENUMERIC"):
        ar.yule_walker(np.full(1000, 3.0), 4)  # constant record
    bad = x4.copy()
    bad[7] = np.nan
    with pytest.raises(CoreError, match="DV_ENUMERIC"):
        ar.burg(bad, 4)
    with pytest.raises(CoreError, match="DV_EINVAL"):
        ar.fit(x4[:5], 5)  # p >= n
    with pytest.raises(CoreError, match="DV_EINVAL"):
        ar.fit(x4, ar.MAX_ORDER + 1)
    with pytest.raises(ValueError):
        ar.fit(x4, 4, "ols")  # type: ignore[arg-type]
    with pytest.raises(CoreError, match="DV_ENUMERIC"):
        ar.arx_fit(x4, np.full_like(x4, 3.0), 2, 2, 1)  # singular: identical input columns
    with pytest.raises(CoreError, match="DV_ENOTREADY"):
        ar.residual_stats(np.ones(100))


def _hex(v: str) -> float:
    return float.fromhex(v)


def test_binding_is_bit_identical_to_c(arx_data: tuple[np.ndarray, np.ndarray], tmp_path: Path,
                                       ar_dump: Path) -> None:
    x, f = arx_data
    x = x + 1.5
    x[[1000, 2500]] += 3.0
    fx, ff = tmp_path / "x.txt", tmp_path / "f.txt"
    np.savetxt(fx, x, fmt="%.17g")
    np.savetxt(ff, f, fmt="%.17g")
    x, f = np.loadtxt(fx), np.loadtxt(ff)
    p, pmax, na, nb, nk, ks, win = 8, 20, 4, 3, 1, 4.0, 256
    out = subprocess.run([str(ar_dump), str(fx), str(ff), str(p), str(pmax), str(na), str(nb),
                          str(nk), str(ks), str(win)], capture_output=True, text=True,
                         check=True).stdout
    ref = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines()}
    assert "status" not in " ".join(v[0] for v in ref.values() if v)

    def vec(name: str) -> list[float]:
        return [_hex(v) for v in ref[name]]

    def model(m: ar.ARModel) -> list[float]:
        return [float(m.order), m.mean, m.sigma2, *m.a.tolist(), *m.refl.tolist()]

    def arx(m: ar.ARXModel) -> list[float]:
        return [float(m.n_rows), m.sigma2, m.rcond, *m.alpha.tolist(), *m.beta.tolist()]

    def parse_model(name: str) -> list[float]:
        v = ref[name]
        return [float(int(v[0])), *[_hex(s) for s in v[1:]]]

    assert vec("autocorr") == ar.autocorr(x, pmax).tolist()
    ms = {}
    for key, meth in (("yw", "yule_walker"), ("burg", "burg")):
        ms[key] = ar.fit(x, p, meth)  # type: ignore[arg-type]
        assert parse_model(f"fit_{key}") == model(ms[key])
        o = ar.select_order(x, pmax, meth)  # type: ignore[arg-type]
        hdr = ref[f"order_{key}"]
        assert [int(hdr[0]), int(hdr[1]), int(hdr[2]), _hex(hdr[3])] == \
            [o.pmax, o.p_aic, o.p_pacf, o.band]
        assert vec(f"aic_{key}") == o.aic.tolist()
        assert vec(f"pacf_{key}") == o.pacf.tolist()
        assert vec(f"sigma2_{key}") == o.sigma2.tolist()
    es = ar.ar_residual(ms["yw"], x, per_sample=True)
    eb = ar.ar_residual(ms["yw"], x)
    assert vec("resid_sample") == es.tolist()
    assert vec("resid_block") == eb.tolist()

    def st(name: str, rs: ar.ResidualStats) -> None:
        v = ref[name]
        assert [_hex(s) for s in v[:5]] == [rs.rec.mean, rs.rec.std, rs.rec.rms, rs.rec.skew,
                                            rs.rec.kurt]
        assert [int(v[5]), int(v[6])] == [rs.n_outliers, rs.n_nonfinite]
        pairs = [s.split(":") for s in v[7:]]
        assert [int(i) for i, _ in pairs] == rs.indices.tolist()
        assert [_hex(z) for _, z in pairs] == rs.sizes.tolist()

    st("stats_record", ar.residual_stats(eb, ks))
    mon = ar.ResidualMonitor(ks, win)
    mon.update(eb)
    st("stats_stream", mon.get())
    am = ar.arx_fit(x, f, na, nb, nk)
    assert parse_model("arx") == arx(am)
    assert vec("arx_resid") == ar.arx_residual(am, x, f).tolist()
    m2, a1 = ar.ararx_fit(x, p, na, nb, 0)
    assert parse_model("ararx") == arx(m2)
    assert parse_model("ararx_ar") == model(a1)
