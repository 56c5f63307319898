"""Issue 21, long records: the simulation and the residuals run block by block (the state
carried across blocks, the input interpolated per block, the sums of squares added exactly) and
give the whole record's numbers, so a memory-mapped hour-long record needs memory for a block."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from dynval import model as mdl
from dynval.io import Channel, Recording, arrays, read_test

MODEL = mdl.Model(masses_kg=(6.54, 6.66, 6.86, 6.80), stiffness_n_per_m=(10.0, 4e5, 4e5, 4e5),
                  damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01)),
                  input=mdl.Input("force", 1, "force_N"),
                  outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)},
                  fs_hz=640.0)
BUMPER = mdl.Contact(3, 4, gap_m=1e-5, delta_m=1e-4, kb_n_per_m=1.9e6, name="bumper")
N = 20_011  # five blocks of 4096 and a short one


def _force(n: int = N) -> np.ndarray:
    rng = np.random.default_rng(3)
    b, a = signal.butter(4, [20, 200], btype="bandpass", fs=640)
    return np.asarray(12 * signal.lfilter(b, a, rng.standard_normal(n)))


def _one_run(m: mdl.Model, u: np.ndarray, r: int) -> np.ndarray:
    """The whole record in one dv_obs_simulate call, the input interpolated in one piece."""
    fine = u if r == 1 else signal.resample_poly(np.r_[u, np.zeros(32)], r, 1,
                                                 window=("kaiser", 12.0))[: u.size * r]
    core = mdl._Core(m, 1.0 / (640.0 * r))
    core.build(m, refill=False)
    y = np.empty((fine.size, core.no))
    core.run(np.ascontiguousarray(fine), y)
    return y[::r]


CUBIC = dataclasses.replace(MODEL, interpolation="cubic")


@pytest.mark.parametrize("m, r", [(MODEL, 4), (dataclasses.replace(MODEL, elements=(BUMPER,)), 4),
                                  (dataclasses.replace(MODEL, interpolation="foh"), 1),
                                  (CUBIC, 1), (dataclasses.replace(CUBIC, oversample=4), 4),
                                  (dataclasses.replace(CUBIC, elements=(BUMPER,)), 1)])
def test_blocks_are_the_whole_record_bit_for_bit(m: mdl.Model, r: int) -> None:
    """The cubic hold's core runs a sample late: its blocks are realigned."""
    u = _force()
    want = _one_run(m, u, r)
    for src in (u, mdl.prepare_input(m, u, oversample=r)):
        got = list(mdl.simulate_blocks(m, src, 640.0, oversample=r, block=4096))
        assert [a for a, _ in got] == list(range(0, N, 4096))
        assert np.array_equal(np.concatenate([y for _, y in got]), want)
    assert float(np.std(want[:, 3])) > 1.0  # a real response (m/s^2), not zeros


@pytest.mark.parametrize("once_bytes", [64 << 20, 0])
def test_batch_in_blocks_is_one_run_per_set(monkeypatch: pytest.MonkeyPatch,
                                            once_bytes: int) -> None:
    """simulate_batch runs each set in blocks of simulate's BLOCK samples (two here), the
    input interpolated once or (a long record: 0 bytes here) per block for each set."""
    monkeypatch.setattr(mdl.simulation, "INTERPOLATE_ONCE_BYTES", once_bytes)
    u = _force(70_000)
    sets = [{"k2": 3.9e5}, {"zeta2": 0.02, "e1.gap_m": 2e-5}]
    for m, r in ((dataclasses.replace(MODEL, elements=(BUMPER,)), 4),
                 (dataclasses.replace(CUBIC, elements=(BUMPER,)), 1),
                 (dataclasses.replace(CUBIC, elements=(BUMPER,), oversample=4), 4)):
        got = mdl.simulate_batch(m, u, 640.0, sets, oversample=r)
        for i, ps in enumerate(sets):
            assert np.array_equal(got[i], _one_run(m.with_params(ps), u, r)), (m, r, i)
        assert not np.array_equal(got[0], got[1])


def test_non_finite_input_held_across_blocks(caplog: pytest.LogCaptureFixture) -> None:
    m = dataclasses.replace(MODEL, interpolation="foh")
    u = _force()
    u[[100, 4095, 4096, 9000]] = np.nan  # at a block's end and the next one's start
    got = np.concatenate([y for _, y in mdl.simulate_blocks(m, u, 640.0, block=4096)])
    assert np.array_equal(got, _one_run(m, u, 1))
    assert "4 non-finite input samples" in caplog.text


def _recording(tmp_path: Path) -> tuple[Recording, Path]:
    """The model's response with 1 % white noise on each channel, one measured NaN; also as
    an HDF5 file (read memory-mapped)."""
    import h5py

    u = _force()
    clean = mdl.simulate(MODEL, u, 640.0)
    rng = np.random.default_rng(5)
    chans = [Channel("force_N", u, "N", "input")]
    for c, y in clean.items():
        chans.append(Channel(c, y + 0.01 * np.std(y) * rng.standard_normal(N), "m/s^2"))
    chans[2].data[7777] = np.nan
    p = tmp_path / "t.h5"
    with h5py.File(p, "w") as f:
        f.attrs["fs_hz"] = 640.0
        for ch in chans:
            f[ch.name] = ch.data
    return Recording("t", 640.0, chans), p


def test_residual_in_blocks_equals_the_whole_record(tmp_path: Path) -> None:
    rec, h5 = _recording(tmp_path)
    whole = mdl.residual(MODEL, rec)  # one block (the default is longer than the record)
    blocks = mdl.residual(MODEL, rec, block=4096)
    mapped = read_test(h5, lenient=True)
    assert arrays.mapped(mapped.channel("acc1_mps2").data)
    streamed = mdl.residual(MODEL, mapped, block=8192, keep=False)
    assert blocks.predicted is not None and whole.predicted is not None
    for c, w in whole.channels.items():
        b = blocks.channels[c]
        assert np.array_equal(b.residual, w.residual, equal_nan=True)  # type: ignore[arg-type]
        assert (b.rmse, b.nrmse, b.n_used) == (w.rmse, w.nrmse, w.n_used)
        assert np.array_equal(blocks.predicted[c], whole.predicted[c])
        s = streamed.channels[c]
        assert (s.rmse, s.nrmse, s.rms_measured, s.n_used) == (w.rmse, w.nrmse,
                                                                w.rms_measured, w.n_used)
        e = rec.channel(c).data - whole.predicted[c]
        ok = np.isfinite(e)
        # numpy's mean adds in another order: the same to rounding
        assert w.rmse == pytest.approx(math.sqrt(np.mean(e[ok] ** 2)), rel=1e-13)
        assert w.nrmse == pytest.approx(0.01, rel=0.05)  # the 1 % noise added
        assert w.n_used == N - (c == "acc2_mps2")
    assert streamed.predicted is None and streamed.channels["acc1_mps2"].residual is None
