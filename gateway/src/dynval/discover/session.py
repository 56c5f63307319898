"""One discover run's setup and records: its options, the tests and their split into
fitting and held-out sets (Session), each round's record (Round) and the result
(DiscoverResult)."""
from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.discover import noise as nz
from dynval.discover import parallel, segments
from dynval.discover import residual as rs
from dynval.discover import trace as tr
from dynval.errors import ConfigError
from dynval.io.recording import Recording
from dynval.validate import measurement

log = logging.getLogger(__name__)


@dataclass
class Options:
    max_effects: int = 3
    top_k: int = 4
    min_gain: float = 0.10
    max_worse: float = 0.05  # a held-out test where the effect never acts moves by fit noise
    significance_ratio: float = rs.SIGNIFICANCE_RATIO
    gray_ratio: float = rs.GRAY_RATIO  # under significance_ratio: tested by fitting (residual.py)
    later_gray_ratio: float = rs.LATER_GRAY_RATIO  # the same after an effect is accepted
    noise: dict[str, float] | None = None  # stated noise RMS per channel (channel units)
    max_nfev: int = 40
    evidence_cut: float = 0.2  # fit only candidates with >= this share of the top evidence
    uncertain: tuple[str, ...] = ()  # declared parameters to calibrate first and re-adjust
    # re-adjust the declared stiffness, mass and damping at each candidate's location (and
    # the modal damping) while it is fitted
    readjust: bool = True
    workers: int = 0  # processes for the candidate fits of a round; 0: every available core
    # simulate with the declared model's own input interpolation and oversampling instead of
    # the core's cubic input hold at the sample rate (loop.simulation_for_fits)
    declared_simulation: bool = False


@dataclass
class Round:
    index: int
    ratio: dict[str, float]
    traits: dict[str, Any]
    evidence: list[tr.Evidence]
    fits: list[dict[str, Any]]
    accepted: dict[str, Any] | None
    decision: str
    view: tr.ForceView | None = None
    second: list[tr.Evidence] = field(default_factory=list)  # the output view's top picks
    noise: dict[str, float] = field(default_factory=dict)  # the floor judged against, per channel
    # weak evidence: each nonlinear type's best-placed candidates, one of each type fitted
    # when the first batch leaves the held-out residual above the floor (judge.weak_to_fit)
    weak: list[tr.Evidence] = field(default_factory=list)

    def above_noise(self) -> float:
        """The residual's share the noise floor does not explain (1 - the "no effect"
        evidence's share)."""
        return 1.0 - next((e.r2 for e in self.evidence if e.cand.type == "none"), 1.0)


@dataclass
class DiscoverResult:
    model0: mdl.Model
    model: mdl.Model
    tests: list[rs.TestData]
    fit_names: list[str]
    held_names: list[str]
    chans: list[str]
    scales: dict[str, float]
    noise: dict[str, float]
    before: rs.ErrorTable
    after: rs.ErrorTable
    res_before: dict[str, dict[str, np.ndarray]]
    res_after: dict[str, dict[str, np.ndarray]]
    rounds: list[Round]
    effects: list[dict[str, Any]]
    mahalanobis: dict[str, Any]
    band_hz: tuple[float, float]
    modes_hz: list[float]
    notes: list[str] = field(default_factory=list)
    timing_s: dict[str, float] = field(default_factory=dict)
    calibration: dict[str, Any] = field(default_factory=dict)
    noise_floors: dict[str, nz.Floor] = field(default_factory=dict)
    unexplained: dict[str, Any] = field(default_factory=dict)  # traits of a residual left
    prediction: str = "open loop"  # or "observer" (a drifting model: discover/drift.py)
    open_loop_before: dict[str, float] = field(default_factory=dict)  # held-out, per channel


# fewer tests than this: cross-validate over time segments of every test instead of
# splitting the tests (two tests split by level leave one level out of the fit entirely)
MIN_TESTS_FOR_TEST_SPLIT = 4


