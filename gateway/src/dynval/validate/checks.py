"""The report's linearity and reciprocity checks (its 5.3.1) in `dynval validate`: each reduced
to scalars over the input's band (catalogue.frf.compare: z2 of H1, z2 of the coherence, mean
|dB|), computed on the tests and, the same way, on the model driven by the same forces with the
same sensor noise. The model is consistent with the tests when the check holds on both or fails
on both; a linear model on a structure whose check fails is not.

    --check linearity@CH      the tests at the higher excitation level against those at the
                              lower (split at the largest step of the input RMS)
    --check reciprocity@CH    the tests (input at the model's input DOF i, response CH at DOF
                              j) against --swapped tests (input at DOF j, response the model's
                              output of CH's kind at DOF i)
"""
from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.catalogue import frf as F
from dynval.errors import ConfigError
from dynval.io.recording import Recording
from dynval.validate import measurement as meas

KINDS = ("linearity", "reciprocity")
LEVEL_RATIO = 1.25  # the smallest step of input RMS that makes two excitation levels
_SPEC = re.compile(r"^(linearity|reciprocity)@([\w.-]+)$")


@dataclass(frozen=True)
class Check:
    kind: str
    channel: str  # the response channel of the tests (resolved)
    other: str  # the response channel of the second group (reciprocity: at the input DOF)


@dataclass
class Outcome:
    """A check on the tests and on the model: the comparisons, the FRFs (for the figure)."""

    check: Check
    labels: tuple[str, str]  # what the two groups are
    measured: F.Comparison
    model: F.Comparison
    frfs: dict[str, tuple[F.Frf, F.Frf]]  # "measured" / "model" -> (group a, group b)

    @property
    def consistent(self) -> bool:
        return self.measured.passed == self.model.passed

    def summary(self) -> dict[str, Any]:
        def side(c: F.Comparison) -> dict[str, Any]:
            return {"z2": c.z2, "z2_coh": c.z2_coh, "db": c.db, "dcoh": c.dcoh,
                    "holds": c.passed}
        c = self.check
        word = "holds" if self.measured.passed else "fails"
        mword = "holds" if self.model.passed else "fails"
        return {"check": c.kind, "channel": c.channel, "other_channel": c.other,
                "groups": list(self.labels), "band_hz": list(self.measured.band_hz),
                "limit": F.Z2_LIMIT, "measured": side(self.measured),
                "model": side(self.model), "consistent": self.consistent,
                "meaning": f"the {c.kind} check {word} on the tests and {mword} on the model"
                           + ("" if self.consistent else ": the model does not reproduce it")}


def parse(specs: Sequence[str], m: mdl.Model, available: Sequence[str]) -> list[Check]:
    """--check texts to checks bound to the model's output channels."""
    out = []
    for s in specs:
        g = _SPEC.match(s.replace(" ", ""))
        if g is None:
            raise ConfigError(f"--check '{s}': expected linearity@CHANNEL or "
                              "reciprocity@CHANNEL, e.g. linearity@acc4")
        kind, c = g.groups()
        hits = [a for a in available if a == c or a.split("_")[0] == c]
        if len(hits) != 1:
            raise ConfigError(f"--check '{s}': channel '{c}' "
                              f"{'is ambiguous' if hits else 'not found'} (outputs: "
                              f"{', '.join(available)})")
        other = hits[0]
        if kind == "reciprocity":
            other = _reciprocal_channel(m, hits[0], s)
        out.append(Check(kind, hits[0], other))
    return out


def _reciprocal_channel(m: mdl.Model, ch: str, spec: str) -> str:
    """The output of ch's kind at the model's input DOF (the swapped tests' response)."""
    if m.input.kind != "force":
        raise ConfigError(f"--check '{spec}': reciprocity swaps a force's DOF; the model's "
                          f"input is a {m.input.kind}")
    o = m.outputs[ch]
    same = [n for n, p in m.outputs.items() if p.kind == o.kind and p.index == m.input.dof]
    if not same:
        raise ConfigError(f"--check '{spec}': the model has no {o.kind} output at its input "
                          f"DOF {m.input.dof} (the swapped tests' response)")
    return same[0]


