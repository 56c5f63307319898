"""The fitting / held-out split of four tests or more (session.split). Inputs over one band
(random or swept tests) are sorted by RMS and dealt alternately; inputs at several
frequencies (a stepped sine) are paired with their nearest in median frequency and RMS, one
of each pair fitted and the other held out, so that every held-out test has a fitting test
like it and each set keeps the levels near one frequency."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from dynval.discover import session

FS = 640.0


def _sine(name: str, f_hz: float, amp: float, n: int = 4096) -> Any:
    t = np.arange(n) / FS
    return SimpleNamespace(name=name, fs_hz=FS, u=amp * np.sin(2 * np.pi * f_hz * t))


def _random(name: str, rms: float, seed: int, n: int = 4096) -> Any:
    return SimpleNamespace(name=name, fs_hz=FS,
                           u=rms * np.random.default_rng(seed).standard_normal(n))


def test_the_median_frequency_of_a_sine_and_of_white_noise() -> None:
    assert session.median_frequency(_sine("a", 55.0, 1.0).u, FS) == pytest.approx(55.0, abs=1.0)
    # white noise: half its power under fs / 4
    assert session.median_frequency(_random("b", 1.0, 1, 65536).u, FS) == pytest.approx(
        FS / 4, rel=0.03)


def test_tests_over_one_band_are_dealt_by_level() -> None:
    tests = [_random(f"t{i}", (12.0, 7.2)[i % 2] * (1 + 0.01 * i), i) for i in range(6)]
    fit, held, how = session.split(tests)
    order = sorted(tests, key=lambda t: float(np.std(t.u)))
    assert [t.name for t in fit] == [t.name for t in order[0::2]]
    assert [t.name for t in held] == [t.name for t in order[1::2]]
    assert "sorted by input RMS" in how


def test_a_stepped_sine_is_dealt_in_pairs_at_each_frequency() -> None:
    tests = [_sine(f"{f:.0f}Hz_{lv}", f, a) for f in (23.0, 26.0, 55.0, 60.0, 81.0)
             for lv, a in (("low", 8.0), ("high", 20.0))]
    fit, held, how = session.split(tests)
    fitted, kept = {t.name for t in fit}, {t.name for t in held}
    # neighbours at one level pair up (23 with 26, 55 with 60), the lone frequency's two
    # levels pair with each other: both sets hold both levels, and each held-out test has a
    # fitting test within 10 % of its frequency
    assert fitted == {"23Hz_low", "23Hz_high", "55Hz_low", "55Hz_high", "81Hz_low"}
    assert kept == {"26Hz_low", "26Hz_high", "60Hz_low", "60Hz_high", "81Hz_high"}
    assert "paired" in how
    # dealt by level alone, both 81 Hz records could go to one side
    assert not session.one_band(session.median_frequency(t.u, FS) for t in tests)
    assert session.one_band([100.0, 110.0, 124.0, 150.0])  # steps under 1.25 x: one band
    assert not session.one_band([100.0, 126.0])
