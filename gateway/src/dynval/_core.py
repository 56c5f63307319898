"""The only bridge to the C code: cffi (ABI mode) over the shared libraries that this package's
build step compiled from the repository (double precision): libdynval (the core) and
libdv_simcore (firmware_sim's socket-free loop, for `dynval run` in-process). One FFI holds both
cdefs, the preprocessed public headers dv_cdef.h and sim_cdef.h (CMakeLists.txt), so the
declarations cannot drift from the C code.

Loaded lazily (PEP 562): importing this module opens nothing; the first `_core.lib`, `_core.ffi`
or `_core.sim_lib` does, and a missing or unusable build raises CoreNotBuiltError (one line and
exit 2 in the CLI), never an ImportError at import time."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from cffi import FFI

from dynval.errors import CoreError, CoreNotBuiltError

_LIB_DIR = Path(__file__).resolve().parent / "_lib"

DV_OK = 0
DV_DONE = 1
DV_RECORD = 2


def lib_file(name: str) -> Path:
    """A file the build step generated into the package's _lib folder (cdefs, contract, DBC)."""
    p = _LIB_DIR / name
    if not p.is_file():
        raise CoreNotBuiltError(f"{p} is missing: the compiled dynval core is not installed "
                                "(`pip install ./gateway` builds it)")
    return p


def find_program(name: str, env_var: str, explicit: str | None = None) -> Path | None:
    """One of the project's programs (firmware_sim, dv_pacer): an explicit path, $env_var, on
    PATH, or the newest build of the repository this command runs in
    (build/*/firmware_sim/<name>)."""
    import os
    import shutil

    for c in (explicit, os.environ.get(env_var), shutil.which(name)):
        if c and Path(c).is_file() and os.access(c, os.X_OK):
            return Path(c)
    d = Path.cwd().resolve()
    for root in (d, *d.parents):
        if (root / "firmware_sim").is_dir() and (root / "CMakeLists.txt").is_file():
            cands = sorted((root / "build").glob(f"*/firmware_sim/{name}"),
                           key=lambda p: p.stat().st_mtime, reverse=True)
            return cands[0] if cands else None
    return None


def _dlopen(stem: str) -> Any:
    # Linux (versioned too), macOS, Windows (MSVC: dynval-f64.dll, MinGW: libdynval-f64.dll)
    libs = [lib for pattern in (f"lib{stem}*.so*", f"*{stem}*.dylib", f"*{stem}*.dll")
            for lib in sorted(_LIB_DIR.glob(pattern))]
    if not libs:
        lib_file(f"lib{stem}.so")  # raises: names what is missing
    try:
        return __getattr__("ffi").dlopen(str(libs[0]))
    except OSError as exc:
        raise CoreNotBuiltError(f"{libs[0]}: cannot load: {exc}") from exc


def _load_ffi() -> Any:
    ffi = FFI()
    ffi.cdef(lib_file("dv_cdef.h").read_text(encoding="utf-8"))
    return ffi


def _load_lib() -> Any:
    lib = _dlopen("dynval-f64")
    if lib.dv_real_size() != 8:
        raise CoreNotBuiltError("the dynval core was built with float samples; "
                                "the binding needs double")
    return lib


def _load_sim_lib() -> Any:
    # the firmware core's own declarations; its dv_* types are dv_cdef.h's (override: a retry
    # after a failed dlopen declares them again)
    __getattr__("ffi").cdef(lib_file("sim_cdef.h").read_text(encoding="utf-8"), override=True)
    return _dlopen("dv_simcore-f64")


_LOADERS: dict[str, Callable[[], Any]] = {"ffi": _load_ffi, "lib": _load_lib,
                                          "sim_lib": _load_sim_lib}
_loaded: dict[str, Any] = {}


def __getattr__(name: str) -> Any:
    """`ffi`, `lib` and `sim_lib`, loaded on first use (cdata objects are dynamically typed:
    callers see Any, not cffi's opaque stub classes)."""
    if name not in _LOADERS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if name not in _loaded:
        _loaded[name] = _LOADERS[name]()
    return _loaded[name]


def status_name(status: int) -> str:
    """The core's name of a status code (dv_status_str: "DV_ESIZE", ...)."""
    ffi, lib = __getattr__("ffi"), __getattr__("lib")
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
    ffi = __getattr__("ffi")
    return ffi.cast("double *", ffi.from_buffer(a))
