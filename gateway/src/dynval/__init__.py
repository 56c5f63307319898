"""dynval: structural-dynamics model validation around one C core.

The numbers come from the C library (``dynval._core``); this package reads tests, drives the
core over numpy arrays, talks to CAN buses, logs MCAP and writes reports.
"""
from __future__ import annotations

__version__ = "0.1.0"
