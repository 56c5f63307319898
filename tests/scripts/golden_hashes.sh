#!/usr/bin/env bash
# Hashes of what the model/observer/element code computes, for refactors that must keep the
# results bit for bit: the Cortex-M4 self-test logs (host float build and both M4 images:
# features, AR, model modes, observer outputs open loop and with the Kalman gain, with a
# bumper), the f64 reference tool over the golden force (linear and with a contact), and the
# Python binding's simulations with every element law, each input kind and both holds.
# usage: tests/scripts/golden_hashes.sh [BUILD_PREFIX]   (default build/hashes)
# Prints "sha256  artefact" lines; compare two runs with diff.
set -euo pipefail
cd "$(dirname "$0")/../.."
P=${1:-build/hashes}
export PATH="$PWD/.venv/bin:$PATH"   # the project venv (scripts/setup.sh) first
PY=${PYTHON:-python3}
mkdir -p "$P"
log="$P/build.log"

# the M4 self-test (it builds its own libraries in build/m4) and its logs
tests/m4/run_m4.sh >"$log" 2>&1 || { tail -20 "$log"; exit 1; }
for f in build/m4/selftest-host.log build/m4/selftest-os.log build/m4/selftest-o2.log; do
    sha256sum "$f" | sed "s|  .*|  m4/$(basename "$f")|"
done

# the f64 reference tool
cmake -S . -B "$P-f64" -G Ninja -DCMAKE_BUILD_TYPE=Release -DDV_REAL_TYPE=double \
    -DDV_BUILD_TESTS=ON >>"$log" 2>&1
cmake --build "$P-f64" --target dv_model_dump >>"$log" 2>&1
awk -F, 'NR > 1 {print $NF}' tests/data/model_force.csv >"$P/force.txt"
"$P-f64/tests/dv_model_dump" "$P/force.txt" 640 | sha256sum | sed 's|  .*|  dump/model_linear|'
"$P-f64/tests/dv_model_dump" "$P/force.txt" 640 1.114e-4 1e-4 1.925e6 | sha256sum |
    sed 's|  .*|  dump/model_contact|'

# the Python binding (the double shared library installed into the source tree)
cmake -S . -B "$P-py" -G Ninja -DDV_BUILD_PYTHON=ON -DDV_BUILD_SHARED=ON -DDV_REAL_TYPE=double \
    -DCMAKE_BUILD_TYPE=Release -DDV_BUILD_TESTS=OFF >>"$log" 2>&1
cmake --build "$P-py" >>"$log" 2>&1
cmake --install "$P-py" --prefix gateway/src >>"$log" 2>&1
PYTHONPATH=gateway/src "$PY" tests/scripts/golden_sims.py
