#!/bin/sh
# End-to-end tests of firmware_sim on a real vcan bus, one command:
#   tests/e2e/run_e2e.sh
# 1. builds firmware_sim + the offline reference into build/e2e (DV_E2E_BUILD),
# 2. runs the host tests that need no CAN (tests/py/test_sim_modbus.py, hostile Modbus
#    clients test_sim_modbus_hostile.py, finite results and I/O errors test_sim_finite.py),
# 3. runs tests/e2e/test_e2e_vcan.py on vcan0: directly when this kernel has vcan
#    (`ip link add dev vcan0 type vcan` works), else inside a QEMU VM built from
#    ../shared/vcan (DV_VCAN_DIR), kernel + initramfs cached in DV_VCAN_VM (default
#    ${TMPDIR:-/tmp}/dv-vcanvm). Needs qemu-system-x86 busybox-static kmod for the VM
#    (installed with apt-get when missing and running as root).
# Exit status: 0 all passed; pytest's status or run-in-vm.sh's (99 no result, 124 timeout).
set -eu
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${DV_E2E_BUILD:-$ROOT/build/e2e}
PYTEST="python3 -m pytest -q -p no:cacheprovider"

if [ -n "${DV_E2E_INSIDE:-}" ]; then
    # inside the VM (or on a host with vcan): the host root is read-only here
    export PYTHONDONTWRITEBYTECODE=1 DV_E2E_BUILD="$BUILD" DV_E2E_REQUIRE_VCAN=1
    cd "$ROOT/tests/e2e"
    exec $PYTEST --durations=10 test_e2e_vcan.py test_e2e_gateway.py
fi

echo "== build ($BUILD)"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DDV_BUILD_SIM=ON -DDV_BUILD_TESTS=OFF \
    >"${TMPDIR:-/tmp}/dv_e2e_cmake.log" 2>&1 || { cat "${TMPDIR:-/tmp}/dv_e2e_cmake.log"; exit 1; }
cmake --build "$BUILD" -j2 --target dv_sim dv_sim_offline dv_simcore >/dev/null

echo "== host: Modbus tests (no CAN)"
DV_E2E_BUILD="$BUILD" $PYTEST "$ROOT/tests/py/test_sim_modbus.py" \
    "$ROOT/tests/py/test_sim_modbus_hostile.py" "$ROOT/tests/py/test_sim_finite.py"

if [ "$(id -u)" = 0 ] && { [ -e /sys/class/net/vcan0 ] || ip link add dev vcan0 type vcan 2>/dev/null; }; then
    echo "== vcan0 on this kernel"
    ip link set vcan0 up
    DV_E2E_INSIDE=1 DV_E2E_BUILD="$BUILD" sh "$0"
    exit $?
fi

echo "== no vcan here: QEMU VM with Debian's kernel"
VCAN=${DV_VCAN_DIR:-$ROOT/../shared/vcan}
VM=${DV_VCAN_VM:-${TMPDIR:-/tmp}/dv-vcanvm}
if ! command -v qemu-system-x86_64 >/dev/null 2>&1 || [ ! -x /bin/busybox ]; then
    if [ "$(id -u)" = 0 ]; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
            qemu-system-x86 busybox-static kmod >/dev/null
    else
        echo "run_e2e: need qemu-system-x86 busybox-static kmod (apt-get as root)" >&2
        exit 1
    fi
fi
if [ ! -f "$VM/vmlinuz" ] || [ ! -f "$VM/initramfs.gz" ]; then
    "$VCAN/build-initramfs.sh" "$VM" >/dev/null
fi
t0=$(date +%s)
rc=0
VCAN_TIMEOUT=${VCAN_TIMEOUT:-900} "$VCAN/run-in-vm.sh" "$VM" \
    "cd '$ROOT' && DV_E2E_INSIDE=1 DV_E2E_BUILD='$BUILD' sh tests/e2e/run_e2e.sh" || rc=$?
echo "== VM run: exit $rc after $(( $(date +%s) - t0 )) s (logs in $VM/out)"
exit "$rc"
