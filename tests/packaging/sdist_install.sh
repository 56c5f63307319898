#!/usr/bin/env bash
# `pip install` of the Python package from its source distribution, as a user of another
# Python would: build the sdist (scikit-build-core), check it carries the C core and not a
# developer's build, install it into a fresh venv of PYTHON_OTHER (default: the first python3.X
# on PATH that is not python3's version; python3 itself when there is none, said so), check the
# wheel's tag (py3-none-<platform>: the core is loaded with cffi's ABI mode) and run the CLI.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
py=${PYTHON:-python3}
base=$("$py" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
other=${PYTHON_OTHER:-}
if [ -z "$other" ]; then
    for v in 3.13 3.12 3.11 3.10; do
        if [ "$v" != "$base" ] && command -v "python$v" >/dev/null &&
                "python$v" -c 'import venv, ensurepip' 2>/dev/null; then
            other=python$v
            break
        fi
    done
fi
if [ -z "$other" ]; then
    echo "sdist: no other Python than $base found: installing with $py itself"
    other=$py
fi
pipq=(-m pip install -q --disable-pip-version-check)

"$py" -m venv "$work/build-env"
"$work/build-env/bin/python" "${pipq[@]}" "scikit-build-core>=1.0"
(cd "$repo/gateway" && "$work/build-env/bin/python" -c \
    'import sys; from scikit_build_core.build import build_sdist; print(build_sdist(sys.argv[1]))' \
    "$work/dist" >/dev/null)
sdist=$(ls "$work"/dist/dynval-*.tar.gz)
listing=$(tar tzf "$sdist")
for f in csrc/CMakeLists.txt csrc/include/dynval/dv.h csrc/src/dv_moments.c \
         csrc/firmware_sim/sim_core.c csrc/firmware_sim/sim_obs_stage.c \
         csrc/firmware_sim/sim_config.c csrc/firmware_sim/sim_priv.h csrc/can/dynval.dbc \
         CMakeLists.txt LICENSE; do
    grep -q "^dynval-[^/]*/$f$" <<<"$listing" || { echo "sdist: $f missing"; exit 1; }
done
if grep -q '\.so$' <<<"$listing"; then echo "sdist: holds a built library"; exit 1; fi
# no tool's cache: CI builds the sdist while mypy and pytest write theirs
if grep -qE '/(\.mypy_cache|\.ruff_cache|\.pytest_cache|__pycache__|node_modules)/' <<<"$listing"; then
    echo "sdist: holds a cache"; exit 1
fi

"$other" -m venv "$work/venv"
# the tested versions (requirements-lock.txt) where they exist for that Python
PIP_CONSTRAINT="$repo/requirements-lock.txt" "$work/venv/bin/python" "${pipq[@]}" "$sdist"
tag=$(sed -n 's/^Tag: //p' "$work"/venv/lib/python*/site-packages/dynval-*.dist-info/WHEEL)
case "$tag" in py3-none-*) ;; *) echo "sdist: wheel tag $tag, expected py3-none-<platform>"; exit 1;; esac
cd "$work"
"$py" -c 'print("time_s,force_N,acc1_mps2"); [print(f"{i / 640!r},{i % 4},1") for i in range(64)]' >t.csv
out=$("$work/venv/bin/dynval" -q features t.csv --json)
grep -q '"mean": 1.5' <<<"$out" || { echo "sdist: unexpected features: $out"; exit 1; }
echo "sdist: built, installed into $("$work/venv/bin/python" --version) ($other), wheel $tag, dynval features ok"
