"""Reading JSON (and YAML) files whatever they hold: every way a file can be malformed
(not UTF-8, not JSON, nested too deeply, an integer too long for Python to convert, a number
beyond the float range) is an InputFileError naming the file, and the line and column where
the parser knows them. The one home of json.loads for files a user gives."""
from __future__ import annotations

import importlib
import json
import math
from pathlib import Path
from typing import Any

from dynval.errors import InputFileError


def decode_utf8(path: Path, raw: bytes) -> str:
    """raw as UTF-8 text (a leading BOM dropped); InputFileError with the line of the first
    byte that is not UTF-8."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputFileError(path, f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                             f"{exc.start})", line) from None


def read_text_file(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    return decode_utf8(path, raw)


def _no_infinity(s: str) -> float:
    v = float(s)
    if not math.isfinite(v):
        raise ValueError(f"number {s[:20]}{'...' if len(s) > 20 else ''} is beyond the "
                         "float range")
    return v


def parse_json(path: Path, text: str) -> Any:
    """text (the content of path) parsed; InputFileError for anything but valid JSON within
    the limits. NaN/Infinity literals are kept (readers decide about them); a number that
    overflows the float range is an error, not an infinity."""
    try:
        return json.loads(text, parse_float=_no_infinity)
    except json.JSONDecodeError as exc:
        raise InputFileError(path, f"not valid JSON ({exc.msg}; truncated file?)", exc.lineno,
                             f"char {exc.colno}") from None
    except RecursionError:
        raise InputFileError(path, "nested too deeply: not a dynval file") from None
    except ValueError as exc:  # int digits limit, a float beyond the range
        raise InputFileError(path, f"not a usable JSON number: {_short(exc)}") from None


def read_json(path: Path | str) -> Any:
    """A JSON file, parsed (see parse_json)."""
    p = Path(path)
    return parse_json(p, read_text_file(p))


def read_yaml(path: Path | str) -> Any:
    """A YAML file, parsed with yaml.safe_load; the same errors as read_json."""
    p = Path(path)
    text = read_text_file(p)
    yaml = importlib.import_module("yaml")
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise InputFileError(p, f"not valid YAML: {_short(exc)}",
                             None if mark is None else mark.line + 1,
                             None if mark is None else f"char {mark.column + 1}") from None
    except (RecursionError, ValueError, OverflowError) as exc:
        raise InputFileError(p, f"not a usable YAML file: {_short(exc)}") from None


def read_mapping_file(path: Path | str) -> Any:
    """JSON, or YAML for a .yaml/.yml suffix."""
    p = Path(path)
    return read_yaml(p) if p.suffix.lower() in (".yaml", ".yml") else read_json(p)


def _short(exc: BaseException, limit: int = 160) -> str:
    t = " ".join(str(exc).split())
    return t if len(t) <= limit else t[: limit - 3] + "..."
