"""Same-run gateway comparisons for bench/run.py (see bench_gateway.py): rows
{"case": "gateway_<name>", "what", "ns", "unit"}."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_gateway as B  # noqa: E402


def compare() -> list[dict]:
    rows: list[dict] = []
    fid = B.replay_fidelity(3.0)
    for who, r in fid.items():
        for k in ("mean_us", "p95_us", "max_us"):
            rows.append({"case": f"gateway_replay_fidelity_{who}", "what":
                         f"{who}: send-time error {k[:-3]} at 5 ch x 2560 Hz (virtual bus, "
                         f"lost {int(r['lost'])})", "ns": r[k] * 1e3, "unit": "frame"})
    a = B.replay_asap(3.0)
    rows.append({"case": "gateway_replay_asap", "what": f"replay --asap over the virtual bus, "
                 f"lost {int(a['lost'])}", "ns": 1e9 / a["frames_per_s"], "unit": "frame"})
    for who, r in B.mcap_write(30000).items():
        rows.append({"case": f"gateway_mcap_{who}", "what": f"{who}: MCAP write "
                     f"({r['mb_per_s']:.2f} MB/s out)", "ns": 1e9 / r["messages_per_s"],
                     "unit": "message"})
    return rows


if __name__ == "__main__":
    for r in compare():
        print(f"{r['case']:<44} {r['ns']:>12.0f} ns/{r['unit']}  {r['what']}")
