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
FLAGS="-std=c99 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all"
# the five targets are built two at a time (2 cores): each is one clang over the library
build() { # target, extra flags and sources...
    t=$1; shift
    # shellcheck disable=SC2086
    "$CC" $FLAGS -I"$ROOT/include" "$@" -lm -o "$OUT/fuzz_$t" >"$OUT/build_$t.log" 2>&1 \
        || { cat "$OUT/build_$t.log"; return 1; }
}
SIM="$ROOT/firmware_sim"
build codec_float "$ROOT/tests/fuzz/fuzz_codec.c" "$ROOT/src/dv_codec.c" "$ROOT/src/dv_common.c" &
b1=$!
build codec_double -DDV_REAL_DOUBLE "$ROOT/tests/fuzz/fuzz_codec.c" "$ROOT/src/dv_codec.c" \
    "$ROOT/src/dv_common.c"
wait "$b1"
build features_float "$ROOT/tests/fuzz/fuzz_features.c" "$ROOT"/src/*.c &
b1=$!
build features_double -DDV_REAL_DOUBLE "$ROOT/tests/fuzz/fuzz_features.c" "$ROOT"/src/*.c
wait "$b1"
build sim_core -I"$SIM" "$ROOT/tests/fuzz/fuzz_sim_core.c" "$SIM/sim_core.c" \
    "$SIM/sim_obs_stage.c" "$SIM/sim_config.c" "$ROOT"/src/*.c
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
# two targets at a time (2 cores), each for its share of the time
fuzz() { # target
    t=$1
    corpus="$OUT/corpus"; [ "$t" = sim_core ] && corpus="$OUT/corpus_sim"
    case $t in features_*) corpus="$OUT/corpus_feat_${t#features_}" ;; esac
    [ "$t" = sim_core ] && cp "$OUT/corpus/seed" "$corpus/" 2>/dev/null
    r=0
    "$OUT/fuzz_$t" -max_total_time="$third" -max_len=1300 -print_final_stats=1 \
        -artifact_prefix="$OUT/" "$corpus" >"$OUT/fuzz_$t.log" 2>&1 || r=$?
    echo "$r" >"$OUT/fuzz_$t.rc"
}
fuzz codec_float & p1=$!; fuzz codec_double; wait "$p1"
fuzz features_float & p1=$!; fuzz features_double; wait "$p1"
fuzz sim_core
rc=0
for t in codec_float codec_double features_float features_double sim_core; do
    r=$(cat "$OUT/fuzz_$t.rc")
    grep -E '^(Done|stat::number_of_executed_units)|ERROR|SUMMARY' "$OUT/fuzz_$t.log" || true
    echo "fuzz_$t: exit $r (log $OUT/fuzz_$t.log)"
    [ "$r" -eq 0 ] || rc=$r
done
exit "$rc"
