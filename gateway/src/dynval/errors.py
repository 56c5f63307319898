"""The exceptions of dynval. The CLI maps every DynvalError to exit code 2 and one log line."""
from __future__ import annotations

from pathlib import Path
from typing import Any


def short_repr(v: Any, limit: int = 40) -> str:
    """A value as an error message quotes it: its repr, cut to ``limit`` characters (a
    file's 'number' can be a megabyte of text)."""
    r = repr(v)
    return r if len(r) <= limit else f"{r[:limit - 3]}..."


class DynvalError(Exception):
    """Base of every error dynval reports to a user."""


class CoreError(DynvalError):
    """The C core returned an error status."""

    def __init__(self, func: str, status: int, name: str) -> None:
        super().__init__(f"{func} failed: {name} ({status})")
        self.func = func
        self.status = status
        self.name = name


class CoreNotBuiltError(DynvalError):
    """The compiled core is missing from the installed package."""


class InputFileError(DynvalError):
    """A recorded test file is missing, truncated or malformed. Names file, line and column."""

    def __init__(self, path: Path | str, message: str, line: int | None = None,
                 column: str | None = None) -> None:
        where = str(path)
        if line is not None:
            where += f":{line}"
        if column is not None:
            where += f" (column {column})"
        super().__init__(f"{where}: {message}")
        self.path = Path(path)
        self.line = line
        self.column = column


class ConfigError(DynvalError):
    """A model, channel map or option is invalid."""
