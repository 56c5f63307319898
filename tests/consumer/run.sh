#!/usr/bin/env bash
# Build and run the consumer every way a user links dynval: float and double installed side by
# side into one prefix, then find_package (default, COMPONENTS f32, COMPONENTS f64), pkg-config
# (dynval-f32: static; dynval-f64: the versioned shared library), and add_subdirectory.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
cmake -S "$repo" -B "$work/lib32" -DDV_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/lib32" -j2 >/dev/null
cmake --install "$work/lib32" --prefix "$prefix" >/dev/null
cmake -S "$repo" -B "$work/lib64" -DDV_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release \
    -DDV_REAL_TYPE=double -DDV_BUILD_SHARED=ON >/dev/null
cmake --build "$work/lib64" -j2 >/dev/null
cmake --install "$work/lib64" --prefix "$prefix" >/dev/null
libdir=$(find "$prefix" -name 'libdynval-f64.so.*.*.*' -printf '%h\n')
soname=$(objdump -p "$libdir"/libdynval-f64.so.*.*.* | awk '/SONAME/ {print $2}')
[ "$soname" = "libdynval-f64.so.0" ] || { echo "consumer: SONAME $soname"; exit 1; }

expect() { # expect BYTES PROGRAM: the consumer ran with samples of BYTES bytes
    out=$("$2")
    echo "$out"
    case "$out" in *", $1-byte samples,"*) ;; *) echo "consumer: expected $1-byte samples"; exit 1;; esac
}
for comp in "" f32 f64; do
    cmake -S "$here" -B "$work/pkg$comp" -DCMAKE_PREFIX_PATH="$prefix" \
        -DDV_CONSUMER_COMPONENT="$comp" >/dev/null
    cmake --build "$work/pkg$comp" >/dev/null
    case "$comp" in f64) bytes=8;; *) bytes=4;; esac  # no component: f32, the default type
    expect $bytes "$work/pkg$comp/consumer"
done
if cmake -S "$here" -B "$work/pkgbad" -DCMAKE_PREFIX_PATH="$prefix" \
        -DDV_CONSUMER_COMPONENT=f16 >/dev/null 2>&1; then
    echo "consumer: an unknown component was accepted"; exit 1
fi

export PKG_CONFIG_PATH="$libdir/pkgconfig"
for pc in dynval-f32 dynval-f64; do
    [ "$(pkg-config --modversion $pc)" = "$(sed -n 's/^#define DV_VERSION_STRING "\(.*\)"$/\1/p' \
        "$repo/include/dynval/dv_version.h")" ] || { echo "consumer: $pc version"; exit 1; }
    # shellcheck disable=SC2046  # word splitting of the flags is the point
    # -lm: main.c itself calls sin()
    cc -std=c99 $(pkg-config --cflags $pc) "$here/main.c" -o "$work/pc-$pc" $(pkg-config --libs $pc) -lm
done
expect 4 "$work/pc-dynval-f32"
# grep reads all of ldd's output: with -q it may stop early, ldd then dies of SIGPIPE and
# pipefail fails the check (seen once in a fresh-clone run)
ldd "$work/pc-dynval-f64" | grep 'libdynval-f64.so.0 ' >/dev/null ||
    { echo "consumer: not shared"; exit 1; }
LD_LIBRARY_PATH="$libdir" expect 8 "$work/pc-dynval-f64"

cmake -S "$here" -B "$work/sub" -DDV_CONSUMER_SUBDIR=ON >/dev/null
cmake --build "$work/sub" -j2 >/dev/null
expect 4 "$work/sub/consumer"
echo "consumer: find_package (default, f32, f64 side by side), pkg-config and add_subdirectory work"