def split(tests: Sequence[rs.TestData]) -> tuple[list[rs.TestData], list[rs.TestData], str]:
    """Fitting and held-out sets, and a sentence saying how they were made."""
    if len(tests) < MIN_TESTS_FOR_TEST_SPLIT:
        fit, held = rs.segment_split(tests)
        return fit, held, (
            f"{len(tests)} test(s): cross-validation over time — each record is cut into "
            f"{rs.SEGMENT_BLOCKS} blocks, the even ones fit and the odd ones are held out "
            "(simulated over the whole record, so every block starts from its true state)")
    med = {t.name: median_frequency(t.u, t.fs_hz) for t in tests}
    if one_band(med.values()):
        order = sorted(tests, key=lambda t: (float(np.std(t.u)), t.name))
        return order[0::2], order[1::2], (
            f"{len(tests)} tests sorted by input RMS, dealt alternately to the fitting and "
            "held-out sets")
    fit, held = twins(tests, med)
    return fit, held, (
        f"{len(tests)} tests at several input frequencies: paired with their nearest in "
        "median frequency and RMS, one of each pair fitted (the lower frequency) and the "
        "other held out")


# inputs whose median frequencies lie within this ratio of each other's excite the same modes
SAME_BAND_RATIO = 1.25


def median_frequency(u: np.ndarray, fs_hz: float) -> float:
    """The frequency below which half the input's power lies (mean removed); at least one
    bin of its PSD."""
    at = measurement.power_quantiles(u - np.mean(u), fs_hz, (0.5,))[0]
    bins = np.fft.rfftfreq(min(1024, u.size), 1.0 / fs_hz)  # power_quantiles' PSD bins
    return max(at, float(bins[1]) if bins.size > 1 else fs_hz / 2)


def one_band(medians: Iterable[float]) -> bool:
    """Whether the tests' inputs share one band: their median frequencies, sorted, never
    jump by more than SAME_BAND_RATIO (random or swept tests over one band)."""
    ms = sorted(medians)
    return all(b <= SAME_BAND_RATIO * a for a, b in zip(ms, ms[1:], strict=False))


