"""Residuals of a model against a recorded test: measured - predicted per output channel, with
RMSE and NRMSE."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval.errors import ConfigError
from dynval.io.recording import Recording
from dynval.model.schema import Model
from dynval.model.simulation import simulate

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ChannelResidual:
    """measured - predicted of one channel; rmse over its n_used finite samples (a measured
    NaN a lenient reader kept is left out, and counted); nrmse = rmse / rms of the measured
    channel (NaN when that is 0)."""

    residual: np.ndarray
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
    predicted: dict[str, np.ndarray]

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
    return simulate(m, rec.channel(input_channel(m, rec)).data, rec.fs_hz, oversample=oversample)


def residual(m: Model, rec: Recording, *, oversample: int | None = None) -> ResidualResult:
    """measured - predicted for every model output the recording also has, with RMSE and
    NRMSE (RMSE / RMS of the measured channel)."""
    common = [c for c in m.outputs if c in rec.names]
    if not common:
        raise ConfigError(f"{rec.source or rec.name}: none of the model's outputs "
                          f"({', '.join(m.outputs)}) is a column of the test "
                          f"({', '.join(rec.names)})")
    missing = [c for c in m.outputs if c not in rec.names]
    if missing:
        log.info("%s: the test lacks the model outputs %s", rec.name, ", ".join(missing))
    pred = simulate_recording(m, rec, oversample=oversample)
    chans: dict[str, ChannelResidual] = {}
    for c in common:
        y = rec.channel(c).data
        e = y - pred[c]
        ok = np.isfinite(e)
        rmse = float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else math.nan
        rms = float(np.sqrt(np.mean(y[ok] ** 2))) if ok.any() else math.nan
        chans[c] = ChannelResidual(e, rmse, rmse / rms if rms > 0 else math.nan, rms,
                                   int(ok.sum()))
    return ResidualResult(rec.name, rec.fs_hz, rec.n_samples, chans, pred)
