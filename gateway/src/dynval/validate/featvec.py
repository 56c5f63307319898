"""Feature vectors by name, computed by the C core (report Section 5 features, Section 6 use).

Grammar (whitespace ignored)::

    SPEC  := TERM (('+' | ';') TERM)*
    TERM  := NAMES '@' CHANS
    NAMES := NAME (',' NAME)*
    CHANS := CHAN (',' CHAN)*

``CHAN`` is a channel name as in the test file (``acc3_mps2``) or its stem before the unit
suffix (``acc3``). ``NAME`` is one of:

* basic statistics of the whole record (dv_moments, population moments, Table 15):
  ``peak mean rms std var skew kurt min max crest kfactor``;
* temporal moments (dv_temporal, eq. 14-16, Table 16): ``tm_E`` energy, ``tm_T`` central time,
  ``tm_D`` RMS duration, ``tm_S`` central skewness, ``tm_K`` central kurtosis, ``tm_A`` root
  energy amplitude;
* ``segstd<N>``: the population STD of each of N equal consecutive segments (N values; the
  report's 64 segments, Fig. 86), by dv_moments on each segment (equal to dv_segstd);
* ``ar_rms`` / ``ar_rms<p>``: RMS of the one-step AR(p) residual (eq. 31, default p = 30,
  Burg) under a reference AR model fitted by the C core to the first baseline test of that
  channel (FeatureSet.fit_reference; that test itself under the second test's); without a
  reference, to the record itself;
* input/output (the input channel is read too, FeatureSet.with_input; the band is where the
  first baseline test's input holds 98 % of its power): ``coh`` the band-mean coherence of
  the channel to the input (5.3.1, Hann 1024 / 50 %); ``modal_f<N>``, ``modal_zeta<N>``,
  ``modal_mac<N>``: the N strongest modes of an EMA over the term's channels jointly (5.1,
  dynval.catalogue.modal): natural frequencies (Hz), damping ratios, and the MAC of each
  mode with the nearest mode of the first baseline test (N values each, ascending frequency);
* the waveform and spectral catalogue (dynval.catalogue.signal_terms: ``ks ad d10 decay
  decay_y0 acf_corr harm_n thd srs_peak srs_rms cep_env holder_drops holder_min``); ``ks``,
  ``ad``, ``acf_corr``, ``srs_*`` and ``cep_env`` compare the record with the first baseline
  test of that channel (FeatureSet.fit_reference), and that test itself, measured or
  simulated (the record driven by its input), with the second (its comparison with itself
  would be 0 measured against the model's nonzero value).

Examples: ``peak,std@acc3,acc4``; ``segstd64@acc4``; ``tm_E,tm_T@acc2 + ar_rms@acc4``;
``modal_f3,modal_zeta3@acc1,acc2,acc3,acc4 + coh@acc4``.
The vector is ordered term by term, then feature by feature, then channel by channel; labels
read ``std@acc3_mps2`` or ``segstd64[5]@acc4_mps2``.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from dynval import ar as _ar
from dynval import features as _feat
from dynval.catalogue import frf as _frf
from dynval.catalogue import modal as _modal
from dynval.catalogue import signal_terms as _cat
from dynval.errors import ConfigError
from dynval.validate import measurement as _meas

BASIC = ("peak", "mean", "rms", "std", "var", "skew", "kurt", "min", "max", "crest", "kfactor")
TEMPORAL = {"tm_E": "energy", "tm_T": "central_time", "tm_D": "rms_duration",
            "tm_S": "central_skew", "tm_K": "central_kurt", "tm_A": "root_energy_amp"}
AR_DEFAULT_ORDER = 30
_SEG = re.compile(r"^segstd(\d+)$")
_AR = re.compile(r"^ar_rms(\d*)$")
_MODAL = re.compile(r"^modal_(f|zeta|mac)(\d+)$")


def valid_names() -> list[str]:
    """Every feature name the grammar accepts (patterns with <N>/<p>)."""
    return [*BASIC, *TEMPORAL, "segstd<N>", "ar_rms", "ar_rms<p>", "coh", "modal_f<N>",
            "modal_zeta<N>", "modal_mac<N>", *_cat.TERMS]


def _check_name(name: str) -> None:
    if name in BASIC or name in TEMPORAL or name == "coh" or name in _cat.TERMS:
        return
    g = _SEG.match(name) or _MODAL.match(name)
    if g is not None:
        if int(g.groups()[-1]) < 1:
            raise ConfigError(f"feature '{name}': needs N >= 1")
        return
    g = _AR.match(name)
    if g is not None:
        p = int(g.group(1) or AR_DEFAULT_ORDER)
        if not 1 <= p <= _ar.MAX_ORDER:
            raise ConfigError(f"feature '{name}': AR order must be 1..{_ar.MAX_ORDER}")
        return
    raise ConfigError(f"unknown feature '{name}' (valid: {', '.join(valid_names())})")


@dataclass(frozen=True)
class Term:
    names: tuple[str, ...]
    channels: tuple[str, ...]


@dataclass(frozen=True)
class FeatureSet:
    """A parsed feature spec. resolve() binds channel stems to a recording's column names."""

    spec: str
    terms: tuple[Term, ...]
    resolved: bool = False
    ar_ref: Mapping[tuple[str, int], _ar.ARModel] = field(default_factory=dict, compare=False)
    input_channel: str = ""  # read by the input/output features (coh, modal_*)
    band_hz: tuple[float, float] = (0.0, 0.0)
    modal_ref: Mapping[tuple[tuple[str, ...], int], _modal.Modes] = field(
        default_factory=dict, compare=False)  # (channels, N) -> the first test's modes
    ref_data: Mapping[str, np.ndarray] = field(default_factory=dict, compare=False)
    # the second baseline test's: the reference of the reference test itself (see _ref)
    alt_data: Mapping[str, np.ndarray] = field(default_factory=dict, compare=False)
    ar_alt: Mapping[tuple[str, int], _ar.ARModel] = field(default_factory=dict, compare=False)
    # the reference test's input: a record driven by it (measured or simulated) is that test
    ref_input: np.ndarray | None = field(default=None, compare=False)

    @property
    def channels(self) -> list[str]:
        """The channels the vector reads, in first-use order."""
        out: list[str] = []
        for t in self.terms:
            for c in t.channels:
                if c not in out:
                    out.append(c)
        return out

    def resolve(self, available: Sequence[str]) -> FeatureSet:
        """Bind each CHAN to one of the available names (exact, or the stem before '_')."""
        terms = []
        for t in self.terms:
            chans = []
            for c in t.channels:
                if c in available:
                    chans.append(c)
                    continue
                hits = [a for a in available if a.split("_")[0] == c]
                if len(hits) != 1:
                    raise ConfigError(f"feature spec '{self.spec}': channel '{c}' "
                                      f"{'is ambiguous' if hits else 'not found'} (available: "
                                      f"{', '.join(available)})")
                chans.append(hits[0])
            terms.append(Term(t.names, tuple(chans)))
        return replace(self, terms=tuple(terms), resolved=True)

    def labels(self) -> list[str]:
        out: list[str] = []
        for t in self.terms:
            for name in t.names:
                for c in t.channels:
                    g = _SEG.match(name) or _MODAL.match(name)
                    if g is not None and g.re is _MODAL:
                        if c == t.channels[0]:  # one EMA over the term's channels
                            out += [f"{name}[{i}]@{','.join(t.channels)}"
                                    for i in range(int(g.group(2)))]
                    elif g is not None:
                        out += [f"{name}[{i}]@{c}" for i in range(int(g.group(1)))]
                    else:
                        out.append(f"{name}@{c}")
        return out

    def needs_ar(self) -> list[tuple[str, int]]:
        out: list[tuple[str, int]] = []
        for t in self.terms:
            for name in t.names:
                g = _AR.match(name)
                if g is not None:
                    p = int(g.group(1) or AR_DEFAULT_ORDER)
                    out += [(c, p) for c in t.channels if (c, p) not in out]
        return out

    def fit_reference(self, data: Mapping[str, np.ndarray], fs_hz: float = 0.0,
                      alt: Mapping[str, np.ndarray] | None = None) -> FeatureSet:
        """Fit the AR reference models (ar_rms) to one baseline record (channel -> samples),
        keep its channels the catalogue's comparing names read, and for the input/output
        features find the band and the reference modes (modal_mac). alt: another baseline
        record, the reference of this one (without it, the reference record's comparing
        features compare it with itself: 0 measured against a model's noisy nonzero value, a
        bias that made a right model fail too often)."""
        ref = {(c, p): _ar.burg(data[c], p) for c, p in self.needs_ar()}
        chans = {c for t in self.terms for n in t.names for c in t.channels
                 if (n in _cat.TERMS and _cat.TERMS[n].ref) or _AR.match(n)}
        keep = {c: data[c] for c in chans}
        alt_keep = {c: alt[c] for c in chans} if alt is not None else {}
        ar_alt = ({(c, p): _ar.burg(alt[c], p) for c, p in self.needs_ar()}
                  if alt is not None else {})
        io = [t for t in self.terms if any(n == "coh" or _MODAL.match(n) for n in t.names)]
        if not io:
            return replace(self, ar_ref=ref, ref_data=keep, alt_data=alt_keep, ar_alt=ar_alt,
                           ref_input=data.get(self.input_channel))
        u = self._input(data)
        if not fs_hz > 0:
            raise ConfigError("fit_reference: coh and modal_* need the sampling rate")
        band = _meas.input_band(u, fs_hz)
        mref = {}
        for t in io:
            for n in {int(g.group(2)) for g in map(_MODAL.match, t.names) if g}:
                modes = _modal.record_modes(u, {c: data[c] for c in t.channels}, fs_hz, band, n)
                if modes is None:
                    raise ConfigError(f"modal features @{','.join(t.channels)}: the first "
                                      f"baseline test shows fewer than {n} stable modes in "
                                      f"{band[0]:g}-{band[1]:g} Hz")
                mref[(t.channels, n)] = modes
        return replace(self, ar_ref=ref, ref_data=keep, band_hz=band, modal_ref=mref,
                       alt_data=alt_keep, ar_alt=ar_alt, ref_input=u)

    def _is_ref(self, c: str, x: np.ndarray, u: np.ndarray | None) -> bool:
        """x (channel c, driven by input u) is the reference test, measured or simulated:
        then alt_data is its reference. By the input where both are known: the model driven
        by the reference test's force compared with that test itself would compare two
        records of one force, measured against two forces (a residual off by the
        test-to-test scatter); else x is the reference record itself."""
        if c not in self.alt_data:
            return False
        r, ru = self.ref_data.get(c), self.ref_input
        if ru is not None and u is not None:
            return ru.shape == u.shape and bool(np.array_equal(ru, u))
        return r is not None and r.shape == x.shape and bool(np.array_equal(r, x))

    def with_input(self, channel: str) -> FeatureSet:
        """The input channel (the force) the input/output features read."""
        return replace(self, input_channel=channel)

    def _input(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        if self.input_channel not in data:
            raise ConfigError(f"feature spec '{self.spec}': coh and modal_* read the input, "
                              f"and the record has no input channel "
                              f"'{self.input_channel or '(none set)'}'")
        return data[self.input_channel]

    def _io_features(self, t: Term, name: str, data: Mapping[str, np.ndarray], fs_hz: float,
                     cache: dict[tuple[tuple[str, ...], int], _modal.Modes | None]
                     ) -> list[float]:
        """Values of an input/output feature (coh per channel, modal_* per mode)."""
        u = self._input(data)
        if not self.band_hz[1] > 0:
            raise ConfigError(f"feature spec '{self.spec}': coh and modal_* need the band of "
                              "a baseline test (FeatureSet.fit_reference with fs_hz)")
        if name == "coh":
            frf = _frf.estimate(u, {c: data[c] for c in t.channels}, fs_hz)
            return [float(v) for v in _frf.band_coherence(frf, self.band_hz)]
        g = _MODAL.match(name)
        assert g is not None
        kind, n = g.group(1), int(g.group(2))
        key = (t.channels, n)
        if key not in cache:
            cache[key] = _modal.record_modes(u, {c: data[c] for c in t.channels}, fs_hz,
                                             self.band_hz, n)
        modes = cache[key]
        if modes is None or modes.f_hz.size < n:
            return [float("nan")] * n
        if kind == "mac":
            return [float(v) for v in _modal.paired_mac(modes, self.modal_ref[key])]
        return [float(v) for v in (modes.f_hz if kind == "f" else modes.zeta)[:n]]

    def extract(self, data: Mapping[str, np.ndarray], fs_hz: float,
                u: np.ndarray | None = None) -> np.ndarray:
        """The feature vector of one record (channel -> samples), through the C core; u: the
        input, when data (a simulation's outputs) lacks it."""
        if not self.resolved:
            raise ConfigError("FeatureSet.extract before resolve()")
        if u is not None and self.input_channel:
            data = {**data, self.input_channel: u}
        u_rec = data.get(self.input_channel)
        out: list[float] = []
        cache: dict[str, tuple[_feat.Stats, _feat.Temporal | None]] = {}
        modal: dict[tuple[tuple[str, ...], int], _modal.Modes | None] = {}
        for t in self.terms:
            for name in t.names:
                if name == "coh" or _MODAL.match(name):
                    out += self._io_features(t, name, data, fs_hz, modal)
                    continue
                for c in t.channels:
                    x = data[c]
                    if name in _cat.TERMS:
                        if _cat.TERMS[name].ref and c not in self.ref_data:
                            raise ConfigError(f"feature '{name}@{c}' compares with a reference "
                                              "record: FeatureSet.fit_reference first")
                        ref = (self.alt_data[c] if self._is_ref(c, x, u_rec)
                               else self.ref_data.get(c, x))
                        out.append(_cat.TERMS[name].value(x, fs_hz, ref))
                        continue
                    if name in BASIC or name in TEMPORAL:
                        if c not in cache:
                            cache[c] = (_feat.moments(x), None)
                        st, tm = cache[c]
                        if name in BASIC:
                            out.append(float(getattr(st, name)))
                            continue
                        if tm is None:
                            tm = _feat.temporal(x, 1.0 / fs_hz)
                            cache[c] = (st, tm)
                        out.append(float(getattr(tm, TEMPORAL[name])))
                        continue
                    g = _SEG.match(name)
                    if g is not None:
                        out.extend(segment_std(x, int(g.group(1))).tolist())
                        continue
                    g = _AR.match(name)
                    if g is not None:
                        p = int(g.group(1) or AR_DEFAULT_ORDER)
                        mdl = ((self.ar_alt.get((c, p)) if self._is_ref(c, x, u_rec) else None)
                               or self.ar_ref.get((c, p)) or _ar.burg(x, p))
                        e = _ar.ar_residual(mdl, x)
                        out.append(float(np.sqrt(np.mean(e * e))) if e.size else float("nan"))
        return np.asarray(out, dtype=np.float64)


def segment_std(x: np.ndarray, n_seg: int) -> np.ndarray:
    """Population STD of n_seg equal consecutive segments (trailing samples dropped), by the
    C core's dv_moments block update on each segment (the numbers of dv_segstd)."""
    seg = x.size // n_seg
    if seg < 1:
        raise ConfigError(f"segstd{n_seg} needs at least {n_seg} samples, got {x.size}")
    return np.array([_feat.moments(x[i * seg:(i + 1) * seg]).std for i in range(n_seg)])


def parse(spec: str) -> FeatureSet:
    """Parse a feature spec (see the module doc). Unknown names raise ConfigError listing the
    valid ones."""
    s = re.sub(r"\s+", "", spec)
    if not s:
        raise ConfigError("empty feature spec (e.g. 'peak,std@acc3,acc4')")
    terms = []
    for part in re.split(r"[+;]", s):
        if part.count("@") != 1:
            raise ConfigError(f"feature spec term '{part}': expected NAMES@CHANNELS, e.g. "
                              "'peak,std@acc3,acc4'")
        names_s, chans_s = part.split("@")
        names = tuple(n for n in names_s.split(",") if n)
        chans = tuple(c for c in chans_s.split(",") if c)
        if not names or not chans:
            raise ConfigError(f"feature spec term '{part}': needs names and channels")
        for n in names:
            _check_name(n)
        terms.append(Term(names, chans))
    return FeatureSet(spec, tuple(terms))
