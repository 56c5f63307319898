"""The binding's features: independent numpy/scipy references, closed forms, and bit-for-bit
equality with the C library's own results (tests/tools/dv_features_dump.c)."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy import signal, stats

from dynval import features
from dynval.errors import CoreError


@pytest.fixture
def x() -> np.ndarray:
    rng = np.random.default_rng(7)
    b, a = signal.butter(4, [20, 200], btype="bandpass", fs=640)
    return signal.lfilter(b, a, rng.standard_normal(8192)) * 3 + 0.5 + rng.gamma(2, 0.3, 8192)


def test_moments_match_scipy(x: np.ndarray) -> None:
    st = features.moments(x)
    assert st.count == x.size
    assert st.mean == pytest.approx(np.mean(x), rel=1e-12)
    assert st.std == pytest.approx(np.std(x), rel=1e-12)
    assert st.rms == pytest.approx(np.sqrt(np.mean(x * x)), rel=1e-12)
    assert st.skew == pytest.approx(stats.skew(x), rel=1e-10)
    assert st.kurt == pytest.approx(stats.kurtosis(x, fisher=False), rel=1e-10)
    assert st.peak == np.max(np.abs(x))
    assert st.crest == pytest.approx(st.peak / st.rms, rel=1e-14)
    assert st.kfactor == pytest.approx(st.peak * st.rms, rel=1e-14)


def test_sine_crest_factor_is_sqrt2() -> None:
    t = np.arange(6400)
    st = features.moments(np.sin(2 * np.pi * t / 64))
    assert st.crest == pytest.approx(math.sqrt(2), rel=1e-9)
    assert st.kurt == pytest.approx(1.5, rel=1e-9)


def test_sliding_is_the_last_window(x: np.ndarray) -> None:
    st = features.sliding(x, 256)
    w = x[-256:]
    assert st.std == pytest.approx(np.std(w), rel=1e-10)
    assert st.max == np.max(w) and st.min == np.min(w)
    ser = features.sliding_series(x[:1024], 256, every=64)
    assert np.isnan(ser["rms"][:3]).all()
    assert ser["rms"][3] == pytest.approx(np.sqrt(np.mean(x[:256] ** 2)), rel=1e-10)
    assert ser["rms"][-1] == pytest.approx(np.sqrt(np.mean(x[768:1024] ** 2)), rel=1e-10)


def test_segstd_and_temporal_match_numpy(x: np.ndarray) -> None:
    seg = features.segstd(x[:4096], 64, 64)
    np.testing.assert_allclose(seg, x[:4096].reshape(64, 64).std(axis=1), rtol=1e-10)
    dt = 1 / 640
    tm = features.temporal(x, dt)
    w = x * x
    t = np.arange(x.size) * dt
    tc = np.sum(w * t) / np.sum(w)
    assert tm.energy == pytest.approx(np.sum(w) * dt, rel=1e-12)
    assert tm.central_time == pytest.approx(tc, rel=1e-12)
    d = np.sqrt(np.sum(w * (t - tc) ** 2) / np.sum(w))
    assert tm.rms_duration == pytest.approx(d, rel=1e-10)


def test_corr_matches_numpy(x: np.ndarray) -> None:
    y = np.roll(x, 5) + 0.3 * x
    assert features.corr(x, y) == pytest.approx(np.corrcoef(x, y)[0, 1], rel=1e-10)
    with pytest.raises(CoreError, match="DV_ENUMERIC"):
        features.corr(x, np.ones_like(x))


def test_channel_records_like_firmware(x: np.ndarray) -> None:
    recs, bad = features.channel_records(x, 640.0, 256, 64, 64)
    assert bad == 0 and len(recs) == 2
    r1 = recs[1]
    seg = x[4096:8192]
    assert r1.stats.std == pytest.approx(np.std(seg), rel=1e-10)
    np.testing.assert_allclose(r1.segstd, seg.reshape(64, 64).std(axis=1), rtol=1e-10)
    assert r1.window is not None and r1.window.std == pytest.approx(np.std(seg[-256:]), rel=1e-10)
    y = x.copy()
    y[[10, 5000]] = np.nan
    recs, bad = features.channel_records(y, 640.0)
    assert bad == 2 and len(recs) == 1  # NaNs dropped and counted: the second record is short


def test_binding_is_bit_identical_to_c(x: np.ndarray, tmp_path: Path, features_dump: Path) -> None:
    f = tmp_path / "x.txt"
    np.savetxt(f, x, fmt="%.17g")
    x = np.loadtxt(f)
    out = subprocess.run([str(features_dump), str(f), "640", "256", "64"], capture_output=True,
                         text=True, check=True).stdout
    ref = {ln.split()[0]: [float.fromhex(v) for v in ln.split()[1:]] for ln in out.splitlines()}
    st = features.moments(x)
    assert ref["moments"] == [st.mean, st.std, st.rms, st.skew, st.kurt, st.peak, st.crest]
    sl = features.sliding(x, 256)
    assert ref["sliding"] == [sl.mean, sl.std, sl.rms, sl.peak, sl.crest]
    tm = features.temporal(x, 1 / 640)
    assert ref["temporal"] == [tm.energy, tm.central_time, tm.rms_duration, tm.central_skew,
                               tm.central_kurt]
    assert ref["segstd"] == features.segstd(x, 64).tolist()


def test_segstd_in_numpy_is_the_cores_arithmetic(x: np.ndarray) -> None:
    from dynval._core import check as core_check
    from dynval._core import ffi, lib, ptr

    y = np.concatenate([x, x[:1000] * 3 + 7])
    y[[10, 3000]] = np.nan  # dropped, as the core drops them
    for seg_len, n_seg in ((64, None), (64, 16), (100, 7), (2, 5)):
        n = np.isfinite(y).sum() // seg_len if n_seg is None else n_seg
        s = ffi.new("dv_segstd_t *")
        buf = ffi.new("double[]", 2 * n)
        core_check(lib.dv_segstd_init(s, seg_len, n, buf, 2 * n), "dv_segstd_init")
        for v in y.tolist():
            lib.dv_segstd_update(s, v)
        ref = np.empty(n)
        core_check(lib.dv_segstd_get(s, ptr(ref), n), "dv_segstd_get")
        assert np.array_equal(features.segstd(y, seg_len, n_seg), ref)


def test_features_refuse_a_2d_array(x: np.ndarray) -> None:
    with pytest.raises(ValueError, match=r"one channel .* shape \(2, 512\)"):
        features.moments(x[:1024].reshape(2, 512))
    with pytest.raises(ValueError, match="apply_along_axis"):
        features.segstd(x[:1024].reshape(512, 2))
    assert features.moments(x[:512].reshape(512, 1)).count == 512  # one column is one channel
