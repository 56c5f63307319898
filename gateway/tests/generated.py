"""What the project's generator (dynval.synth) puts in every test besides the effects a test
asks for: its DAQ's anti-alias filter (8th-order Butterworth at 0.4 fs), which discover finds
beside a nonlinear element (the daq_filter effect). One definition for the discover tests."""
from __future__ import annotations

from typing import Any


def sought(effects: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """discover's effect entries without a DAQ filter it found (the generator's own)."""
    return [e for e in effects if e["type"] != "daq_filter"]
