#!/usr/bin/env bash
# The library's golden vectors on an emulated Cortex-M4F, and the same program on the host.
#   1. cross-build the float library (-Os = preset cross-m4, and -O2 = preset cross-m4-o2
#      settings) into build/m4/lib-os, build/m4/lib-o2; the host float library into
#      build/m4/host-f32
#   2. tests/m4/gen_m4_vectors.py: tests/data/*.csv -> build/m4/gen/dv_m4_vectors.h
#   3. link the bare-metal self-test image for MPS2-AN386 (Cortex-M4) at -Os and -O2 and run
#      each under qemu-system-arm with semihosting (timeout M4_TIMEOUT s, default 300)
#   4. build and run the host twin (same source, gcc, host float library)
#   5. tests/m4/compare_m4.py: every check passed on both, and which outputs are bit-identical
# --build-only: steps 1-3 without running (also builds the typical-set images for mem_budget.py)
# Exit status non-zero on any failure. Needs: gcc-arm-none-eabi libnewlib-arm-none-eabi
# qemu-system-arm (apt), python3 with numpy.
set -euo pipefail
cd "$(dirname "$0")/../.."
B=build/m4
T=tests/m4
TIMEOUT=${M4_TIMEOUT:-300}
JOBS=${JOBS:-2}
mkdir -p "$B/gen"

for tool in arm-none-eabi-gcc qemu-system-arm python3; do
    command -v "$tool" >/dev/null || { echo "run_m4: $tool not found (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm)"; exit 2; }
done

# ---- 1. libraries ------------------------------------------------------------------------
build_lib() { # dir, extra cmake args...
    local dir=$1; shift
    cmake -S . -B "$dir" -DDV_BUILD_TESTS=OFF -DDV_WERROR=ON "$@" >"$dir.cmake.log" 2>&1 \
        || { cat "$dir.cmake.log"; exit 1; }
    cmake --build "$dir" -j"$JOBS" >"$dir.build.log" 2>&1 || { cat "$dir.build.log"; exit 1; }
}
mkdir -p "$B"
build_lib "$B/lib-os" -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/arm-none-eabi.cmake" -DCMAKE_BUILD_TYPE=MinSizeRel
build_lib "$B/lib-o2" -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/arm-none-eabi.cmake" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG"
build_lib "$B/host-f32" -DCMAKE_BUILD_TYPE=Release
for v in os o2; do
    tests/scripts/check_lib_symbols.sh "$B/lib-$v/libdynval-f32.a" arm-none-eabi-nm
done

# ---- 2. vectors ----------------------------------------------------------------------------
python3 "$T/gen_m4_vectors.py" tests/data "$B/gen/dv_m4_vectors.h"

# ---- 3. images -----------------------------------------------------------------------------
M4_FLAGS=(-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -ffunction-sections
          -fdata-sections -std=c99 -Wall -Wextra -Werror -g)
M4_LINK=(-T "$T/mps2_an386.ld" -nostartfiles --specs=nano.specs --specs=nosys.specs
         -Wl,--gc-sections)
link_image() { # out.elf, optflag, lib, sources...
    local out=$1 opt=$2 lib=$3; shift 3
    arm-none-eabi-gcc "${M4_FLAGS[@]}" "$opt" -Iinclude -I"$B/gen" -I"$T" \
        -fno-tree-loop-distribute-patterns -c "$T/m4_startup.c" -o "${out%.elf}.startup.o"
    arm-none-eabi-gcc "${M4_FLAGS[@]}" "$opt" -Iinclude -I"$B/gen" -I"$T" "$@" \
        "${out%.elf}.startup.o" "${M4_LINK[@]}" -Wl,-Map="${out%.elf}.map" "$lib" -lm -o "$out"
}
link_image "$B/selftest-os.elf" -Os "$B/lib-os/libdynval-f32.a" "$T/m4_selftest.c" "$T/m4_fmt.c"
link_image "$B/selftest-o2.elf" -O2 "$B/lib-o2/libdynval-f32.a" "$T/m4_selftest.c" "$T/m4_fmt.c"
# the typical firmware set (memory budget) and its instruction-count variant (mem_budget.py)
for v in os o2; do
    opt=-Os; [ $v = o2 ] && opt=-O2
    link_image "$B/typical-$v.elf" $opt "$B/lib-$v/libdynval-f32.a" "$T/m4_typical.c" "$T/m4_fmt.c"
    link_image "$B/icount-$v.elf" $opt "$B/lib-$v/libdynval-f32.a" -DM4_ICOUNT "$T/m4_typical.c" "$T/m4_fmt.c"
done
[ "${1:-}" = "--build-only" ] && exit 0

run_qemu() { # elf, log
    local st=0
    timeout "$TIMEOUT" qemu-system-arm -M mps2-an386 -cpu cortex-m4 -nographic -monitor none \
        -serial none -semihosting-config enable=on,target=native -kernel "$1" >"$2" 2>&1 || st=$?
    return $st
}
status=0
for v in os o2; do
    st=0
    run_qemu "$B/selftest-$v.elf" "$B/selftest-$v.log" || st=$?
    echo "m4 self-test (-${v^}): qemu exit status $st, $(grep -c '^CHECK PASS' "$B/selftest-$v.log") checks passed, $(grep -c '^CHECK FAIL' "$B/selftest-$v.log") failed"
    grep '^CHECK FAIL\|^FATAL' "$B/selftest-$v.log" || true
    [ "$st" -eq 0 ] || status=1
    [ "$st" -eq 124 ] && echo "  timeout after ${TIMEOUT}s"
done

for v in os o2; do  # the typical firmware set runs 8192 samples and checks its own outputs
    st=0
    run_qemu "$B/typical-$v.elf" "$B/typical-$v.log" || st=$?
    echo "typical firmware set (-${v^}): $(grep -E '^(TYPICAL|STACK|LIVE)' "$B/typical-$v.log" | tr '\n' ' ')"
    [ "$st" -eq 0 ] || status=1
done

# ---- 4. host twin --------------------------------------------------------------------------
gcc -std=c99 -O2 -Wall -Wextra -Werror -Iinclude -I"$B/gen" -I"$T" "$T/m4_selftest.c" \
    "$T/m4_fmt.c" "$T/m4_plat_host.c" "$B/host-f32/libdynval-f32.a" -lm -o "$B/selftest-host"
st=0
"$B/selftest-host" >"$B/selftest-host.log" 2>&1 || st=$?
echo "host twin (float, gcc -O2): exit status $st, $(grep -c '^CHECK PASS' "$B/selftest-host.log") checks passed"
[ "$st" -eq 0 ] || status=1

# ---- 5. compare ----------------------------------------------------------------------------
python3 "$T/compare_m4.py" "$B/selftest-host.log" "$B/selftest-os.log" "$B/selftest-o2.log" \
    | tee "$B/compare.txt" || status=1
exit $status
