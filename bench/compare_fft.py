"""Same-run comparisons for the FFT/FRF benchmarks (bench/bench_fft.c), float and double.

- CMSIS-DSP's arm_rfft_fast_f64 / _f32 in C, compiled from the cmsisdsp 1.10.3 sdist (fetched
  into build/cmsis with a sha256 check, then cached) together with bench/cmsis/cmsis_fft_bench.c
  by the compiler and Release flags of the bench build (build/bench-f64|f32/CMakeCache.txt), and
  timed with bench_fft's protocol, cases and data. Each row says how far CMSIS's spectrum is
  from dv_fft_forward_real's on the same input (max |diff|, relative to the largest |X|).
- frf_welch_1024_sample: the same Welch average (periodic Hann, running mean of Guu, Gyy, Guy)
  as a plain block loop in C around arm_rfft_fast: segments read in place, no ring buffer.
- numpy.fft.rfft and scipy.fft.rfft (one call per transform: Python call overhead included),
  and scipy.signal.csd + welch over the whole record for the FRF.

When the download or the build fails the CMSIS rows are left out with a warning.

    python3 bench/compare_fft.py     # after bench/run.py (or a build/bench-f64 configure)
"""
from __future__ import annotations

import hashlib
import logging
import shutil
import statistics
import subprocess
import tarfile
import urllib.request
from pathlib import Path

import numpy as np
from measure import instructions, median_ns  # bench/ is on the path (run.py's folder)
from scipy import fft as sfft
from scipy import signal

ROOT = Path(__file__).resolve().parent.parent
CACHE = ROOT / "build" / "cmsis"
SDIST = "cmsisdsp-1.10.3"
URL = ("https://files.pythonhosted.org/packages/2c/ec/0decbb48985d2eb98739a9bbf4ba090278cc492a7c1"
       "a5d5b907e8baf67b5/cmsisdsp-1.10.3.tar.gz")
SHA256 = "307d32298faa7c58db912851027fce35f886fec7eb1a27c4b309ce1a97f47519"
FFT_CASES = {"fft_real_256": 256, "fft_real_1024": 1024, "fft_real_4096": 4096}
FRF_CASE = "frf_welch_1024_sample"
PROCS, REPS = 5, 31
LINE_KEYS = ("case", "units", "unit", "ns")
log = logging.getLogger("bench")
Row = dict[str, str | float]  # case, real, what, ns, unit: one row of bench/run.py's tables


def _sources() -> Path:
    """The unpacked sdist under build/cmsis, downloaded and checked once."""
    src = CACHE / SDIST
    if (src / "Include" / "arm_math.h").is_file():
        return src
    CACHE.mkdir(parents=True, exist_ok=True)
    tgz = CACHE / f"{SDIST}.tar.gz"
    if not tgz.is_file():
        with urllib.request.urlopen(URL, timeout=60) as r:  # noqa: S310 (a fixed https URL)
            data = r.read()
        if hashlib.sha256(data).hexdigest() != SHA256:
            raise RuntimeError(f"{URL}: sha256 mismatch")
        tgz.write_bytes(data)
    elif hashlib.sha256(tgz.read_bytes()).hexdigest() != SHA256:
        raise RuntimeError(f"{tgz}: sha256 mismatch")
    with tarfile.open(tgz) as tf:
        members = tf.getmembers()
        bad = [m.name for m in members if m.name.startswith("/") or ".." in Path(m.name).parts
               or not (m.isfile() or m.isdir())]
        if bad:  # Python < 3.11.4 has no extraction filter: refuse what it would refuse
            raise RuntimeError(f"{tgz}: unexpected members {bad[:3]}")
        tf.extractall(CACHE, members=members)  # noqa: S202 (checked above)
    return src


def _toolchain(real: str) -> tuple[str, list[str]]:
    """The C compiler and Release flags the bench build of @real uses (cc -O3 when unbuilt)."""
    cache = ROOT / "build" / f"bench-{'f64' if real == 'double' else 'f32'}" / "CMakeCache.txt"
    vals: dict[str, str] = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            key, _, val = line.partition("=")
            if key in ("CMAKE_C_COMPILER:FILEPATH", "CMAKE_C_FLAGS:STRING",
                       "CMAKE_C_FLAGS_RELEASE:STRING"):
                vals[key.split(":")[0]] = val
    cc = vals.get("CMAKE_C_COMPILER") or shutil.which("cc") or "cc"
    flags = (vals.get("CMAKE_C_FLAGS", "") + " " +
             vals.get("CMAKE_C_FLAGS_RELEASE", "-O3 -DNDEBUG")).split()
    # bench/CMakeLists.txt's per-target flags: C99 with GNU extensions, POSIX clocks
    return cc, [*flags, "-std=gnu99", "-Wall", "-Wextra", "-D_POSIX_C_SOURCE=200809L"]


