#!/bin/sh
# Build the codec fuzz target with clang (libFuzzer + ASan + UBSan) and run it for a bounded time.
# usage: tests/fuzz/run_fuzz.sh [SECONDS=30] [OUTDIR=build/fuzz]
# Exit status: 0 when the time ran out without a crash; libFuzzer's status otherwise.
set -eu
SECS=${1:-30}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
OUT=${2:-$ROOT/build/fuzz}
CC=${FUZZ_CC:-clang}
mkdir -p "$OUT/corpus"
for real in float double; do
    def=""; [ "$real" = double ] && def="-DDV_REAL_DOUBLE"
    "$CC" -std=c99 -g -O1 $def -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
        -I"$ROOT/include" "$ROOT/tests/fuzz/fuzz_codec.c" "$ROOT/src/dv_codec.c" \
        "$ROOT/src/dv_common.c" -lm -o "$OUT/fuzz_codec_$real"
done
# a seed: one valid frame of each kind, then a sample stream with a gap and a duplicate
python3 - "$OUT/corpus/seed" <<'PY' 2>/dev/null || true
import struct, sys
recs = b""
for idsel, d in [(0, b"\x01"*8), (1, b"\x01\x00\x01\x02\x03\x04\x00\x00"),
                 (2, b"\x00\x01\x80\x02\x00\x00\x80\x3a"), (4, b"\x11\x00\x00\x00\x00\x00\x80\x3f"),
                 (3, b"\x00\x00\x01\x00\x02\x00\x03\x00"), (3, b"\x00\x02\x01\x00\x02\x00\x03\x00"),
                 (3, b"\x00\x02\x01\x00\x02\x00\x03\x00"), (3, b"\x00\x01\x00\x80\x00\x00\x00\x00")]:
    recs += struct.pack("<IB", idsel, 8) + d
open(sys.argv[1], "wb").write(recs)
PY
half=$(( (SECS + 1) / 2 ))
rc=0
for real in float double; do
    r=0
    "$OUT/fuzz_codec_$real" -max_total_time="$half" -max_len=1300 -print_final_stats=1 \
        -artifact_prefix="$OUT/" "$OUT/corpus" >"$OUT/fuzz_$real.log" 2>&1 || r=$?
    grep -E '^(Done|stat::number_of_executed_units)|ERROR|SUMMARY' "$OUT/fuzz_$real.log" || true
    echo "fuzz_codec_$real: exit $r (log $OUT/fuzz_$real.log)"
    [ "$r" -eq 0 ] || rc=$r
done
exit "$rc"
