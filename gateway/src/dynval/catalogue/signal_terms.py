"""The waveform and spectral catalogue as `dynval validate` feature names (validate.featvec):
each name is one scalar per channel. Names marked ``ref`` compare the record with the
reference record of that channel (the first baseline test, FeatureSet.fit_reference), the
report's 'metric to compare' two high-dimensional features."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dynval.catalogue import holder, spectral, waveform


@dataclass(frozen=True)
class SignalTerm:
    value: Callable[[np.ndarray, float, np.ndarray], float]
    ref: bool  # compares with the reference record
    doc: str


def _srs(i: int) -> Callable[[np.ndarray, float, np.ndarray], float]:
    def f(x: np.ndarray, fs: float, ref: np.ndarray) -> float:
        return spectral.db_distance(spectral.response_spectrum(x, fs)[i],
                                    spectral.response_spectrum(ref, fs)[i])
    return f


def _holder_drops(x: np.ndarray, fs: float, _ref: np.ndarray) -> float:
    return float(holder.drops_of(x, fs).count)


def _holder_min(x: np.ndarray, _fs: float, _ref: np.ndarray) -> float:
    ok = holder.readable(x)
    return float(np.min(holder.holder_exponent(x)[ok])) if ok.any() else float("nan")


TERMS: dict[str, SignalTerm] = {
    "ks": SignalTerm(lambda x, fs, r: waveform.pdf_distance(x, r, "ks"), True,
                     "Kolmogorov-Smirnov distance of the amplitude distributions (5.2.2)"),
    "ad": SignalTerm(lambda x, fs, r: waveform.pdf_distance(x, r, "ad"), True,
                     "Anderson-Darling k-sample statistic of the amplitudes (5.2.2)"),
    "d10": SignalTerm(lambda x, fs, r: waveform.duration10(x, fs), False,
                      "10 % duration, s (5.2.4)"),
    "decay": SignalTerm(lambda x, fs, r: waveform.decay_fit(x, fs)[1], False,
                        "decay constant a of y0 exp(a t), 1/s (5.2.4)"),
    "decay_y0": SignalTerm(lambda x, fs, r: waveform.decay_fit(x, fs)[0], False,
                           "intercept y0 of y0 exp(a t) (5.2.4)"),
    "acf_corr": SignalTerm(lambda x, fs, r: waveform.acf_corr(x, r), True,
                           "correlation coefficient of the autocorrelation functions (5.2.6)"),
    "harm_n": SignalTerm(lambda x, fs, r: float(spectral.harmonic_peaks(x, fs).count), False,
                         "number of harmonic peaks of a harmonic test (5.3.2)"),
    "thd": SignalTerm(lambda x, fs, r: spectral.harmonic_peaks(x, fs).thd_db, False,
                      "total harmonic distortion, dB (5.3.2)"),
    "srs_peak": SignalTerm(_srs(1), True, "dB distance of the peak response spectra (5.3.3)"),
    "srs_rms": SignalTerm(_srs(2), True, "dB distance of the RMS response spectra (5.3.3)"),
    "cep_env": SignalTerm(lambda x, fs, r: spectral.cepstral_distance(x, r, fs), True,
                          "liftered log spectrum above the reference's at its peaks, dB (5.3.4)"),
    "holder_drops": SignalTerm(_holder_drops, False,
                               "number of drop-offs of the Holder exponent (5.3.5)"),
    "holder_min": SignalTerm(_holder_min, False, "lowest Holder exponent (5.3.5)"),
}
