#!/usr/bin/env bash
# Render every HTML report dynval writes and take a headless-Chromium screenshot of each, for a
# person to look at (gateway/docs/reports.md says what to check). discover runs on the bundled
# bumper data; validate and calibrate need more tests than are bundled and use ../shared/data
# when it is beside the repository (validate on the bundled data is INCONCLUSIVE: 2 tests).
# Output: OUT/<report>.html, OUT/<report>.png and OUT/<report>.log (default OUT: out/report-check).
# Needs: the project venv (scripts/setup.sh) or dynval on PATH, and chromium.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/dynval ] && export PATH="$(pwd)/.venv/bin:$PATH"
out=${1:-out/report-check}
mkdir -p "$out"
browser=$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)
[ -n "$browser" ] || { echo "no chromium on PATH (apt-get install chromium)" >&2; exit 2; }
bundled=data/lanl4dof-sim/bumper
shared=../shared/data/synthetic/lanl4dof-bumper

shot() {  # $1: report name; a tall window holds the whole page
    "$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars \
        --screenshot="$out/$1.png" --window-size=1280,6000 "file://$(realpath "$out/$1.html")" \
        >/dev/null 2>&1
    echo "$out/$1.png"
}

run() {  # $1: report name; the rest: the dynval command (its exit code is the verdict's)
    local name=$1; shift
    set +e
    dynval "$@" >"$out/$name.log" 2>&1
    echo "exit code $?" >>"$out/$name.log"
    set -e
    tail -n 1 "$out/$name.log"
    shot "$name"
}

run discover-bundled discover $bundled/declared_model.json $bundled \
    --json "$out/discover-bundled.json" --html "$out/discover-bundled.html" \
    --model-out "$out/discover-bundled-model.json"
run validate-bundled validate --model $bundled/declared_model.json --experiments $bundled \
    --features peak,std@acc3,acc4 --workers 1 \
    --json "$out/validate-bundled.json" --html "$out/validate-bundled.html"
if [ -d "$shared" ]; then
    run discover-shared discover $shared/declared_model.json $shared \
        --json "$out/discover-shared.json" --html "$out/discover-shared.html"
    run validate-shared validate --model $shared/declared_model.json --experiments $shared \
        --features peak,std@acc3,acc4 --param zeta2=0.01:0.08 --param zeta4=0.001:0.02 \
        --runs 40 --workers 1 --json "$out/validate-shared.json" --html "$out/validate-shared.html"
    run validate-shared-fail validate --model $shared/declared_model.json --experiments $shared \
        --features peak@acc4 --workers 1 \
        --json "$out/validate-shared-fail.json" --html "$out/validate-shared-fail.html"
    run calibrate-shared calibrate --model $shared/declared_model.json --experiments $shared \
        --features peak,std@acc3,acc4 --param zeta2=0.01:0.08 --param zeta4=0.001:0.02 \
        --method both --runs 40 --steps 300 --direct-steps 40 --holdout 6 --workers 1 \
        --json "$out/calibrate-shared.json" --html "$out/calibrate-shared.html" \
        --model-out "$out/calibrate-shared-model.json"
else
    echo "($shared not found: validate and calibrate on the bundled data only)"
fi
