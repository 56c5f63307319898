"""Readers for recorded tests. Every reader returns a Recording; bad input raises
InputFileError naming the file, line and column (or, with lenient=True, recoverable problems
are counted in Recording.warnings and logged — never silently dropped)."""
from __future__ import annotations

from pathlib import Path

from dynval.io.csvfile import read_csv
from dynval.io.recording import Channel, Recording

__all__ = ["Channel", "Recording", "read_csv", "read_test"]


def read_test(path: Path | str, *, lenient: bool = False) -> Recording:
    """Read a recorded test, choosing the reader from the file's suffix."""
    p = Path(path)
    if p.suffix.lower() == ".csv":
        return read_csv(p, lenient=lenient)
    from dynval.errors import InputFileError

    raise InputFileError(p, f"unknown test file type '{p.suffix}' (supported: .csv)")
