"""Residuals of a model against a recorded test: measured - predicted per output channel, with
RMSE and NRMSE."""
from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError, InputFileError
from dynval.io.recording import Recording
from dynval.model.schema import Model
from dynval.model.simulation import BLOCK, simulate, simulate_blocks

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ChannelResidual:
    """measured - predicted of one channel (None when not kept); rmse over its n_used finite
    samples (a measured NaN a lenient reader kept is left out, and counted); nrmse = rmse / rms
    of the measured channel (NaN when that is 0)."""

    residual: np.ndarray | None
    rmse: float
    nrmse: float
    rms_measured: float
    n_used: int = 0


@dataclass(frozen=True)
class ResidualResult:
    test: str
    fs_hz: float
    n_samples: int
    channels: dict[str, ChannelResidual]
    predicted: dict[str, np.ndarray] | None

    def summary(self) -> dict[str, Any]:
        return {"test": self.test, "fs_hz": self.fs_hz, "n_samples": self.n_samples,
                "channels": {k: {"rmse": c.rmse, "nrmse": c.nrmse, "rms_measured": c.rms_measured,
                                 "n_used": c.n_used} for k, c in self.channels.items()}}


def input_channel(m: Model, rec: Recording) -> str:
    """The recording's column that drives the model."""
    if m.input.channel is not None:
        if m.input.channel not in rec.names:
            raise ConfigError(f"{rec.source or rec.name}: no input column '{m.input.channel}' "
                              f"required by the model {m.source} (columns: "
                              f"{', '.join(rec.names)})")
        return m.input.channel
    ins = [c.name for c in rec.channels if c.role == "input"]
    if len(ins) != 1:
        raise ConfigError(f"{rec.source or rec.name}: cannot tell the input column (candidates: "
                          f"{', '.join(ins) or 'none'}); name it in the model's input.channel")
    return ins[0]


def _check_fs(m: Model, rec: Recording) -> None:
    if m.fs_hz is not None and abs(m.fs_hz - rec.fs_hz) > 1e-6 * m.fs_hz:
        log.warning("%s: sampled at %g Hz, the model %s declares %g Hz; simulating at the "
                    "test's rate", rec.name, rec.fs_hz, m.source, m.fs_hz)


def simulate_recording(m: Model, rec: Recording, *,
                       oversample: int | None = None) -> dict[str, np.ndarray]:
    """The model's prediction for a recorded test's measured input."""
    _check_fs(m, rec)
    with _named(rec):
        return simulate(m, rec.channel(input_channel(m, rec)).data, rec.fs_hz,
                        oversample=oversample)


@contextlib.contextmanager
def _named(rec: Recording) -> Iterator[None]:
    """The simulation's refusal of this record's input (ConfigError) named by its file."""
    try:
        yield
    except ConfigError as exc:
        raise ConfigError(f"{rec.source or rec.name}: {exc}") from None


# samples per partial sum of squares: the sums of whole chunks are added exactly (math.fsum),
# so the RMSE does not depend on how the record is split into blocks (a multiple of this)
_CHUNK = 4096


def residual(m: Model, rec: Recording, *, oversample: int | None = None, keep: bool = True,
             block: int = BLOCK) -> ResidualResult:
    """measured - predicted for every model output the recording also has, with RMSE and
    NRMSE (RMSE / RMS of the measured channel). Simulated and summed in blocks of `block`
    samples (a multiple of _CHUNK): keep=False holds no series, so a long (memory-mapped)
    record needs memory for a block only (a nonlinear model with a DAQ filter: for the whole
    record, model/daq.py); the results do not depend on the block."""
    common = [c for c in m.outputs if c in rec.names]
    if not common:
        raise ConfigError(f"{rec.source or rec.name}: none of the model's outputs "
                          f"({', '.join(m.outputs)}) is a column of the test "
                          f"({', '.join(rec.names)})")
    missing = [c for c in m.outputs if c not in rec.names]
    if missing:
        log.info("%s: the test lacks the model outputs %s", rec.name, ", ".join(missing))
    if block % _CHUNK:
        raise ValueError(f"block {block} is not a multiple of {_CHUNK}")
    _check_fs(m, rec)
    n = rec.n_samples
    col = {c: j for j, c in enumerate(m.outputs)}
    pred = {c: np.empty(n) for c in m.outputs} if keep else None
    resid = {c: np.empty(n) for c in common} if keep else None
    sums: dict[str, list[list[float]]] = {c: [[], []] for c in common}  # e^2, y^2 per chunk
    used = dict.fromkeys(common, 0)
    u = rec.channel(input_channel(m, rec)).data
    with _named(rec):
        for a, yp in simulate_blocks(m, u, rec.fs_hz, oversample=oversample, block=block):
            b = a + yp.shape[0]
            if pred is not None:
                for c, arr in pred.items():
                    arr[a:b] = yp[:, col[c]]
            for c in common:
                y = np.asarray(rec.channel(c).data[a:b], dtype=np.float64)
                e = y - yp[:, col[c]]
                if resid is not None:
                    resid[c][a:b] = e
                ok = np.isfinite(e)
                used[c] += int(ok.sum())
                with np.errstate(over="ignore"):  # an overflowed square is refused below
                    sums[c][0] += _chunk_sums(np.where(ok, e, 0.0))
                    sums[c][1] += _chunk_sums(np.where(ok, y, 0.0))
    chans: dict[str, ChannelResidual] = {}
    for c in common:
        k = used[c]
        rmse = math.sqrt(math.fsum(sums[c][0]) / k) if k else math.nan
        rms = math.sqrt(math.fsum(sums[c][1]) / k) if k else math.nan
        if k and not (math.isfinite(rmse) and math.isfinite(rms)):
            raise _overflowed(rec, c)
        chans[c] = ChannelResidual(None if resid is None else resid[c], rmse,
                                   rmse / rms if rms > 0 else math.nan, rms, k)
    return ResidualResult(rec.name, rec.fs_hz, n, chans, pred)


def _overflowed(rec: Recording, c: str) -> InputFileError:
    """The error for a channel whose squares overflow (a sample near the real type's range:
    a saturated or mis-scaled sensor), naming its largest sample."""
    y = np.asarray(rec.channel(c).data, dtype=np.float64)
    big = np.where(np.isfinite(y), np.abs(y), 0.0)
    i = int(np.argmax(big))
    return InputFileError(rec.source or rec.name, f"channel {c}: sample {i} is {y[i]:.3g}: its "
                          "square overflows the RMSE; rescale the channel (channel map "
                          "'scale')")


def _chunk_sums(x: np.ndarray) -> list[float]:
    """Sums of squares of x's _CHUNK-sample chunks (the last one may be shorter)."""
    full = x.size - x.size % _CHUNK
    out: list[float] = (x[:full].reshape(-1, _CHUNK) ** 2).sum(axis=1).tolist()
    if full < x.size:
        out.append(float(np.sum(x[full:] ** 2)))
    return out
