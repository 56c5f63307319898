"""Designs of experiments over named model parameters and parallel simulation sweeps.

Parameters are Model.with_params names (m<i>, k<i>, zeta<i>, alpha, beta, e<i>.gap_m,
e<i>.delta_m, e<i>.kb_n_per_m) with a uniform range ``NAME=LO:HI``. A sweep runs
model.simulate_batch (the C model and observer) for every parameter set and every driving
force of the job, extracts the feature vector of each run and the RMSE (eq. 47) of chosen
channels against the measured record of the first force. Chunks of runs go to a
concurrent.futures.ProcessPoolExecutor over all cores, or to a Dask distributed cluster
(``scheduler=ADDRESS``); only features and RMSE travel back, not time histories.
"""
from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import importlib
import itertools
import logging
import math
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.errors import ConfigError
from dynval.validate import measurement as meas
from dynval.validate.featvec import FeatureSet

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class ParamRange:
    name: str
    lo: float
    hi: float

    def scale(self, u: np.ndarray) -> np.ndarray:
        return np.asarray(self.lo + (self.hi - self.lo) * np.asarray(u))

    def unit(self, v: np.ndarray) -> np.ndarray:
        return np.asarray((np.asarray(v) - self.lo) / (self.hi - self.lo))


def parse_param(text: str) -> ParamRange:
    """'zeta2=0.01:0.08' -> ParamRange."""
    try:
        name, rng = text.split("=", 1)
        lo_s, hi_s = rng.split(":", 1)
        lo, hi = float(lo_s), float(hi_s)
    except ValueError:
        raise ConfigError(f"--param '{text}': expected NAME=LO:HI, e.g. zeta2=0.01:0.08") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ConfigError(f"--param '{text}': need finite LO < HI")
    return ParamRange(name.strip(), lo, hi)


def check_params(m: mdl.Model, ranges: Sequence[ParamRange]) -> None:
    """Every name must be a parameter of the model (ConfigError lists the known ones)."""
    if not ranges:
        raise ConfigError("no parameters to vary (--param NAME=LO:HI)")
    known = m.parameters()
    for r in ranges:
        if r.name not in known:
            raise ConfigError(f"unknown model parameter '{r.name}' (known: {', '.join(known)})")
    names = [r.name for r in ranges]
    if len(set(names)) != len(names):
        raise ConfigError(f"a parameter is named twice: {', '.join(names)}")


def latin_hypercube(ranges: Sequence[ParamRange], n: int, seed: int = 0) -> np.ndarray:
    """n x k Latin hypercube sample (scipy.stats.qmc.LatinHypercube) scaled to the ranges."""
    qmc = importlib.import_module("scipy.stats.qmc")
    u = qmc.LatinHypercube(d=len(ranges), seed=seed).random(n)
    return np.column_stack([r.scale(u[:, j]) for j, r in enumerate(ranges)])


def full_factorial(ranges: Sequence[ParamRange], levels: int = 3) -> np.ndarray:
    """levels^k x k full factorial (lower, ..., upper evenly spaced; Table 18 for 3 levels)."""
    if levels < 2:
        raise ConfigError("a full factorial needs at least 2 levels")
    grids = [np.linspace(r.lo, r.hi, levels) for r in ranges]
    return np.array(list(itertools.product(*grids)), dtype=np.float64)


def design(kind: str, ranges: Sequence[ParamRange], runs: int, seed: int = 0,
           levels: int = 3) -> np.ndarray:
    if kind == "lhs":
        return latin_hypercube(ranges, runs, seed)
    if kind == "factorial":
        return full_factorial(ranges, levels)
    raise ConfigError(f"unknown design '{kind}' (lhs, factorial)")


def as_sets(ranges: Sequence[ParamRange], x: np.ndarray) -> list[dict[str, float]]:
    return [{r.name: float(v) for r, v in zip(ranges, row, strict=True)} for row in x]


