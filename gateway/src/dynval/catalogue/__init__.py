"""The reference report's Section 5 feature catalogue beyond the C core's streaming features,
offline on numpy/scipy: FRF, coherence and the linearity/reciprocity checks (frf.py, 5.3.1),
experimental and numerical modal analysis with the MAC (modal.py, 5.1)."""
