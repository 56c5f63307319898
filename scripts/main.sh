#!/usr/bin/env bash
# README's first command: install what dynval needs, then run the main job on the bundled data.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
echo
echo "== dynval features: the bundled three-story-structure records (clean and with a bumper)"
for f in data/lanl4dof-sim/clean/test_high_01.csv data/lanl4dof-sim/bumper/test_high_01.csv; do
    dynval features "$f"
    echo
done
