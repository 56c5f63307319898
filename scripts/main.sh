#!/usr/bin/env bash
# README's first command: install what dynval needs, then run the main job on the bundled data:
# replay each bundled test through the firmware loop (the real firmware_sim on vcan0 where the
# kernel has CAN, else the same loop in-process), log everything to one MCAP per test, and
# summarise. Output goes to out/ (override with DV_OUT).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
export PATH="$(pwd)/.venv/bin:$PATH"   # the project virtual environment
out=${DV_OUT:-out}
mkdir -p "$out"
echo
echo "== dynval run: bundled three-story-structure tests (clean, and with an undeclared bumper)"
dynval run data/lanl4dof-sim/clean data/lanl4dof-sim/bumper --asap -o "$out/run"
echo
echo "== dynval inspect: one of the logs"
dynval inspect "$out/run/bumper_test_high_01.mcap"
echo
echo "== dynval residual: the declared model against each test (NRMSE per channel)"
dynval residual data/lanl4dof-sim/clean/declared_model.json data/lanl4dof-sim/clean data/lanl4dof-sim/bumper
echo
echo "== dynval discover: what does the declared model lack? (JSON + HTML report per folder)"
reports=()
for folder in clean bumper; do
    dynval discover data/lanl4dof-sim/$folder/declared_model.json data/lanl4dof-sim/$folder \
        --json "$out/discover-$folder.json" --html "$out/discover-$folder.html" \
        --model-out "$out/discover-$folder-model.json" ||
        [ $? -eq 1 ] # exit 1 is the verdict "the model lacks something", not a failure
    reports+=("$folder=$out/discover-$folder.json")
done
echo
echo "== verdict"
python3 scripts/main_summary.py "$out" "${reports[@]}"