def twins(tests: Sequence[rs.TestData], med: Mapping[str, float]
          ) -> tuple[list[rs.TestData], list[rs.TestData]]:
    """Fitting and held-out sets of tests at several input frequencies: the two tests
    nearest in log median frequency plus log RMS paired first, and so on; the lower
    frequency (then RMS, name) of each pair is fitted, the other held out, an odd one
    fitted. Each held-out test has a fitting test like it, and each set keeps the levels
    near one frequency: a stepped sine dealt by level alone held out both records beside its
    third mode, the fit never saw that mode and its re-adjusted damping wandered (a
    stick-slip joint fitted within 2 % was refused at 130 x the true model's held-out
    error)."""
    left = sorted(tests, key=lambda t: (med[t.name], float(np.std(t.u)), t.name))
    key = np.array([(math.log(med[t.name]), math.log(max(float(np.std(t.u)), 1e-300)))
                    for t in left])
    dist = np.abs(key[:, None, :] - key[None, :, :]).sum(axis=2)
    dist[np.tril_indices(len(left))] = np.inf  # each pair once, i < j: i the lower frequency
    fit: list[rs.TestData] = []
    held: list[rs.TestData] = []
    for _ in range(len(left) // 2):
        i, j = np.unravel_index(int(np.argmin(dist)), dist.shape)
        fit.append(left[i])
        held.append(left[j])
        dist[[i, j], :] = np.inf
        dist[:, [i, j]] = np.inf
    paired = {id(t) for t in fit + held}
    return fit + [t for t in left if id(t) not in paired], held


def settle_s(modes_hz: Sequence[float], zeta: float = 0.01) -> float:
    """How long the structure rings after its input stops: 1 % of the amplitude left in the
    lowest flexible mode at a light damping ratio (at most 5 s)."""
    flex = [f for f in modes_hz if f > 0.1]
    return min(5.0, math.log(100.0) / (2 * math.pi * min(flex) * zeta)) if flex else 5.0


def settle_samples(modes_hz: Sequence[float], band_hz: tuple[float, float], fs_hz: float
                   ) -> int:
    """The start-up window in samples (settle_s) over the modes that are not rigid-body-like
    (above 5 % of the input band's lower edge)."""
    return int(settle_s([f for f in modes_hz if f > 0.05 * band_hz[0]]) * fs_hz)


def bic(nsse: float, n: float, p: int) -> float:
    return n * math.log(max(nsse, 1e-300) / n) + p * math.log(n)


@dataclass
class Session:
    """What every stage of one discover run reads: the tests and their split, the channels
    and their scales, the input band, the model's modes and the options."""

    o: Options
    tests: list[rs.TestData]
    chans: list[str]
    scales: dict[str, float]
    fit_t: list[rs.TestData]
    held_t: list[rs.TestData]
    band: tuple[float, float]
    modes_hz: list[float]
    settle: int
    notes: list[str] = field(default_factory=list)
    # declared parameters an accepted effect re-adjusted: free already, so a later change of
    # one is the re-adjustment going on (the final joint one), not a new effect
    readjusted: set[str] = field(default_factory=set)
    # the model parameters accepted effects added (e<i>.<name> of their elements, l<i>.* and
    # the mass of an appendage): re-adjusted with the declared ones, since they moved
    # together (a best-linear model; a second effect found later) (their entry in the effects
    # list and their name there, '' for an appendage's link and mass: read back)
    effect_params: dict[str, tuple[int, str]] = field(default_factory=dict)
    # a round's winner that gave the round to the linear change in its re-adjustment
    # (judge.change_in_the_readjustment): fitted again next round, on top of the change
    carried: set[str] = field(default_factory=set)
    # each candidate's last fit's wall time (s) by judge.cand_key: a round's map hands the
    # longest out first (parallel.ordered_map's cost)
    fit_seconds: dict[str, float] = field(default_factory=dict)
    # a joint re-adjustment of the declared parameters was kept (loop._readjust_declared):
    # the modes are where the data put them, and later ones start there
    readjust_kept: bool = False
    # the re-adjustment went through the observer's gains on the structure as it is (not
    # kept): a measurement-chain effect accepted since (a DAQ filter, a sensor's gain) moves
    # no mode, so the same search would find the same basin (loop._readjust_declared)
    gains_tried: bool = False

    @property
    def workers(self) -> int:
        """Processes for independent fits (candidates, per-test refits)."""
        return self.o.workers or parallel.available_workers()

    @property
    def evals(self) -> list[rs.TestData]:
        return [*self.fit_t, *self.held_t]  # every test once, or every test's two views

    @property
    def fit_names(self) -> list[str]:
        return [t.name for t in self.fit_t]

    @property
    def held_names(self) -> list[str]:
        return [t.name for t in self.held_t]

    def table(self, m: mdl.Model) -> tuple[rs.ErrorTable, dict[str, dict[str, np.ndarray]]]:
        return rs.error_table(m, self.evals, self.chans, self.scales)


def make_session(m: mdl.Model, recs: Sequence[Recording], o: Options) -> Session:
    tests = rs.prepare(m, recs)
    dead = dead_channels(m, tests)
    left = [f"left out, unusable in some test: {', '.join(dead)}"] if dead else []
    left += partial_channels(m, tests)  # by the records' names, before any segments
    chans = rs.common_channels(m, tests)
    if not chans:
        raise ConfigError("no model output is a column of every test" + (
            f" that can be fitted (unusable: {', '.join(dead)})" if dead else ""))
    fs_set = {round(t.fs_hz, 6) for t in tests}
    if len(fs_set) != 1:
        raise ConfigError(f"the tests have different sample rates: {sorted(fs_set)}")
    band = tr.input_band(tests)
    modes_hz = [float(f) for f in mdl.natural_frequencies(m)]
    settle = settle_samples(modes_hz, band, tests[0].fs_hz)
    tests, cut = segments.bound(tests, settle)  # long records: evenly spaced segments
    fit_t, held_t, how = split(tests)
    return Session(o, tests, chans, rs.channel_scales(tests, chans), fit_t, held_t, band,
                   modes_hz, settle, [how, *left, *cut, *sub_band_note(m, tests)])


# a channel holding its largest (or smallest) value at this many samples, and this share of
# the record, is clipped: a live sensor's extreme is one sample (a Gaussian response's within
# a quarter-sigma quantisation step: about 0.3 of 8192 samples)
CLIPPED_SAMPLES = 8
CLIPPED_SHARE = 0.002


def unusable(y: np.ndarray, kind: str = "acc") -> str:
    """Why a test's output channel cannot be fitted: '' when it can; constant throughout (a
    sensor not wired or dead); an accelerometer's clipped (an overloaded sensor or DAQ range:
    the response beyond its limits is not in the record, and a model fitted to it takes a
    sensor gain or worse). Only an acceleration: a position held at a step's plateau, a
    quantised one flickering there, reads its extreme for long (a BRFD step test: 103 samples
    of 15 361)."""
    if not y.size:
        return ""
    hi, lo = float(np.max(y)), float(np.min(y))
    if hi == lo:
        return "constant throughout (a dead or unplugged sensor)"
    if kind != "acc":
        return ""
    at = max(int(np.count_nonzero(y == hi)), int(np.count_nonzero(y == lo)))
    if at >= max(CLIPPED_SAMPLES, CLIPPED_SHARE * y.size):
        return f"clipped ({at} samples at its limit: an overloaded sensor or DAQ range)"
    return ""


def partial_channels(m: mdl.Model, tests: Sequence[rs.TestData]) -> list[str]:
    """A note (and a warning) for the model's outputs that some tests have and others lack:
    discover uses the channels every test has, so those are left out (silently before). A
    dead one is out of every test already (dead_channels), so not among them."""
    lacking = {c: [t.name for t in tests if c not in t.y] for c in m.outputs}
    parts = [f"{c} (not in {', '.join(names)})" for c, names in lacking.items()
             if names and len(names) < len(tests)]
    if not parts:
        return []
    text = f"left out, a column of some tests only: {', '.join(parts)}"
    log.warning("%s", text)
    return [text]


def dead_channels(m: mdl.Model, tests: Sequence[rs.TestData]) -> list[str]:
    """Output channels that cannot be fitted in some test (unusable: constant or clipped; a
    dead one drew a sensor gain at its bound and a spurious mass change, a clipped one a
    sensor gain), taken out of every test (discover uses the channels all tests have),
    logged; 'channel (test: why; ...)'."""
    where: dict[str, list[str]] = {}
    for t in tests:
        for c, y in t.y.items():
            why = unusable(y, m.outputs[c].kind)
            if why:
                where.setdefault(c, []).append(f"{t.name}: {why}")
    for t in tests:
        for c in where:
            t.y.pop(c, None)
    out = [f"{c} ({'; '.join(whys)})" for c, whys in where.items()]
    for text in out:
        log.warning("channel %s: left out", text)
    return out


def sub_band_note(m: mdl.Model, tests: Sequence[rs.TestData]) -> list[str]:
    """Notes saying what of its sensor's noise the simulations' input leaves out (the tests'
    input_for: noise.without_mains, noise.without_sub_band_noise)."""
    if m.input.kind not in nz.SUB_BAND_KINDS:
        return []
    hum = {t.name: nz.input_mains_lines(t.u, t.fs_hz) for t in tests}
    hummed = [t for t, lines in hum.items() if lines]
    notes = [f"the measured input's mains hum at "
             f"{', '.join(f'{x:g}' for x in sorted({x for v in hum.values() for x in v}))} Hz "
             f"({len(hummed)} of {len(tests)} tests), outside the excitation band, is its "
             "sensor's pick-up: taken out of the input the simulations are driven with"
             ] if hummed else []
    corners = [c for t in tests if (c := nz.sub_band_corner(nz.without_mains(t.u, t.fs_hz),
                                                             t.fs_hz)) is not None]
    if not corners:
        return notes
    lo, hi = f"{min(corners):.3g}", f"{max(corners):.3g}"
    return [*notes,
            f"the measured input under {lo if lo == hi else f'{lo}-{hi}'} Hz "
            f"({len(corners)} of {len(tests)} tests) is its sensor's noise (its spectrum within "
            f"{nz.SUB_BAND_SNR:g} x of the noise's level under the excitation band): the "
            "simulations are driven without it, and without its mean where that is no larger than "
            f"{nz.SUB_BAND_MEAN:g} x that noise's RMS"]


