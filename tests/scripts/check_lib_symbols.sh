#!/usr/bin/env bash
# The library's fixed-memory promise, checked on the built archive: no allocator, no stdio,
# no abort/exit, and no writable static data (.data/.bss symbols). usage: check_lib_symbols.sh LIB [NM]
set -euo pipefail
lib=$1
nm=${2:-nm}
# a missing archive must fail: nm's error would otherwise read as "no forbidden symbols"
[ -f "$lib" ] || { echo "FAIL: $lib: no such archive"; exit 1; }
forbidden='^(malloc|calloc|realloc|free|printf|fprintf|sprintf|snprintf|puts|putchar|fopen|fwrite|fputs|abort|exit|_exit|__assert_fail|__assert_func|errno|__errno_location|__errno)$'
bad_undef=$("$nm" -u "$lib" | awk 'NF>=2{print $NF}' | grep -E "$forbidden" || true)
bad_data=$("$nm" "$lib" | awk '$2 ~ /^[DdBbCcGgSs]$/ {print $3}' || true)
status=0
if [ -n "$bad_undef" ]; then
    echo "FAIL: $lib calls forbidden functions:"; echo "$bad_undef" | sort -u; status=1
fi
if [ -n "$bad_data" ]; then
    echo "FAIL: $lib has writable static data:"; echo "$bad_data" | sort -u; status=1
fi
[ $status -eq 0 ] && echo "ok: $lib has no allocator/stdio/abort calls and no .data/.bss symbols"
exit $status