# ---------------------------------------------------------------------------------------------
# Sweeps
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SweepJob:
    """What every run of a sweep shares: the model (outputs cut to the channels needed), the
    driving forces, the feature set and the RMSE references (records of forces[0]'s test)."""

    model: mdl.Model
    forces: tuple[np.ndarray, ...]
    fs_hz: float
    features: FeatureSet
    oversample: int | None = None
    rmse_channels: tuple[str, ...] = ()
    rmse_refs: tuple[np.ndarray, ...] = ()
    # sensor noise RMS per channel on the features, per force (its test's)
    noise: tuple[tuple[tuple[str, float], ...], ...] = ()
    # per force, its test's number: the noise draw's stream (tests with the same force, a
    # hammer's pulse, must not share one draw: a common draw reads as a bias)
    streams: tuple[int, ...] = ()


def make_job(m: mdl.Model, forces: Sequence[np.ndarray], fs_hz: float, features: FeatureSet,
             *, oversample: int | None = None, rmse_refs: Mapping[str, np.ndarray] | None = None,
             noise: Sequence[Mapping[str, float]] | None = None,
             streams: Sequence[int] | None = None) -> SweepJob:
    """A job whose model predicts only the channels the features and RMSE read (fewer
    outputs: a faster core run), with the validation input hold (measurement.py; oversample
    None: measurement.OVERSAMPLE). rmse_refs: channel -> the measured record that forces[0]
    drove (eq. 47 reference). noise: per force, the sensor noise RMS per channel of its test,
    added before the features (measurement.add_noise: the draw of a force is the one its test
    gets in validation). streams: per force, its test's number (default 0, 1, ...)."""
    if noise is not None and len(noise) != len(forces):
        raise ConfigError(f"sweep: {len(noise)} noise levels for {len(forces)} forces")
    refs = dict(rmse_refs or {})
    need = list(features.channels)
    need += [c for c in refs if c not in need]
    missing = [c for c in need if c not in m.outputs]
    if missing:
        raise ConfigError(f"the model does not predict {', '.join(missing)} (outputs: "
                          f"{', '.join(m.outputs)})")
    cut = meas.predictor(dataclasses.replace(m, outputs={c: m.outputs[c] for c in need}))
    return SweepJob(cut, tuple(np.ascontiguousarray(f, dtype=np.float64) for f in forces),
                    fs_hz, features, meas.OVERSAMPLE if oversample is None else oversample,
                    tuple(refs),
                    tuple(np.ascontiguousarray(v, dtype=np.float64) for v in refs.values()),
                    tuple(tuple(sorted(n.items())) for n in noise or ()),
                    tuple(streams) if streams is not None else tuple(range(len(forces))))


@dataclass
class SweepResult:
    """features: (runs, forces, p); rmse: (runs, channels) eq. 47 per RMSE channel; failed:
    runs the core refused (their rows are NaN)."""

    features: np.ndarray
    rmse: np.ndarray
    failed: list[int]
    ref_rms: tuple[float, ...] = ()

    @property
    def mean_features(self) -> np.ndarray:
        return np.asarray(self.features.mean(axis=1))

    @property
    def score(self) -> np.ndarray:
        """One accuracy number per run: the RMSE (eq. 47) for one channel; for several, the
        root mean square of each channel's RMSE over its measured RMS (normalised RMSE)."""
        if self.rmse.shape[1] == 1:
            return np.asarray(self.rmse[:, 0])
        r = self.rmse / np.asarray(self.ref_rms)
        return np.asarray(np.sqrt(np.mean(r * r, axis=1)))


# samples per partial sum in rmse_eq47 (its temporaries are a chunk, not the record)
_RMSE_CHUNK = 1 << 16


def rmse_eq47(pred: np.ndarray, meas: np.ndarray) -> float:
    """R_k = sqrt(mean((x^N - x^E)^2)) (eq. 47), over finite samples."""
    p, q = np.asarray(pred), np.asarray(meas)
    sums, k = [], 0
    for a in range(0, p.size, _RMSE_CHUNK):
        e = p[a:a + _RMSE_CHUNK] - q[a:a + _RMSE_CHUNK]
        e = e[np.isfinite(e)]
        sums.append(float(e @ e))
        k += e.size
    return math.sqrt(math.fsum(sums) / k) if k else math.nan


