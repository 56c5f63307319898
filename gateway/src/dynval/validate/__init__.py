"""Offline model validation (report Section 6): feature vectors by name, Mahalanobis distance
against an experimental baseline, designs of experiments run through the C model, ANOVA R^2
sensitivity, PCA, Bayesian calibration (GP emulator + MCMC, or MCMC on the C model) and
JSON/HTML reports. Every feature is computed by the C core the firmware runs."""
from __future__ import annotations
