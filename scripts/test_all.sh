#!/usr/bin/env bash
# Every test of dynval, one command (README's second command; .ci/run calls it):
# C library in float and double with gcc, clang, ASan+UBSan; Eigen cross-checks; the
# fixed-memory symbol check; the Cortex-M4F cross build; a consumer project; the Python
# package's tests; the firmware simulator's end-to-end tests on a real vcan bus; a bounded
# fuzz run. Prints one summary line "N passed, N failed" and exits non-zero on any failure.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
export CTEST_OUTPUT_ON_FAILURE=1
passed=0
failed=0
failures=()

step() { # step NAME COMMAND...
    local name=$1
    shift
    echo
    echo "=== $name"
    local t0=$SECONDS
    if "$@"; then
        passed=$((passed + 1))
        echo "--- ok: $name ($((SECONDS - t0)) s)"
    else
        failed=$((failed + 1))
        failures+=("$name")
        echo "--- FAILED: $name ($((SECONDS - t0)) s)"
    fi
}

preset() { # configure, build and ctest one CMake preset
    cmake --preset "$1" >/dev/null && cmake --build --preset "$1" -j2 >/dev/null &&
        ctest --preset "$1" -j2
}

[ "${DV_SKIP_SETUP:-0}" = 1 ] || scripts/setup.sh || exit 1
# the project virtual environment (scripts/setup.sh) first: python3, pytest, dynval
export PATH="$ROOT/.venv/bin:$PATH"

# Beside the main line: the end-to-end run (a QEMU VM, about one core), the sdist install
# (mostly downloads) and the fuzz run (one core at a time) need nothing the main line builds.
# Run one after the other in the background from the start, they fill the cores the main
# line's serial parts leave idle (run after it, they added about 370 s to CI). Their
# output is kept in a log and printed, with their results, after the main line's.
BESIDE=$(mktemp -d "${TMPDIR:-/tmp}/dv_beside.XXXXXX")
beside() {
    if [ -x tests/e2e/run_e2e.sh ]; then
        step "end-to-end on a real vcan bus" tests/e2e/run_e2e.sh
    fi
    step "Python sdist: carries the C core, pip install into a fresh venv" \
        tests/packaging/sdist_install.sh
    if [ -x tests/fuzz/run_fuzz.sh ]; then
        step "fuzz the CAN decoder (bounded)" tests/fuzz/run_fuzz.sh 30
    fi
    echo "$passed $failed" >"$BESIDE/counts"
    printf '%s\n' "${failures[@]}" >"$BESIDE/failures"
}
beside >"$BESIDE/log" 2>&1 </dev/null &
beside_pid=$!
# an interrupted run stops the background steps too (they ignore SIGINT: no job control here)
# and leaves no temporary folder behind
trap 'trap - INT TERM; rm -rf "$BESIDE"; kill 0' INT TERM

step "C float, gcc Debug (dev)" preset dev
step "C double, gcc Release (f64)" preset f64
step "C float, gcc Release" preset release
step "C double, ASan+UBSan" preset asan
step "C float, ASan+UBSan" preset asan-f32
step "C double, clang" preset clang
step "C++/Eigen cross-checks" preset xcheck
# (the Debug build keeps assert() as its DV_ASSERT hook by design; release builds are checked)
step "no malloc/stdio/abort, no .data/.bss (float)" tests/scripts/check_lib_symbols.sh build/release/libdynval-f32.a
step "no malloc/stdio/abort, no .data/.bss (double)" tests/scripts/check_lib_symbols.sh build/f64/libdynval-f64.a
step "no -ffast-math in the build" bash -c '! grep -rn -- "-ffast-math\|-Ofast" CMakeLists.txt CMakePresets.json cmake/ src/ gateway/pyproject.toml'
step "Cortex-M4F cross build + size" tests/scripts/cross_m4.sh
step "Cortex-M4F self-test on an emulated MCU (qemu mps2-an386)" tests/m4/run_m4.sh
step "consumer: find_package (f32, f64 side by side), pkg-config, add_subdirectory" \
    tests/consumer/run.sh
step "C API docs: Doxygen, 0 warnings (public headers)" cmake --build build/f64 --target docs
step "Python lint and types (ruff, mypy --strict)" bash -c 'cd gateway && ruff check src tests && mypy src'
# the C reference tools of the bit-for-bit tests and Foxglove's parser (gateway/tests/foxglove):
# set, so a missing tool fails instead of skipping
# DYNVAL_WORKERS=1: pytest-xdist already keeps both cores busy, and discover's own forked
# pools would only add work (test_discover.py on 2 xdist workers: 318 s with them, 256 s without)
# --durations: where CI's time goes, in its log. firmware_sim's host tests (tests/py/test_sim_*)
# are the end-to-end step's: it builds the simulator they need (beside this step: here they
# would run or skip by when its build ends)
step "Python package (pytest)" env DYNVAL_WORKERS=1 DV_FOXGLOVE_CHECK=1 DV_FEATURES_DUMP="$ROOT/build/f64/tests/dv_features_dump" \
    DV_AR_DUMP="$ROOT/build/f64/tests/dv_ar_dump" DV_MODEL_DUMP="$ROOT/build/f64/tests/dv_model_dump" \
    python3 -m pytest -q -p no:cacheprovider -n auto --dist worksteal --durations=25 \
    gateway/tests tests/py --ignore-glob='tests/py/test_sim_*'

echo
echo "=== (the steps run beside the main line; waiting for them)"
wait "$beside_pid"
cat "$BESIDE/log"
if [ -f "$BESIDE/counts" ]; then
    read -r bp bf <"$BESIDE/counts"
    passed=$((passed + bp))
    failed=$((failed + bf))
    while IFS= read -r f; do
        [ -n "$f" ] && failures+=("$f")
    done <"$BESIDE/failures"
else
    failed=$((failed + 1))
    failures+=("the steps beside the main line (no result)")
fi
rm -rf "$BESIDE"

echo
if [ "$failed" -gt 0 ]; then
    printf 'failed: %s\n' "${failures[@]}"
fi
echo "checks: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
