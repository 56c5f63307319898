#!/bin/sh
# Build the fuzz targets with clang (libFuzzer + ASan + UBSan) and run them for a bounded time:
# the CAN decoder + sequence tracker (float and double builds), the waveform features with the
# finiteness oracle (float and double) and firmware_sim's core loop (frames sent are finite).
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
    "$CC" -std=c99 -g -O1 $def -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
        -I"$ROOT/include" "$ROOT/tests/fuzz/fuzz_features.c" "$ROOT"/src/*.c -lm \
        -o "$OUT/fuzz_features_$real"
done
"$CC" -std=c99 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
    -I"$ROOT/include" -I"$ROOT/firmware_sim" "$ROOT/tests/fuzz/fuzz_sim_core.c" \
    "$ROOT/firmware_sim/sim_core.c" "$ROOT/firmware_sim/sim_obs_stage.c" \
    "$ROOT/firmware_sim/sim_config.c" "$ROOT"/src/*.c -lm -o "$OUT/fuzz_sim_core"
mkdir -p "$OUT/corpus_sim"
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
mkdir -p "$OUT/corpus_feat_float" "$OUT/corpus_feat_double"
third=$(( (SECS + 4) / 5 ))
rc=0
for t in codec_float codec_double features_float features_double sim_core; do
    r=0
    corpus="$OUT/corpus"; [ "$t" = sim_core ] && corpus="$OUT/corpus_sim"
    case $t in features_*) corpus="$OUT/corpus_feat_${t#features_}" ;; esac
    [ "$t" = sim_core ] && cp "$OUT/corpus/seed" "$corpus/" 2>/dev/null
    "$OUT/fuzz_$t" -max_total_time="$third" -max_len=1300 -print_final_stats=1 \
        -artifact_prefix="$OUT/" "$corpus" >"$OUT/fuzz_$t.log" 2>&1 || r=$?
    grep -E '^(Done|stat::number_of_executed_units)|ERROR|SUMMARY' "$OUT/fuzz_$t.log" || true
    echo "fuzz_$t: exit $r (log $OUT/fuzz_$t.log)"
    [ "$r" -eq 0 ] || rc=$r
done
exit "$rc"
