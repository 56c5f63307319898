"""The only bridge to the C core: cffi (ABI mode) over the shared library that this package's
build step compiled from the repository's src/ (double precision), with the cdef taken from the
preprocessed public headers, so the declarations cannot drift from the C code."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from cffi import FFI

from dynval.errors import CoreError, CoreNotBuiltError

_LIB_DIR = Path(__file__).resolve().parent / "_lib"


def _load() -> tuple[FFI, Any]:  # (ffi, lib): lib's functions come from the cdef at run time
    cdef = _LIB_DIR / "dv_cdef.h"
    libs = sorted(_LIB_DIR.glob("libdynval-f64*.so*"))
    libs += sorted(_LIB_DIR.glob("*dynval-f64*.dylib"))
    if not cdef.is_file() or not libs:
        raise CoreNotBuiltError(
            f"the compiled dynval core is missing from {_LIB_DIR}: install the package with "
            "`pip install ./gateway` (its build step compiles the C library)")
    ffi = FFI()
    ffi.cdef(cdef.read_text(encoding="utf-8"))
    lib: Any = ffi.dlopen(str(libs[0]))
    if lib.dv_real_size() != 8:
        raise CoreNotBuiltError("the dynval core was built with float samples; "
                                "the binding needs double")
    return ffi, lib


_ffi, lib = _load()
# cdata objects are dynamically typed: callers see Any, not cffi's opaque stub classes
ffi: Any = _ffi

DV_OK = 0
DV_DONE = 1
DV_RECORD = 2


def status_name(status: int) -> str:
    return str(ffi.string(lib.dv_status_str(status)).decode("ascii"))


def check(status: int, func: str) -> int:
    """Raise CoreError for a negative status; return the status otherwise."""
    if status < 0:
        raise CoreError(func, int(status), status_name(status))
    return int(status)


def as_doubles(x: Any) -> np.ndarray:
    """A C-contiguous float64 view or copy of x (1-D)."""
    return np.ascontiguousarray(np.asarray(x, dtype=np.float64)).reshape(-1)


def ptr(a: np.ndarray) -> Any:
    """A `double *` into a contiguous float64 array (kept alive by the caller)."""
    return ffi.cast("double *", ffi.from_buffer(a))
