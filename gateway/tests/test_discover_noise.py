"""The noise floor from what the data offers (issue 16, item 4): each method against noise of
known RMS, and coloured noise through a gentle anti-alias filter, where the top band alone
reads several times too low."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import signal

from dynval.discover import noise as nz

FS = 640.0
N = 8192
BAND = (20.0, 200.0)
# noise power left in a swept input, the sweep's ramp-in skirt it takes under the band
# counted (measured 0.30 and 0.30; 0.18 and 0.27 with the former high-pass capped an octave
# under the band, which left the noise an octave under a cut sweep's band: test below)
MEASURED_LEFT = {"logarithmic": 0.35, "linear": 0.35}


@dataclass
class T:
    name: str
    u: np.ndarray
    y: dict[str, np.ndarray] = field(default_factory=dict)
    fs_hz: float = FS


def structure(u: np.ndarray) -> np.ndarray:
    """A lightly damped resonance at 60 Hz (what the structure does to the input)."""
    w = 2 * math.pi * 60 / FS
    return signal.lfilter([0.05], [1, -2 * 0.99 * math.cos(w), 0.99 ** 2], u)


def band_input(rng: np.random.Generator) -> np.ndarray:
    sos = signal.butter(4, [BAND[0], BAND[1]], btype="band", fs=FS, output="sos")
    return signal.sosfilt(sos, rng.standard_normal(N))


def pink(rng: np.random.Generator, n: int) -> np.ndarray:
    """1/f noise (spectral shaping of white noise), unit RMS."""
    x = np.fft.rfft(rng.standard_normal(n))
    f = np.arange(x.size, dtype=float)
    f[0] = 1.0
    p = np.fft.irfft(x / np.sqrt(f), n)
    return p / np.std(p)


def cheap_daq(recs: list[Any], rng: np.random.Generator, offset: float, hum: float) -> None:
    """A cheap DAQ on every channel of the records: 1/f + white noise (level: 1 % of the
    channel's STD) behind a 2nd-order anti-alias filter at 0.4 fs, 50 Hz hum of ``hum`` x
    that level, and on each output an offset of ``offset`` x its STD x (its index + 1)."""
    fs = recs[0].fs_hz
    sos = signal.butter(2, 0.4 * fs, fs=fs, output="sos")
    t = np.arange(recs[0].n_samples) / fs
    for rec in recs:
        for k, ch in enumerate(rec.channels):
            lv = 0.01 * float(np.std(ch.data))
            n = signal.sosfilt(sos, lv * (2 * pink(rng, ch.data.size)
                                          + rng.standard_normal(ch.data.size)))
            off = offset * float(np.std(ch.data)) * (k + 1) if ch.role == "output" else 0.0
            ch.data = ch.data + n + hum * lv * np.sin(2 * np.pi * 50 * t + k) + off


def test_white_noise_reads_the_same_out_of_band_and_in_the_top_band() -> None:
    rng = np.random.default_rng(1)
    res = [0.02 * rng.standard_normal(N) for _ in range(3)]
    fl = nz.spectral(res, FS, BAND)
    assert fl.method == "out of band"
    assert fl.rms == pytest.approx(0.02, rel=0.1)
    wide = nz.spectral(res, FS, (0.5, 300.0))  # no room beside the band: the top band
    assert wide.method == "top band" and wide.rms == pytest.approx(0.02, rel=0.1)


@pytest.mark.parametrize(("order", "pink_rms", "white_rms"),
                         [(0, 0.02, 0.005), (2, 0.02, 0.005), (2, 0.0, 0.02), (8, 0.02, 0.0)])
def test_coloured_noise_behind_an_anti_alias_filter_is_read_within_1p6x(
        order: int, pink_rms: float, white_rms: float) -> None:
    rng = np.random.default_rng(order + 10)
    res = [pink_rms * pink(rng, N) + white_rms * rng.standard_normal(N) for _ in range(3)]
    if order:  # the DAQ's anti-alias filter at 0.4 fs (a cheap one: 2nd order)
        sos = signal.butter(order, 0.4 * FS, fs=FS, output="sos")
        res = [signal.sosfilt(sos, r) for r in res]
    true = float(np.sqrt(np.mean(np.concatenate(res) ** 2)))
    top_only = math.sqrt(np.median([
        np.median(p[(f >= 0.45 * FS)]) * FS / 2
        for f, p in (signal.welch(r, fs=FS, nperseg=1024) for r in res)]))
    assert top_only < true / 2.5  # the old estimate: several times too low
    fl = nz.spectral(res, FS, BAND)
    assert fl.method == "out of band"
    assert true / 1.6 < fl.rms < 1.6 * true  # measured 0.86-1.55 x


@pytest.mark.parametrize("f_mode", [12.0, 14.0])
def test_a_model_error_at_a_mode_under_the_band_is_not_read_as_noise(f_mode: float) -> None:
    """A mode under the input band (the input's skirt drives it) that the model places 4 %
    off: its residual there (13-21 x the noise's RMS over the record) is a model error, narrow
    and tall. Read beside the model's modes, the floor is the sensor's white noise within
    1.3 x (measured 0.99, 1.03); taken as noise it read 7.5-14 x (blind two-effect 432: 23-30
    x, and discover answered "no effect")."""
    rng = np.random.default_rng(int(f_mode))

    def mode(u: np.ndarray, f_hz: float) -> np.ndarray:
        w, r = 2 * math.pi * f_hz / FS, 1 - 2 * math.pi * 0.013 * f_hz / FS
        return signal.lfilter([1.0], [1, -2 * r * math.cos(w), r * r], u)

    noise = [0.002 * rng.standard_normal(N) for _ in range(3)]
    inputs = [band_input(rng) for _ in range(3)]
    res = [0.002 * (mode(u, f_mode) - mode(u, 1.04 * f_mode)) + e
           for u, e in zip(inputs, noise, strict=True)]
    true = float(np.sqrt(np.mean(np.concatenate(noise) ** 2)))
    beside = nz.spectral(res, FS, BAND, inputs, modes_hz=(f_mode, 45.0, 90.0))
    assert beside.method == "out of band"
    assert true / 1.3 < beside.rms < 1.3 * true
    assert nz.spectral(res, FS, BAND, inputs).rms > 5 * true  # the model's modes not given


def test_repeated_input_gives_the_noise_whatever_the_structure_does() -> None:
    rng = np.random.default_rng(4)
    u = band_input(rng)
    clean = structure(u) + 0.3 * structure(u) ** 3  # nonlinear, but the same twice
    tests = [T(f"r{i}", u.copy(), {"a": clean + 0.01 * rng.standard_normal(N)})
             for i in range(3)]
    fl = nz.from_repeats(tests, "a")
    assert fl is not None and fl.method == "repeats"
    assert fl.rms == pytest.approx(0.01, rel=0.05)
    other = T("x", band_input(rng), {"a": np.zeros(N)})
    assert nz.from_repeats([tests[0], other], "a") is None  # different inputs: no pair


def test_periodic_input_gives_the_noise_from_period_differences() -> None:
    rng = np.random.default_rng(5)
    period = 512
    one = band_input(rng)[:period]
    u = np.tile(one, N // period)
    y = structure(u) + 0.01 * rng.standard_normal(N)
    assert nz.period_of(u) == period
    fl = nz.from_periods([T("p", u, {"a": y})], "a")
    assert fl is not None and fl.rms == pytest.approx(0.01, rel=0.05)
    assert nz.period_of(band_input(rng)) is None


def test_input_off_stretches_give_the_noise_after_the_ringing() -> None:
    rng = np.random.default_rng(6)
    u = band_input(rng)
    u[: 2 * int(FS)] = 0.0  # pre-trigger: 2 s
    u[-3 * int(FS):] = 0.0  # run-out: 3 s, the structure rings for the first of them
    y = structure(u) + 0.01 * rng.standard_normal(N) + 0.5  # an offset is not noise
    fl = nz.from_input_off([T("q", u, {"a": y})], "a", settle_s=1.0)
    assert fl is not None and fl.method == "input off"
    assert fl.rms == pytest.approx(0.01, rel=0.05)
    assert nz.from_input_off([T("r", band_input(rng), {"a": y})], "a", 1.0) is None


def test_estimate_prefers_stated_then_repeats_and_says_so() -> None:
    rng = np.random.default_rng(7)
    u = band_input(rng)
    tests = [T(f"r{i}", u, {"a": structure(u) + 0.01 * rng.standard_normal(N),
                            "b": structure(u) + 0.02 * rng.standard_normal(N)})
             for i in range(2)]
    res = {t.name: {c: t.y[c] - structure(u) for c in "ab"} for t in tests}
    fl = nz.estimate(tests, ["a", "b"], res, BAND, 1.0, stated={"b": 0.5})
    assert fl["a"].method == "repeats" and fl["a"].rms == pytest.approx(0.01, rel=0.1)
    assert fl["b"].method == "stated" and fl["b"].rms == 0.5


def stories(x: np.ndarray, i: int) -> np.ndarray:
    """What sensor i of a structure sees of a force x: resonances at 45 and 110 Hz, in a
    proportion that differs per sensor."""
    out = np.zeros_like(x)
    for f0, gain in ((45.0, 1.0 + i), (110.0, 2.0 - 0.4 * i)):
        w = 2 * math.pi * f0 / FS
        out += gain * signal.lfilter([0.05], [1, -2 * 0.99 * math.cos(w), 0.99 ** 2], x)
    return out


def test_cross_channel_reads_the_noise_where_an_effect_spreads_outside_the_band() -> None:
    """A missing stick-slip force (square-wave jumps: energy far outside the input band)
    reaches four sensors through the structure; each sensor adds its own 1/f + white noise.
    The out-of-band view counts the jumps' harmonics as noise (reads 2x and more); the
    channels' shared part is the effect, what each has alone the noise."""
    rng = np.random.default_rng(21)
    res, noise, inputs = [], [], []
    for _ in range(4):
        u = band_input(rng)
        slow = signal.sosfilt(signal.butter(2, 8.0, fs=FS, output="sos"), rng.standard_normal(N))
        jumps = 0.04 * np.sign(slow)  # stick-slip: the sign of a slow velocity
        own = {c: 0.004 * (i + 1) * (pink(rng, N) + rng.standard_normal(N))
               for i, c in enumerate("abcd")}
        res.append({c: stories(jumps, i) + own[c] for i, c in enumerate("abcd")})
        noise.append(own)
        inputs.append(u)
    shared = nz.cross_channel(res, inputs, "abcd", FS)
    assert shared is not None
    for c in "abcd":
        true = float(np.sqrt(np.mean(np.concatenate([n[c] for n in noise]) ** 2)))
        oob = nz.spectral([r[c] for r in res], FS, BAND).rms
        assert oob > 2 * true  # the out-of-band view: the jumps read as noise (2.2-2.8 x)
        assert math.sqrt(shared[c]) == pytest.approx(true, rel=0.15)  # measured 0.86-0.96 x
    assert nz.cross_channel([{c: r[c] for c in "ab"} for r in res], inputs, "ab", FS) is None


def test_the_input_sensors_noise_through_the_model_is_part_of_the_floor() -> None:
    """The right model driven by a measured input with sensor noise leaves that noise's
    response on every channel: shared, yet noise. It is added from the input's quiet band."""
    rng = np.random.default_rng(22)
    tests, res = [], []
    for k in range(4):
        u_true = band_input(rng)
        e_u = 0.01 * float(np.std(u_true)) * rng.standard_normal(N)
        u = u_true + e_u  # what the force sensor gives
        y = {c: stories(u_true, i) + 0.002 * rng.standard_normal(N)
             for i, c in enumerate("abc")}
        pred = {c: stories(u, i) for i, c in enumerate("abc")}
        tests.append(T(f"t{k}", u, y))
        res.append({c: y[c] - pred[c] for c in "abc"})
    fl = nz.estimate(tests, list("abc"), {str(id(t.u)): r for t, r in zip(tests, res, strict=True)},
                     BAND, 1.0)
    for c in "abc":
        true = float(np.sqrt(np.mean(np.concatenate([r[c] for r in res]) ** 2)))
        assert fl[c].method == "cross-channel"
        assert fl[c].rms == pytest.approx(true, rel=0.15)
        without = nz.cross_channel(res, [t.u for t in tests], "abc", FS)
        assert without is not None and math.sqrt(without[c]) < 0.7 * true


def test_mains_hum_is_a_steady_tone_not_a_resonance_at_60_hz() -> None:
    """Mains hum is noise a right model leaves; a resonance of the residual that sits at
    60 Hz (a mode an effect moved, driven by the random input) is not. Both stand 10 x above
    their surroundings in a 1024-point spectrum; in 0.1 Hz bins the tone stands far above its
    neighbours and the resonance (zeta 0.01: 1.2 Hz wide) does not. Before, the resonance was read
    as hum: a shake table with a cubic spring and a DOF unmeasured got a floor of 1.0-1.5
    m/s^2 against a true 0.05-0.07 and ended "no effect" at 790 x the ideal."""
    rng = np.random.default_rng(23)
    t = np.arange(N) / FS
    floor = [0.01 * rng.standard_normal(N) for _ in range(3)]
    inputs = [band_input(rng) for _ in range(3)]
    hum = [f + 0.05 * np.sin(2 * np.pi * 50.02 * t + k) for k, f in enumerate(floor)]
    power, lines = nz.mains_hum(hum, inputs, FS)
    assert lines == [50.0]
    assert power == pytest.approx(0.05 ** 2 / 2, rel=0.2)
    b, a = signal.iirpeak(60.0, 50.0, fs=FS)  # Q 50: zeta 0.01
    mode = [f + 0.3 * signal.lfilter(b, a, rng.standard_normal(N)) for f in floor]
    fc, pc = signal.welch(mode[0], fs=FS, nperseg=1024)
    k = int(round(60.0 / (fc[1] - fc[0])))
    assert pc[k] > nz.LINE_RATIO * float(np.median(pc[np.r_[k - 12:k - 2, k + 3:k + 13]]))
    assert max(nz.tone_contrast(r, FS, 60.0) for r in mode) < nz.TONE_CONTRAST
    assert min(nz.tone_contrast(r, FS, 50.0) for r in hum) > 5 * nz.TONE_CONTRAST
    assert nz.mains_hum(mode, inputs, FS) == (0.0, [])


def test_discover_on_a_cheap_daq_keeps_a_right_model_and_reads_its_noise() -> None:
    """A right model, tests with 1/f + white noise behind a 2nd-order anti-alias filter: the
    floor reads within 1.6x of the noise actually added (the top band read it 3-7x low, and
    discover then kept hunting), and no effect is claimed."""
    from dynval import model as mdl
    from dynval import synth as gen
    from dynval.discover import loop

    m = mdl.Model(masses_kg=(6.54, 6.66, 6.86, 6.80), stiffness_n_per_m=(10.0, 4e5, 4e5, 4e5),
                  damping=mdl.Damping("modal", (0.01, 0.05, 0.01, 0.01)),
                  input=mdl.Input("force", 1, "force_N"),
                  outputs={f"acc{i}_mps2": mdl.Output("acc", i) for i in range(1, 5)},
                  fs_hz=FS)
    rng = np.random.default_rng(91)
    recs = gen.generate(m, gen.Truth(), n_tests=4, seed=91, noise=0.0)
    sos = signal.butter(2, 0.4 * FS, fs=FS, output="sos")
    added: dict[str, list[np.ndarray]] = {}
    for rec in recs:
        for ch in rec.channels:
            if ch.role == "output":
                level = 0.01 * float(np.std(ch.data))
                n = signal.sosfilt(sos, level * (2 * pink(rng, ch.data.size)
                                                 + rng.standard_normal(ch.data.size)))
                ch.data = ch.data + n
                added.setdefault(ch.name, []).append(n)
    r = loop.discover(m, recs)
    assert r.effects == []
    # half the residual lies below the band (1/f noise), but within the floor: not a drift
    assert r.prediction == "open loop"
    for c in r.chans:
        true = float(np.sqrt(np.mean(np.concatenate(added[c]) ** 2)))
        assert r.noise_floors[c].method == "cross-channel"
        assert true / 1.6 < r.noise[c] < 1.6 * true, (c, r.noise[c], true)  # measured 0.77-0.84 x


def test_cli_noise_in_channel_units_and_a_wrong_channel(
        repo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from dynval import cli

    folder = repo / "data" / "lanl4dof-sim" / "clean"
    out = tmp_path / "d.json"
    args = ["-q", "discover", str(folder / "declared_model.json"), str(folder),
            "--max-effects", "0", "--json", str(out)]
    capsys.readouterr()
    assert cli.main([*args, "--noise", "acc2_mps2=0.04"]) == 0
    table = capsys.readouterr().out
    assert any(line.split()[:3] == ["channel", "unit", "held-out"]  # the table's units
               for line in table.splitlines()), table
    assert any(line.split()[:2] == ["acc2_mps2", "m/s^2"] and line.split()[4] == "0.04"
               for line in table.splitlines()), table
    doc = json.loads(out.read_text())
    assert doc["noise_floor"]["acc2_mps2"] == 0.04
    assert doc["noise_method"]["acc2_mps2"]["method"] == "stated"
    assert doc["noise_method"]["acc1_mps2"]["method"] == "cross-channel"
    assert cli.main([*args, "--noise", "acc9=0.04"]) == 2
    assert cli.main([*args, "--noise", "acc2_mps2=-1"]) == 2


def _power(x: np.ndarray, lo: float, hi: float) -> float:
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    s = np.abs(np.fft.rfft(x)) ** 2
    return float(np.sum(s[(f > lo) & (f < hi)]))


@pytest.mark.parametrize("seed", [31, 32, 33])
def test_a_band_limited_inputs_sensor_noise_under_the_band_is_taken_out(seed: int) -> None:
    """A 20-200 Hz force read by a sensor with 1/f and white noise (1 % of its RMS each): under
    the band the measured force is noise; 95 % of its power below 8 Hz goes, with its mean,
    while the band keeps its content to 0.1 % of its power."""
    rng = np.random.default_rng(seed)
    u_true = band_input(rng)
    lv = 0.01 * float(np.std(u_true))
    u = u_true + lv * (2 * pink(rng, N) + rng.standard_normal(N))
    fc = nz.sub_band_corner(u, FS)
    assert fc is not None and 5.0 < fc < BAND[0]
    clean = nz.without_sub_band_noise(u, FS)
    assert _power(clean, 0.0, 8.0) < 0.05 * _power(u, 0.0, 8.0)
    assert abs(np.mean(clean)) < 0.05 * abs(np.mean(u))
    assert _power(clean - u, 25.0, 190.0) < 1e-3 * _power(u_true, 25.0, 190.0)


def test_an_input_with_content_down_to_dc_or_a_real_static_force_is_kept() -> None:
    """Broadband (white) and 1-200 Hz inputs have no noise-only band under them: unchanged. A
    static force ten times the slow noise is a force, not the sensor's mean: kept."""
    rng = np.random.default_rng(34)
    white = rng.standard_normal(N)
    assert nz.sub_band_corner(white, FS) is None
    assert nz.without_sub_band_noise(white, FS) is white
    sos = signal.butter(4, [1.0, 200.0], btype="band", fs=FS, output="sos")
    low = signal.sosfilt(sos, rng.standard_normal(N))
    assert nz.sub_band_corner(low, FS) is None
    u = band_input(rng)
    lv = 0.01 * float(np.std(u))
    slow_noise = lv * 2 * pink(rng, N)
    pre = 10 * float(np.std(slow_noise))
    clean = nz.without_sub_band_noise(u + slow_noise + pre, FS)
    assert np.mean(clean) == pytest.approx(pre + np.mean(u + slow_noise), rel=1e-2)


@pytest.mark.parametrize("f_hz", [3.1, 10.0, 54.0])
def test_a_sine_inputs_tone_is_kept_whole(f_hz: float) -> None:
    """A sine test read by a sensor with 1/f and white noise: under the tone the input is noise
    (taken out), the tone itself keeps its amplitude to 0.5 % (the high-pass stays an octave
    under the band: a tone's leakage reaches the floor a few bins from it)."""
    rng = np.random.default_rng(35)
    t = np.arange(N) / FS
    tone = np.sin(2 * np.pi * f_hz * t)
    u = tone + 0.01 * (2 * pink(rng, N) + rng.standard_normal(N))
    clean = nz.without_sub_band_noise(u, FS)
    mid = slice(N // 8, -N // 8)  # away from the records' ends
    amp = float(np.dot(clean[mid], tone[mid]) / np.dot(tone[mid], tone[mid]))
    assert amp == pytest.approx(1.0, abs=0.005)


def test_sub_band_cleaning_leaves_an_input_it_cannot_judge_alone() -> None:
    """A record with a NaN (the core counts and holds those), a short one, and huge finite
    values: no corner is claimed where the spectrum cannot be read, the input stays as it is."""
    rng = np.random.default_rng(36)
    u = band_input(rng) + 0.01 * pink(rng, N)
    bad = u.copy()
    bad[100] = np.nan
    assert nz.sub_band_corner(bad, FS) is None and nz.without_sub_band_noise(bad, FS) is bad
    short = u[:512]
    assert nz.without_sub_band_noise(short, FS) is short
    huge = nz.without_sub_band_noise(u * 1e150, FS)
    assert np.all(np.isfinite(huge))
    np.testing.assert_allclose(huge / 1e150, nz.without_sub_band_noise(u, FS), rtol=1e-9,
                               atol=1e-9 * np.std(u))


@pytest.mark.parametrize("method", ["logarithmic", "linear"])
def test_a_sweeps_input_noise_between_its_passes_is_taken_out(method: str) -> None:
    """A 10-220 Hz swept sine read by a sensor with 1/f and white noise (1 % of its RMS each):
    at each frequency the sweep passes once, and the rest of the record there is the sensor's
    noise, which would drive every mode of the simulations all along. The idle cells go
    (noise.idle_gain): the noise left is at most MEASURED_LEFT of it, the sweep keeps its
    content to 1e-5 of its power (measured 9e-7); a band-limited random or a steady sine
    input (no frequency switched on and off) passes unchanged."""
    from dynval import synth

    rng = np.random.default_rng(37)
    u_true = synth.excitation_force(synth.Sweep(10.0, 220.0, method), rng, N, FS, 1.0)
    noise = 0.01 * (2 * pink(rng, N) + rng.standard_normal(N))
    g = nz.idle_gain(u_true + noise, FS)
    assert g is not None
    left = nz.simulated_input("force", u_true + noise, FS) - u_true
    assert np.var(left) < MEASURED_LEFT[method] * np.var(noise)
    kept = nz._gated(u_true, FS, g)  # the same gain on the sweep alone: its content stays
    assert np.var(kept - u_true) < 1e-5 * np.var(u_true)
    assert nz.idle_gain(band_input(rng) + noise, FS) is None
    tone = np.sin(2 * np.pi * 54.0 * np.arange(N) / FS)
    assert nz.idle_gain(tone + noise, FS) is None
    assert nz.idle_gain(np.full(N, np.nan), FS) is None
    huge = nz.simulated_input("force", (u_true + noise) * 1e150, FS)
    np.testing.assert_allclose(huge / 1e150, nz.simulated_input("force", u_true + noise, FS),
                               atol=1e-9)


def test_a_record_is_carried_on_past_its_end_unless_silent_or_growing() -> None:
    """A steady tone is carried on past the record's end as it goes (1e-9 over the first
    half, before the fade); an end that is silent, or a prediction that grows past
    EDGE_GROWTH x the end (a tone growing 24 x over the extension), gives the plain zero
    padding; no warning either way."""
    t = np.arange(N) / FS
    e = 1024
    after = (N + np.arange(e // 2)) / FS
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tone = np.sin(2 * np.pi * 37.3 * t + 0.4)
        carried = nz._carried_on(tone, e)
        assert np.max(np.abs(carried[:e // 2] - np.sin(2 * np.pi * 37.3 * after + 0.4))) < 1e-9
        silent = tone.copy()
        silent[-3 * e:] = 0.0
        assert not np.any(nz._carried_on(silent, e))
        growing = np.exp(2.0 * t) * np.sin(2 * np.pi * 20.0 * t)
        assert not np.any(nz._carried_on(growing, e))


def _mode_response(x: np.ndarray, f_hz: float, zeta: float = 0.02) -> np.ndarray:
    """x through a single mode at f_hz (bilinear twin of 1 / (1 + 2 zeta s/w + s^2/w^2))."""
    w = 2 * np.pi * f_hz
    b, a = signal.bilinear([1.0], [1 / w**2, 2 * zeta / w, 1.0], fs=FS)
    return np.asarray(signal.lfilter(b, a, x))


@pytest.mark.parametrize("method", ["linear", "logarithmic"])
@pytest.mark.parametrize("seed", [41, 42, 43])
def test_a_cut_sweeps_input_noise_under_its_band_does_not_drive_a_mode_there(
        seed: int, method: str) -> None:
    """The second half of a 10-220 Hz sweep (a record cut from a run: its band starts at
    60-120 Hz) read by a sensor with 1/f and white noise: a mode at 0.6 and 0.8 x the band's
    lower edge, driven by the cleaned input, is off the one driven by the true force by at
    most a quarter of what the raw measured input puts there (measured 0.03-0.20; 0.78-0.93
    with the former high-pass capped an octave under the band), after the start-up. Over
    its first 0.8 s, the record's sudden start, the cleaned input is off the true force by at
    most 1.2 x the raw noise (measured 0.69-1.04; 3.3-4.6 with the record zero-padded instead
    of carried on past its ends)."""
    from dynval import synth

    rng = np.random.default_rng(seed)
    u_true = synth.excitation_force(synth.Sweep(10.0, 220.0, method), rng, 2 * N, FS, 1.0)[N:]
    u = u_true + 0.01 * (2 * pink(rng, N) + rng.standard_normal(N))
    clean = nz.without_sub_band_noise(u, FS)
    f, p = signal.welch(u_true, fs=FS, nperseg=1024)
    edge = float(f[np.searchsorted(np.cumsum(p) / p.sum(), 0.01)])
    start = slice(0, 512)
    assert np.std((clean - u_true)[start]) < 1.2 * np.std((u - u_true)[start])
    late = slice(N // 2, None)
    for f_mode in (0.6 * edge, 0.8 * edge):
        truth = _mode_response(u_true, f_mode)[late]
        raw = np.std(_mode_response(u, f_mode)[late] - truth)
        assert np.std(_mode_response(clean, f_mode)[late] - truth) < 0.25 * raw


@pytest.mark.parametrize("n", [5, 6, 513, 1025])
def test_the_running_median_is_the_median_of_each_five_bins(n: int) -> None:
    p = np.random.default_rng(n).random(n)
    expected = [np.median(p[max(0, i - 2):i + 3]) for i in range(n)]
    assert np.array_equal(nz._median5(p), expected)


def _band_noise(rng: np.random.Generator, n: int, fs: float, lo: float, hi: float
                ) -> np.ndarray:
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec[(f < lo) | (f > hi)] = 0.0
    return np.fft.irfft(spec, n)


def test_mains_hum_outside_the_input_band_is_taken_out_of_the_input() -> None:
    """A force measured with 50 Hz pick-up (2 % of its RMS, 0.03 Hz off) and a 100 Hz one,
    its excitation at 90-160 Hz: the 50 Hz sine is taken out to 1 % of its amplitude and
    the rest is untouched beyond that; the 100 Hz line lies in the band and stays."""
    fs, n = 640.0, 16384
    rng = np.random.default_rng(3)
    force = _band_noise(rng, n, fs, 90.0, 160.0)
    force /= np.std(force)
    t = np.arange(n) / fs
    hum = 0.02 * np.sqrt(2) * np.sin(2 * np.pi * 50.03 * t + 0.7)
    tone100 = 0.02 * np.sqrt(2) * np.sin(2 * np.pi * 100.0 * t)
    sensor = 1e-3 * rng.standard_normal(n)
    u = force + hum + tone100 + sensor
    clean = nz.without_mains(u, fs)
    left = clean - (force + tone100 + sensor)
    assert np.std(left) < 0.01 * np.std(hum)
    assert np.std(clean - u + hum) < 0.01 * np.std(hum)


@pytest.mark.parametrize("units", [1e-300, 1e-150, 1e150, 1e300])
def test_mains_hum_comes_out_the_same_in_any_units(units: float) -> None:
    """The same hummed force in units 1e-300 to 1e300 times larger: the hum is found and
    taken out to the same relative level (1 %), with no overflow or underflow warning."""
    fs, n = 640.0, 16384
    rng = np.random.default_rng(5)
    force = _band_noise(rng, n, fs, 90.0, 160.0)
    force /= np.std(force)
    hum = 0.02 * np.sqrt(2) * np.sin(2 * np.pi * 50.0 * np.arange(n) / fs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        clean = nz.without_mains((force + hum) * units, fs)
    assert np.all(np.isfinite(clean))
    assert np.std(clean / units - force) < 0.01 * np.std(hum)


@pytest.mark.parametrize("bad", ["nan", "inf", "zero", "short"])
def test_an_input_hum_cannot_be_judged_on_is_returned_as_it_is(bad: str) -> None:
    """A force with a NaN or an inf sample, all zeros, or shorter than a spectrum segment:
    returned unchanged (the same array), no warning, no exception."""
    fs = 640.0
    t = np.arange(8192) / fs
    u = 0.1 * np.sin(2 * np.pi * 50.0 * t) + np.sin(2 * np.pi * 120.0 * t)
    if bad == "nan":
        u[100] = np.nan
    elif bad == "inf":
        u[100] = -np.inf
    elif bad == "zero":
        u[:] = 0.0
    else:
        u = u[:1000]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert nz.without_mains(u, fs) is u


def test_an_input_with_no_line_outside_its_band_is_kept() -> None:
    """Band-limited noise over 5-250 Hz with 50 Hz hum inside it, and a pure 50 Hz stepped
    sine (its band is the line): the input is returned as it is."""
    fs, n = 640.0, 8192
    rng = np.random.default_rng(4)
    t = np.arange(n) / fs
    wide = _band_noise(rng, n, fs, 5.0, 250.0) + 0.02 * np.sin(2 * np.pi * 50.0 * t)
    assert nz.without_mains(wide, fs) is wide
    stepped = np.sin(2 * np.pi * 50.0 * t) + 1e-3 * rng.standard_normal(n)
    assert nz.without_mains(stepped, fs) is stepped


def test_the_report_says_the_inputs_hum_was_taken_out() -> None:
    """discover's notes name the hum line and the tests it was taken out of."""
    from types import SimpleNamespace

    from dynval import model as mdl
    from dynval.discover import session

    fs, n = 640.0, 8192
    rng = np.random.default_rng(5)
    t = np.arange(n) / fs
    quiet = _band_noise(rng, n, fs, 90.0, 160.0)
    hummed = quiet + 0.02 * np.std(quiet) * np.sin(2 * np.pi * 50.0 * t)
    tests = [SimpleNamespace(name=f"t{i}", u=u, fs_hz=fs) for i, u in enumerate((hummed, quiet))]
    m = mdl.Model(masses_kg=(1.0,), stiffness_n_per_m=(1e5,),
                  damping=mdl.Damping("modal", (0.02,)), input=mdl.Input("force", 1, "f"),
                  outputs={"a1": mdl.Output("acc", 1)}, fs_hz=fs)
    notes = session.sub_band_note(m, tests)  # type: ignore[arg-type]
    assert any("mains hum at 50 Hz (1 of 2 tests)" in x for x in notes)
    assert not any("mains" in x for x in session.sub_band_note(m, tests[1:]))  # type: ignore[arg-type]
