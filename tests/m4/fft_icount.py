#!/usr/bin/env python3
"""Cortex-M4F instructions of a 1024-point real FFT: dv_fft_forward_real (float) against
CMSIS-DSP's arm_rfft_fast_f32, both compiled into one image (tests/m4/m4_fft_icount.c) by
arm-none-eabi-gcc with the same flags, at -Os and -O2; writes bench/RESULTS.m4-fft.md.

    python3 tests/m4/fft_icount.py     # after bench/compare_fft.py fetched CMSIS-DSP

Counts as tests/m4/mem_budget.py does (its icount(): QEMU's per-instruction trace between the
markers, minus the call overhead of an empty function). CMSIS-DSP is built with __GNUC_PYTHON__
(its host configuration: no CMSIS-Core headers, which the sdist does not ship); that only turns
off the integer DSP intrinsics, which the float FFT does not use. Not part of CI.
"""
from __future__ import annotations

import logging
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import compare_fft  # noqa: E402  (bench/: the CMSIS-DSP sdist, fetched and checked)
from mem_budget import QEMU, icount  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
T = ROOT / "tests" / "m4"
B = ROOT / "build" / "m4-fft"
log = logging.getLogger("m4_fft")
FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard",
         "-ffunction-sections", "-fdata-sections", "-std=c99", "-Wall", "-Wextra", "-g"]
LINK = ["-T", str(T / "mps2_an386.ld"), "-nostartfiles", "--specs=nano.specs",
        "--specs=nosys.specs", "-Wl,--gc-sections"]


def build(opt: str) -> Path:
    """The image at @opt (-Os / -O2): dv_fft.c and the CMSIS files compiled alike."""
    src = compare_fft._sources()
    tf = src / "Source" / "TransformFunctions"
    cm = [tf / "arm_rfft_fast_f32.c", tf / "arm_rfft_fast_init_f32.c", tf / "arm_cfft_f32.c",
          tf / "arm_cfft_init_f32.c", tf / "arm_cfft_radix8_f32.c", tf / "arm_bitreversal2.c",
          src / "Source" / "CommonTables" / "arm_common_tables.c",
          src / "Source" / "CommonTables" / "arm_const_structs.c"]
    B.mkdir(parents=True, exist_ok=True)
    elf = B / f"fft-{opt.lstrip('-').lower()}.elf"
    inc = [f"-I{p}" for p in (ROOT / "include", ROOT / "src", T, src / "Include",
                              src / "PrivateInclude")]
    cmd = ["arm-none-eabi-gcc", *FLAGS, opt, "-D__GNUC_PYTHON__", *inc,
           str(T / "m4_fft_icount.c"), str(T / "m4_fmt.c"), str(T / "m4_startup.c"),
           str(ROOT / "src" / "dv_fft.c"), *map(str, cm), *LINK, "-lm", "-o", str(elf)]
    subprocess.run(cmd, check=True)
    return elf


def counts(elf: Path) -> dict[str, float]:
    cts = icount(elf)
    cal = statistics.mean(cts["mark_cal"]) - 2.0
    return {k: statistics.median(v) - cal for k, v in cts.items() if k != "mark_cal"}


def main() -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    gcc = subprocess.run(["arm-none-eabi-gcc", "--version"], capture_output=True,
                         text=True).stdout.splitlines()[0]
    res = {}
    for opt in ("-Os", "-O2"):
        elf = build(opt)
        r = subprocess.run([*QEMU, "-kernel", str(elf)], capture_output=True, text=True,
                           timeout=300)
        text = r.stdout + r.stderr  # semihosting console output goes to stderr
        if r.returncode != 0 or "ICOUNT DONE" not in text:  # the spectra differ: no counts
            log.error("%s failed under QEMU:\n%s", elf.name, text)
            return 1
        diff = next(ln.split()[-1] for ln in text.splitlines() if ln.startswith("FFT MAXDIFF"))
        res[opt] = (counts(elf), diff)
        log.info("%s: %s (max |diff| %s of max |X|)", opt, res[opt][0], diff)
    lines = ["## Cortex-M4F: 1024-point real FFT, dynval against CMSIS-DSP", "",
             f"`python3 tests/m4/fft_icount.py` ({gcc}; QEMU mps2-an386). Instructions per call, "
             "counted from QEMU's trace as tests/m4/mem_budget.py counts them (not cycles; the "
             "call overhead subtracted; median of 4 calls); both FFTs compiled into one image "
             f"with the same flags (`{' '.join(FLAGS[:4])}`), CMSIS-DSP 1.10.3 "
             "`arm_rfft_fast_f32` with `arm_rfft_fast_init_1024_f32`, input uniform noise; the "
             "spectra agree to the relative max |diff| shown.", "",
             "| flags | dv_fft_forward_real | arm_rfft_fast_f32 | dv / CMSIS | max diff / max X |",
             "|---|---:|---:|---:|---:|"]
    for opt, (c, diff) in res.items():
        dv, cm = c["mark_dv_fft1024"], c["mark_cmsis_fft1024"]
        lines.append(f"| {opt} | {dv:.0f} | {cm:.0f} | {dv / cm:.2f} | {diff} |")
    (ROOT / "bench" / "RESULTS.m4-fft.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
