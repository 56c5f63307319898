#!/usr/bin/env python3
"""Compare self-test logs: the host float twin (first) against the M4 images (the others).

Every log must end with RESULT PASS and hold the same CHECK names. For each dumped output
group (V lines, float bits) it reports: bit-identical, or the count that differ, the largest
difference in ULP and the largest |difference| relative to the group's largest |value|.
usage: compare_m4.py HOST.log TARGET.log [TARGET.log ...]; exit 1 on a failure.
"""
import struct
import sys
from collections import OrderedDict


def parse(path):
    checks, groups, result = OrderedDict(), OrderedDict(), None
    with open(path, errors="replace") as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "CHECK":
                checks[w[2]] = w[1]
            elif w[0] == "V":
                groups.setdefault(w[1], []).extend(int(h, 16) for h in w[3:])
            elif w[0] == "RESULT":
                result = w[1] + " " + w[2]
    return checks, groups, result


def f32(u):
    return struct.unpack("<f", struct.pack("<I", u))[0]


def ordered(u):  # float bits -> integer on a line where adjacent floats differ by 1
    return u if u < 0x80000000 else 0x80000000 - u


def main():
    logs = sys.argv[1:]
    host = parse(logs[0])
    ok = True
    for path in logs:
        _, _, res = parse(path)
        print(f"{path}: {res}")
        ok &= res is not None and res.startswith("PASS")
    for path in logs[1:]:
        checks, groups, _ = parse(path)
        if list(checks) != list(host[0]):
            print(f"{path}: CHECK names differ from the host's")
            ok = False
        print(f"\n{path} vs {logs[0]} (host float twin):")
        print(f"{'output group':38s} {'values':>7s} {'identical':>9s} {'max ulp':>8s} {'max |d|/max|v|':>14s}")
        n_all = n_same = 0
        ident_groups, diff_groups = [], []
        for name, hv in host[1].items():
            tv = groups.get(name)
            if tv is None or len(tv) != len(hv):
                print(f"{name:38s} missing or length differs")
                ok = False
                continue
            same = sum(a == b for a, b in zip(hv, tv))
            ulp = max(abs(ordered(a) - ordered(b)) for a, b in zip(hv, tv))
            vmax = max(abs(f32(a)) for a in hv) or 1.0
            dmax = max(abs(f32(a) - f32(b)) for a, b in zip(hv, tv)) / vmax
            n_all += len(hv)
            n_same += same
            (ident_groups if same == len(hv) else diff_groups).append(name)
            print(f"{name:38s} {len(hv):7d} {same:9d} {ulp:8d} {dmax:14.3g}")
            if 0 < len(hv) - same <= 4:
                for i, (a, b) in enumerate(zip(hv, tv)):
                    if a != b:
                        rel = abs(f32(a) - f32(b)) / (abs(f32(a)) or 1.0)
                        print(f"    [{i}] host {f32(a):.9g} target {f32(b):.9g} "
                              f"({abs(ordered(a) - ordered(b))} ulp, rel {rel:.3g})")
        print(f"total: {n_same}/{n_all} values bit-identical; "
              f"{len(ident_groups)} groups identical, {len(diff_groups)} differ")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
