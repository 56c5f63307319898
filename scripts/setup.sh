#!/usr/bin/env bash
# Install what dynval needs on Debian 12 (as root, or with sudo): compilers, cmocka, Eigen,
# libmodbus, the Cortex-M toolchain, QEMU for the vcan VM and the emulated MCU, valgrind;
# then the Python package (its build step compiles the C core) and the test tools.
# Idempotent: already-installed packages are not fetched again.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PKGS=(cmake ninja-build gcc g++ clang libclang-rt-14-dev pkg-config libcmocka-dev
          libeigen3-dev libmodbus-dev gcc-arm-none-eabi libnewlib-arm-none-eabi
          qemu-system-arm qemu-system-x86 busybox-static kmod iproute2 valgrind python3-pip)
missing=()
for p in "${APT_PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO=sudo
    echo "setup: apt-get install ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
        "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3}
echo "setup: python packages"
$PY -m pip install -q --disable-pip-version-check -r requirements-dev.txt
# the package itself: its build step (scikit-build-core + CMake) compiles the C core
$PY -m pip install -q --disable-pip-version-check "./gateway[validate]"
echo "setup: done"