# bytes of simulated records one simulate_batch call returns (a long record's sets are run
# one at a time; a test of the usual length runs a whole chunk at once)
BATCH_BYTES = 64 << 20


def _chunk_run(job: SweepJob, sets: list[dict[str, float]]
               ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Simulate and extract one chunk (runs in a worker process)."""
    nf = len(job.features.labels())
    feats = np.full((len(sets), len(job.forces), nf), np.nan)
    rmse = np.full((len(sets), len(job.rmse_channels)), np.nan)
    failed: list[int] = []
    chans = list(job.model.outputs)
    for fi, u in enumerate(job.forces):
        step = max(1, BATCH_BYTES // (u.size * len(chans) * 8))
        for s0 in range(0, len(sets), step):
            ys, ok = _simulate_sets(job, u, sets[s0:s0 + step], s0, failed)
            for i in ok:
                if (~np.isfinite(ys[i - s0]).all(axis=1) & np.isfinite(u)).any():  # diverged
                    if i not in failed:
                        failed.append(i)
                        log.warning("run %s diverged (a prediction that is not finite)",
                                    sets[i])
                    continue
                y = {c: ys[i - s0, :, j] for j, c in enumerate(chans)}
                nz = dict(job.noise[fi]) if job.noise else {}
                stream = job.streams[fi] if job.streams else fi
                feats[i, fi] = job.features.extract(meas.add_noise(y, nz, u, stream),
                                                    job.fs_hz, u)
                if fi == 0:
                    for j, (c, ref) in enumerate(zip(job.rmse_channels, job.rmse_refs,
                                                     strict=True)):
                        rmse[i, j] = rmse_eq47(y[c], ref)
    return feats, rmse, failed


def _chunk_run_mapped(job: SweepJob, files: tuple[tuple[str, ...], tuple[str, ...]],
                      sets: list[dict[str, float]]) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """_chunk_run in a worker process, its forces and RMSE references read from .npy files
    (memory-mapped: the workers share the pages instead of each unpickling a copy)."""
    forces, refs = (tuple(np.load(f, mmap_mode="r") for f in fs) for fs in files)
    return _chunk_run(dataclasses.replace(job, forces=forces, rmse_refs=refs), sets)


def _to_files(job: SweepJob, where: str) -> tuple[SweepJob, tuple[tuple[str, ...],
                                                                  tuple[str, ...]]]:
    """The job without its records, and the .npy files in `where` holding them."""
    names: list[list[str]] = [[], []]
    for kind, arrays in enumerate((job.forces, job.rmse_refs)):
        for i, a in enumerate(arrays):
            names[kind].append(os.path.join(where, f"{kind}_{i}.npy"))
            np.save(names[kind][-1], a)
    return (dataclasses.replace(job, forces=(), rmse_refs=()),
            (tuple(names[0]), tuple(names[1])))


def _simulate_sets(job: SweepJob, u: np.ndarray, sets: list[dict[str, float]], s0: int,
                   failed: list[int]) -> tuple[np.ndarray, list[int]]:
    """The sets (numbered from s0) on the force u: their records and the numbers of those the
    core ran; a set it refuses is logged and added to `failed`."""
    try:
        ys = mdl.simulate_batch(job.model, u, job.fs_hz, sets, oversample=job.oversample)
        return ys, list(range(s0, s0 + len(sets)))
    except ConfigError:  # a set refused: run them one by one, keep the good ones
        pass
    ys = np.full((len(sets), u.size, len(job.model.outputs)), np.nan)
    ok = []
    for i, s in enumerate(sets, start=s0):
        try:
            ys[i - s0] = mdl.simulate_batch(job.model, u, job.fs_hz, [s],
                                            oversample=job.oversample)[0]
            ok.append(i)
        except ConfigError as exc:
            if i not in failed:
                failed.append(i)
                log.warning("run %s refused by the core: %s", s, exc)
    return ys, ok


class Runner:
    """Runs sweep chunks inline (workers=1), on a process pool (default: all cores) or on a
    Dask cluster (scheduler address, or an existing client). A context manager; reusable."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None,
                 client: Any = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self.scheduler = scheduler
        self._client = client
        self._own_client = False
        self._pool: cf.ProcessPoolExecutor | None = None

    def __enter__(self) -> Runner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if self._client is not None and self._own_client:
            self._client.close()
            self._client = None

    @property
    def kind(self) -> str:
        if self.scheduler or self._client is not None:
            return "dask"
        return "inline" if self.workers == 1 else "processes"

    def _dask(self) -> Any:
        if self._client is None:
            try:
                distributed = importlib.import_module("dask.distributed")
            except ImportError as exc:
                raise ConfigError("--scheduler needs dask[distributed] (pip install "
                                  "'dynval[validate]')") from exc
            try:
                self._client = distributed.Client(self.scheduler, timeout=30)
            except OSError as exc:
                raise ConfigError(f"cannot reach the Dask scheduler {self.scheduler}: "
                                  f"{exc}") from None
            self._own_client = True
            log.info("Dask scheduler %s: %d workers", self.scheduler,
                     len(self._client.scheduler_info().get("workers", {})))
        return self._client

    def _n_slots(self) -> int:
        if self.kind == "dask":
            info = self._dask().scheduler_info().get("workers", {})
            return max(1, sum(int(w.get("nthreads", 1)) for w in info.values()))
        return self.workers

    def run(self, job: SweepJob, sets: Sequence[Mapping[str, float]], *,
            chunk: int | None = None, on_progress: Progress | None = None) -> SweepResult:
        """Every parameter set through every force of the job."""
        sets_l = [dict(s) for s in sets]
        n = len(sets_l)
        nf = len(job.features.labels())
        feats = np.full((n, len(job.forces), nf), np.nan)
        rmse = np.full((n, len(job.rmse_channels)), np.nan)
        failed: list[int] = []
        ref_rms = tuple(float(np.sqrt(np.mean(r * r))) for r in job.rmse_refs)
        if n == 0:
            return SweepResult(feats, rmse, failed, ref_rms)
        slots = self._n_slots()
        size = chunk or max(1, min(64, math.ceil(n / (4 * slots)) if n >= 8 * slots
                                   else math.ceil(n / slots)))
        bounds = [(i, min(n, i + size)) for i in range(0, n, size)]
        done = 0

        def take(b: tuple[int, int], res: tuple[np.ndarray, np.ndarray, list[int]]) -> None:
            nonlocal done
            feats[b[0]:b[1]] = res[0]
            rmse[b[0]:b[1]] = res[1]
            failed.extend(b[0] + i for i in res[2])
            done += b[1] - b[0]
            if on_progress is not None:
                on_progress(done, n)

        if self.kind == "inline" or (len(bounds) == 1 and self.kind != "dask"):
            for b in bounds:
                take(b, _chunk_run(job, sets_l[b[0]:b[1]]))
        elif self.kind == "processes":
            if self._pool is None:
                self._pool = cf.ProcessPoolExecutor(max_workers=self.workers)
            with tempfile.TemporaryDirectory(prefix="dynval-sweep-") as tmp:
                light, files = _to_files(job, tmp)
                futs = {self._pool.submit(_chunk_run_mapped, light, files, sets_l[b[0]:b[1]]): b
                        for b in bounds}
                for fu in cf.as_completed(futs):
                    take(futs[fu], fu.result())
        else:
            client = self._dask()
            distributed = importlib.import_module("dask.distributed")
            [job_f] = client.scatter([job], broadcast=True)
            dfuts = {client.submit(_chunk_run, job_f, sets_l[b[0]:b[1]], pure=False): b
                     for b in bounds}
            for fu in distributed.as_completed(list(dfuts)):
                take(dfuts[fu], fu.result())
        failed.sort()
        return SweepResult(feats, rmse, failed, ref_rms)


def simulate_one(m: mdl.Model, params: Mapping[str, float], force: np.ndarray, fs_hz: float,
                 oversample: int | None = None) -> dict[str, np.ndarray]:
    """Time histories of one run (all outputs of m)."""
    return meas.simulate(m.with_params(params), force, fs_hz, oversample)
