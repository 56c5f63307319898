#!/usr/bin/env bash
# The JSON-schema parser of the open-source Foxglove Studio (its mcap-support package, as
# built into the last Foxglove Studio release on npm, @foxglove/studio-base 1.48.0): npm pack
# fetches the tarball (integrity-checked by npm, no dependencies installed) and the one webpack
# chunk that holds parseJsonSchema is kept as node_modules/.foxglove-studio/mcap-support.js.
# check_mcap.mjs loads the function from it verbatim. Idempotent.
set -euo pipefail
cd "$(dirname "$0")"
OUT=node_modules/.foxglove-studio/mcap-support.js
[ -s "$OUT" ] && exit 0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
npm pack --silent --pack-destination "$tmp" @foxglove/studio-base@1.48.0 >/dev/null
tar xzf "$tmp"/foxglove-studio-base-1.48.0.tgz -C "$tmp" --wildcards 'package/assets/*.js'
chunk=$(grep -l 'CONCATENATED MODULE: ../mcap-support/src/parseJsonSchema.ts' "$tmp"/package/assets/*.js |
        while read -r f; do echo "$(wc -c <"$f") $f"; done | sort -n | head -1 | cut -d' ' -f2)
[ -n "$chunk" ] || { echo "fetch_studio_parser: parseJsonSchema not found in @foxglove/studio-base" >&2; exit 1; }
mkdir -p "$(dirname "$OUT")"
cp "$chunk" "$OUT"
