#!/usr/bin/env bash
# Build and run the consumer both ways: find_package after cmake --install, and add_subdirectory.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake -S "$repo" -B "$work/lib" -DDV_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/lib" -j2 >/dev/null
cmake --install "$work/lib" --prefix "$work/prefix" >/dev/null
cmake -S "$here" -B "$work/pkg" -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/pkg" >/dev/null
"$work/pkg/consumer"
cmake -S "$here" -B "$work/sub" -DDV_CONSUMER_SUBDIR=ON >/dev/null
cmake --build "$work/sub" -j2 >/dev/null
"$work/sub/consumer"
echo "consumer: find_package and add_subdirectory both work"
