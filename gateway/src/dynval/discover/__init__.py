"""`dynval discover`: find the residual of a declared model against measured tests, trace it
to the effect the model lacks, add the effect, and report the error before and after.

Modules: effects (the library of physical effects), residual (errors, noise floor,
Mahalanobis), trace (time/frequency traits, the restoring-force view and evidence), fit (least
squares through the C simulator), loop (the cross-validated loop), report (JSON + HTML).
Realistic measured tests with an undeclared effect, for tests and demos: dynval.synth."""
from __future__ import annotations

from dynval.discover.loop import DiscoverResult, Options, discover

__all__ = ["DiscoverResult", "Options", "discover"]
