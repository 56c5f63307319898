"""The gateway-firmware contract, derived from the C sources and never restated here: every
DV_* / SIM_* object-like macro of firmware_sim/sim_core.h and the headers it includes
(sim_regmap.h: register map and model parameter offsets; dv_codec.h: CAN ids, commands, sample
packing), as the C preprocessor dumped them at build time (_lib/dv_contract.h, see
CMakeLists.txt), and the value tables of the DBC (can/dynval.dbc, copied to _lib/).
Parsed once, at import; a package without its build raises CoreNotBuiltError."""
from __future__ import annotations

import ast
import operator
import re
from collections.abc import Callable
from typing import Any

from dynval import _core

_DEFINE = re.compile(r"^#define ((?:DV|SIM)_\w+) (.+)$", re.M)  # not function-like: NAME(
_SUFFIX = re.compile(r"\b(0[xX][0-9a-fA-F]+|\d+\.?\d*(?:[eE][-+]?\d+)?)[uUlLfF]+\b")
_BINOPS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.LShift: operator.lshift, ast.RShift: operator.rshift,
    ast.BitOr: operator.or_, ast.BitAnd: operator.and_}


def parse_macros(text: str) -> dict[str, int | float]:
    """The numeric DV_*/SIM_* macros of `#define NAME VALUE` lines: C literals (suffixes u, l,
    f), names of other macros and + - * / << >> | & ( ). Anything else (types, casts,
    function-like macros) is left out."""
    raw = dict(_DEFINE.findall(text))
    out: dict[str, int | float] = {}

    def value(node: ast.expr) -> int | float:
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return node.value
        if isinstance(node, ast.Name):
            return macro(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
            v = value(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            a, b = value(node.left), value(node.right)
            if isinstance(node.op, ast.Div) and isinstance(a, int) and isinstance(b, int):
                return a // b  # C: integer division of integers
            return _BINOPS[type(node.op)](a, b)  # type: ignore[no-any-return]
        raise ValueError(ast.dump(node))

    def macro(name: str) -> int | float:
        if name not in out:
            expr = _SUFFIX.sub(r"\1", raw[name])
            out[name] = value(ast.parse(expr, mode="eval").body)
        return out[name]

    for name in list(raw):
        try:
            macro(name)
        except (SyntaxError, ValueError, KeyError, TypeError, RecursionError):
            out.pop(name, None)
    return out


def parse_dbc_values(text: str) -> dict[tuple[int, str], dict[int, str]]:
    """The DBC's value tables: (message id, signal) -> {value: name}."""
    out: dict[tuple[int, str], dict[int, str]] = {}
    for m in re.finditer(r"^VAL_ (\d+) (\w+) (.*?);", text, re.M):
        pairs = re.findall(r'(-?\d+) "([^"]*)"', m.group(3))
        out[(int(m.group(1)), m.group(2))] = {int(v): n for v, n in pairs}
    return out


MACROS = parse_macros(_core.lib_file("dv_contract.h").read_text(encoding="utf-8"))
DBC_VALUES = parse_dbc_values(_core.lib_file("dynval.dbc").read_text(encoding="utf-8"))


def const(name: str) -> int:
    """An integer macro of the C headers (KeyError: not in this build's headers)."""
    return int(MACROS[name])


def named(prefix: str) -> dict[str, int]:
    """The integer macros NAME = prefix + suffix, as {suffix lower-cased: value}."""
    return {k[len(prefix):].lower(): int(v) for k, v in MACROS.items()
            if k.startswith(prefix) and isinstance(v, int)}


#: firmware_sim's global counters (input registers, uint32): name -> first register (the
#: addresses from SIM_IR_RX_FRAMES up to the per-channel blocks, SIM_IR_CH_* offsets aside)
IR_COUNTERS = {k: v for k, v in named("SIM_IR_").items() if not k.startswith("ch_")
               and const("SIM_IR_RX_FRAMES") <= v < const("SIM_IR_CH_BASE")}
