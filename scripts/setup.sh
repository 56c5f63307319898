#!/usr/bin/env bash
# Install what dynval needs on Debian 12 / Ubuntu (as root, or a user with sudo): compilers,
# cmocka, Eigen, libmodbus, the Cortex-M toolchain, QEMU for the vcan VM and the emulated MCU,
# valgrind, Doxygen (the C API docs); then a project virtual environment .venv (PEP 668:
# Debian's python3 refuses system-wide pip installs) with the test tools and the package (its
# build compiles the C core). Then node/npm with Foxglove's npm packages for the MCAP check
# (gateway/tests/foxglove).
# Idempotent: installed apt packages are not fetched again, and pip runs only when the
# requirements or the package's sources changed since the last install (a stamp in .venv).
# PYTHON picks the interpreter the venv is made from (default: the distribution's python3).
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PKGS=(cmake ninja-build gcc g++ clang libclang-rt-14-dev pkg-config libcmocka-dev
          libeigen3-dev libmodbus-dev gcc-arm-none-eabi libnewlib-arm-none-eabi
          qemu-system-arm qemu-system-x86 busybox-static kmod iproute2 valgrind
          python3 python3-venv python3-dev doxygen)
# node and npm for the check of the MCAP files with Foxglove's own reader and parser
# (gateway/tests/foxglove); a node that is already there (with its npm) is used as it is
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    APT_PKGS+=(nodejs npm)
fi
missing=()
for p in "${APT_PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep "install ok installed" >/dev/null || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO=sudo
    echo "setup: apt-get install ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
        "${missing[@]}" >/dev/null
fi

if [ -z "${PYTHON:-}" ]; then
    PYTHON=python3
    [ -x /usr/bin/python3 ] && PYTHON=/usr/bin/python3
fi
VENV=.venv
if [ ! -x "$VENV/bin/python" ]; then
    echo "setup: virtual environment $VENV (from $("$PYTHON" --version 2>&1), $PYTHON)"
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
fi
PIP=("$VENV/bin/python" -m pip install -q --disable-pip-version-check -c requirements-lock.txt)

# reinstall only what changed: the stamps hold a hash of the inputs of each install
src_hash() { # content hash of the source files under the given paths
    find "$@" -type f -not -path '*/build/*' -not -path '*/__pycache__/*' -not -path '*/_lib/*' \
        -not -path '*/tests/*' -not -name '*.so' -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -c1-16
}
req_hash=$(sha256sum requirements-dev.txt requirements-lock.txt gateway/pyproject.toml | sha256sum | cut -c1-16)
if [ "$(cat "$VENV/.dv-req" 2>/dev/null)" != "$req_hash" ]; then
    echo "setup: python test tools (requirements-dev.txt)"
    "${PIP[@]}" -r requirements-dev.txt
    echo "$req_hash" >"$VENV/.dv-req"
fi
pkg_hash=$( { src_hash gateway/src gateway/pyproject.toml gateway/CMakeLists.txt include src cmake \
                     CMakeLists.txt firmware_sim can; echo "$req_hash"; } |
            sha256sum | cut -c1-16)
if [ "$(cat "$VENV/.dv-pkg" 2>/dev/null)" != "$pkg_hash" ]; then
    echo "setup: the dynval package (builds the C core)"
    "${PIP[@]}" "./gateway[validate,formats]"
    echo "$pkg_hash" >"$VENV/.dv-pkg"
fi
# Foxglove's npm packages (gateway/tests/foxglove/package-lock.json) and the JSON-schema
# parser of the open-source Foxglove Studio, for gateway/tests/test_foxglove.py
FOX=gateway/tests/foxglove
fox_hash=$(sha256sum "$FOX/package-lock.json" "$FOX/fetch_studio_parser.sh" | sha256sum | cut -c1-16)
if [ "$(cat "$FOX/node_modules/.dv-stamp" 2>/dev/null)" != "$fox_hash" ]; then
    echo "setup: Foxglove's MCAP reader and parser (npm, $FOX)"
    (cd "$FOX" && npm ci --silent --no-audit --no-fund && ./fetch_studio_parser.sh)
    echo "$fox_hash" >"$FOX/node_modules/.dv-stamp"
fi
echo "setup: done (commands in $VENV/bin: dynval, python; scripts put it first on PATH)"