def split_levels(recs: Sequence[Recording], inp: str) -> tuple[list[int], list[int]]:
    """Indices of the high- and low-level tests: split at the largest ratio between
    consecutive input RMS values; ConfigError when it is below LEVEL_RATIO."""
    rms = np.array([np.sqrt(np.mean(r.channel(inp).data ** 2)) for r in recs])
    order = np.argsort(rms)
    steps = rms[order][1:] / np.maximum(rms[order][:-1], 1e-300)
    k = int(np.argmax(steps)) if steps.size else 0
    if not steps.size or steps[k] < LEVEL_RATIO:
        raise ConfigError(f"--check linearity: the tests' input RMS spans {rms.min():.4g}-"
                          f"{rms.max():.4g}: it needs tests at two excitation levels (a step "
                          f"of at least {LEVEL_RATIO:g} x)")
    lo = sorted(int(i) for i in order[:k + 1])
    hi = sorted(int(i) for i in order[k + 1:])
    return hi, lo


def _frf(recs: Sequence[Recording], ys: Sequence[dict[str, np.ndarray]], inp: str, ch: str,
         fs: float) -> F.Frf:
    return F.estimate_records([(r.channel(inp).data, {"y": y[ch]})
                               for r, y in zip(recs, ys, strict=True)], fs)


def _simulated(m: mdl.Model, recs: Sequence[Recording], inp: str, chans: Sequence[str],
               noise_spec: str, stream: int) -> list[dict[str, np.ndarray]]:
    """m driven by each test's force, with sensor noise: --noise auto estimates it test by
    test (the coherence compared follows each test's signal-to-noise ratio, which differs
    between excitation levels when the noise does not scale with them)."""
    fs = recs[0].fs_hz
    out = []
    for k, r in enumerate(recs):  # a draw per test, also for tests with equal forces
        nz = meas.noise_levels(noise_spec, m, [r], list(chans), inp)[0]
        u = r.channel(inp).data
        out.append(meas.add_noise(meas.simulate(m, u, fs), nz, u, 1_000_000 * stream + k))
    return out


def run(m: mdl.Model, recs: Sequence[Recording], checks: Sequence[Check], inp: str,
        noise_spec: str = "auto", swapped: Sequence[Recording] = ()) -> list[Outcome]:
    """Each check on the tests and on the model m (driven by each test's force, with the
    sensor noise --noise gives, test by test; draws apart from the validation's)."""
    if not checks:
        return []
    fs = recs[0].fs_hz
    band = meas.input_band(recs[0].channel(inp).data, fs)
    chans = sorted({k.channel for k in checks})
    meas_y = [{c: r.channel(c).data for c in chans} for r in recs]
    sim_y = _simulated(m, recs, inp, chans, noise_spec, 1)
    out = []
    for c in checks:
        if c.kind == "linearity":
            hi, lo = split_levels(recs, inp)
            frfs = {src: (_frf([recs[i] for i in hi], [ys[i] for i in hi], inp, c.channel, fs),
                          _frf([recs[i] for i in lo], [ys[i] for i in lo], inp, c.channel, fs))
                    for src, ys in (("measured", meas_y), ("model", sim_y))}
            labels = (f"{len(hi)} higher-level tests", f"{len(lo)} lower-level tests")
        else:
            if not swapped:
                raise ConfigError(f"--check reciprocity@{c.channel}: needs --swapped TESTS "
                                  f"(the force at DOF {m.outputs[c.channel].index}, the "
                                  f"response {c.other})")
            _check_swapped(swapped, fs, inp, c)
            m_sw = dataclasses.replace(m, input=dataclasses.replace(
                m.input, dof=m.outputs[c.channel].index))
            sw_meas = [{c.other: r.channel(c.other).data} for r in swapped]
            sw_sim = _simulated(m_sw, swapped, inp, [c.other], noise_spec, 2)
            frfs = {src: (_frf(recs, a, inp, c.channel, fs), _frf(swapped, b, inp, c.other, fs))
                    for src, a, b in (("measured", meas_y, sw_meas), ("model", sim_y, sw_sim))}
            labels = (f"input DOF {m.input.dof} -> {c.channel}",
                      f"input DOF {m.outputs[c.channel].index} -> {c.other}")
        cmp = {k: F.compare(a, b, 0, 0, band) for k, (a, b) in frfs.items()}
        out.append(Outcome(c, labels, cmp["measured"], cmp["model"], dict(frfs)))
    return out


def _check_swapped(swapped: Sequence[Recording], fs: float, inp: str, c: Check) -> None:
    for r in swapped:
        if abs(r.fs_hz - fs) > 1e-6 * fs:
            raise ConfigError(f"{r.name} (--swapped): sampled at {r.fs_hz:g} Hz, the tests at "
                              f"{fs:g} Hz")
        missing = [n for n in (inp, c.other) if n not in r.names]
        if missing:
            raise ConfigError(f"{r.name} (--swapped): no channel {', '.join(missing)}")