def _build(real: str, src: Path) -> Path:
    """cmsis_fft_bench for @real, against the CMSIS-DSP files the real FFT needs."""
    sfx = "f64" if real == "double" else "f32"
    tf = src / "Source" / "TransformFunctions"
    files = [tf / f"arm_rfft_fast_{sfx}.c", tf / f"arm_rfft_fast_init_{sfx}.c",
             tf / f"arm_cfft_{sfx}.c", tf / f"arm_cfft_init_{sfx}.c", tf / "arm_bitreversal2.c",
             src / "Source" / "CommonTables" / "arm_common_tables.c",
             src / "Source" / "CommonTables" / "arm_const_structs.c"]
    if real == "float":
        files.append(tf / "arm_cfft_radix8_f32.c")
    cc, flags = _toolchain(real)
    exe = CACHE / f"cmsis_fft_bench-{sfx}"
    # __GNUC_PYTHON__: CMSIS's host build without the Cortex core headers (as its setup.py)
    defs = ["-D__GNUC_PYTHON__", *(["-DDV_REAL_DOUBLE"] if real == "double" else [])]
    inc = [f"-I{p}" for p in (ROOT / "bench", ROOT / "include", ROOT / "src",
                              src / "Include", src / "PrivateInclude")]
    cmd = [cc, *flags, *defs, *inc, str(ROOT / "bench" / "cmsis" / "cmsis_fft_bench.c"),
           str(ROOT / "src" / "dv_fft.c"), *map(str, files), "-lm", "-o", str(exe)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"building {exe.name} failed: {r.stderr[-2000:]}")
    return exe


def _run(exe: Path, *args: str) -> str:
    return subprocess.run([str(exe), *args], check=True, capture_output=True, text=True).stdout


def _time_cases(exes: dict[str, Path]) -> dict[tuple[str, str], tuple[float, str, int]]:
    """Median over PROCS processes (in rounds over the cases, as run.py) of each case's ns."""
    cases = [*FFT_CASES, FRF_CASE]
    ns: dict[tuple[str, str], list[float]] = {}
    unit: dict[tuple[str, str], tuple[str, int]] = {}
    for _ in range(PROCS):
        for real, exe in exes.items():
            for case in cases:
                fields = dict(kv.split("=", 1) for kv in _run(exe, case, str(REPS)).split())
                ns.setdefault((real, case), []).append(float(fields["ns"]))
                unit[(real, case)] = (fields["unit"], int(fields["units"]))
    return {k: (statistics.median(v), *unit[k]) for k, v in ns.items()}


def _cmsis_rows() -> list[Row]:
    try:
        src = _sources()
        exes = {real: _build(real, src) for real in ("double", "float")}
    except Exception as exc:  # no network, no compiler: the other rows still stand
        log.warning("compare_fft: no CMSIS-DSP comparison: %s", exc)
        return []
    timed = _time_cases(exes)
    rows: list[Row] = []
    for (real, case), (ns, unit, units) in timed.items():
        sfx = "f64" if real == "double" else "f32"
        if case in FFT_CASES:
            chk = dict(kv.split("=", 1) for kv in _run(exes[real], "--check", case).split())
            what = (f"CMSIS-DSP arm_rfft_fast_{sfx} (C, same compiler and flags, cmsisdsp 1.10.3; "
                    f"max |diff| from dv {float(chk['maxdiff']):.1e}, "
                    f"{float(chk['rel']):.1e} of max |X|)")
        else:
            what = (f"plain C block Welch around CMSIS-DSP arm_rfft_fast_{sfx} (same window and "
                    f"averages, segments read in place: no ring, no NaN check)")
        row: Row = {"case": case, "real": real, "what": what, "ns": ns, "unit": unit}
        instr = instructions(exes[real], case, units)
        if instr is not None:  # run.py prints float keys after the ratio: ", instr X"
            row["instr"] = instr
        rows.append(row)
    return rows


def _python_rows() -> list[Row]:
    rng = np.random.default_rng(7)
    rows: list[Row] = []
    for case, n in FFT_CASES.items():
        for real, dt in (("double", np.float64), ("float", np.float32)):
            x = rng.standard_normal(n).astype(dt)
            batch = max(1, 16384 // n)

            def run_np(x: np.ndarray = x, batch: int = batch) -> None:
                for _ in range(batch):
                    np.fft.rfft(x)

            def run_sp(x: np.ndarray = x, batch: int = batch) -> None:
                for _ in range(batch):
                    sfft.rfft(x)

            for name, fn in (("numpy.fft.rfft", run_np), ("scipy.fft.rfft", run_sp)):
                rows.append({"case": case, "real": real, "ns": median_ns(fn, batch, 101),
                             "unit": "transform",
                             "what": f"{name} on a {np.dtype(dt).name} array, one call per "
                                     f"transform (Python call overhead included)"})
    u = rng.standard_normal(16384)
    y = 0.8 * u + 0.5 * np.r_[0.0, u[:-1]] + 0.1 * rng.standard_normal(u.size)

    def welch() -> None:
        kw = {"fs": 1024.0, "window": "hann", "nperseg": 1024, "noverlap": 512, "detrend": False}
        signal.csd(u, y, **kw)
        signal.welch(u, **kw)
        signal.welch(y, **kw)

    rows.append({"case": FRF_CASE, "real": "double", "ns": median_ns(welch, u.size, 31),
                 "unit": "sample",
                 "what": "scipy.signal csd + 2 welch over the whole record (not streaming)"})
    return rows


def compare() -> list[Row]:
    return _cmsis_rows() + _python_rows()


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for c in compare():
        log.info("%-24s %-6s %12.1f ns/%s  %s", c["case"], c["real"], c["ns"], c["unit"], c["what"])
