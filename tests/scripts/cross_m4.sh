#!/usr/bin/env bash
# Cross-build the library for Cortex-M4F (float, -Os) and print its flash/RAM per object;
# the fixed-memory symbol check runs on the ARM archive too.
set -euo pipefail
cd "$(dirname "$0")/../.."
cmake --preset cross-m4 >/dev/null
cmake --build --preset cross-m4 -j2 >/dev/null
lib=build/cross-m4/libdynval-f32.a
tests/scripts/check_lib_symbols.sh "$lib" arm-none-eabi-nm
arm-none-eabi-size -t "$lib" | awk '{print "  " $0}'
