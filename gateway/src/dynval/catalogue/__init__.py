"""The reference report's Section 5 feature catalogue beyond the C core's streaming features:
offline features on numpy/scipy, each with the low-dimensional metric `dynval validate` uses.
FRF, coherence and the linearity/reciprocity checks (frf.py, 5.3.1); experimental and
numerical modal analysis with the MAC (modal.py, 5.1); waveform, spectral and Hölder features
(waveform.py, spectral.py, holder.py; their grammar names in signal_terms.py); one figure per
feature (modal_plots.py, signal_plots.py)."""
