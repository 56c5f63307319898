"""Run the gateway benchmarks and write bench/RESULTS.gateway.md.
    python3 bench/gateway_bench.py [--hours H]   (H = 1 by default; the 1-hour log takes minutes)
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_gateway as B  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seconds", type=float, default=4.0, help="replay length")
    ap.add_argument("-o", type=Path,
                    default=Path(__file__).resolve().parent / "RESULTS.gateway.md")
    a = ap.parse_args()
    fid = B.replay_fidelity(a.seconds)
    asap = B.replay_asap(a.seconds)
    mw = B.mcap_write(60000)
    lg = B.log_1h(3600.0 * a.hours)
    cpu = platform.processor() or platform.machine()
    L = [f"# Gateway benchmarks ({time.strftime('%Y-%m-%d')}, {cpu}, "
         f"Python {platform.python_version()})", "",
         "Made by `python3 bench/gateway_bench.py` (code: bench/bench_gateway.py). Host, "
         "python-can's `virtual` bus (this kernel has no vcan; the VM's emulated vcan is "
         "3-5x slower and not a performance reference).", "",
         f"## Replay timing fidelity, 5 channels x 2560 Hz ({a.seconds:g} s, "
         f"{int(fid['dynval']['frames'])} frames)", "",
         "| player | mean error us | p95 us | max us | drift us/s | drift over run us | lost |",
         "|---|---|---|---|---|---|---|"]
    for who, r in fid.items():
        L.append(f"| {who} | {r['mean_us']:.1f} | {r['p95_us']:.0f} | {r['max_us']:.0f} | "
                 f"{r['drift_us_per_s']:+.2f} | {r['drift_us_over_run']:+.1f} | "
                 f"{int(r['lost'])} |")
    L += ["", "Error = time bus.send returned minus the frame's due time (the recorded time of "
          "its last sample).", "",
          "## Replay as fast as possible (virtual bus)", "",
          f"{int(asap['frames'])} frames at {asap['frames_per_s']:.0f} frames/s, lost "
          f"{int(asap['lost'])} (a receiver thread counted them).", "",
          "## MCAP write (60000 sample frames)", "",
          "| writer | frames/s | messages/s | MB/s written | file MB |", "|---|---|---|---|---|"]
    for who, r in mw.items():
        L.append(f"| {who} | {r['frames_per_s']:.0f} | {r['messages_per_s']:.0f} | "
                 f"{r['mb_per_s']:.2f} | {r['file_mb']:.2f} |")
    L += ["", "dynval_logger decodes every frame with the C codec and writes four JSON messages "
          "per sample frame (/can/raw, and one /dv/samples/<ch> message per sample, for "
          "Foxglove's plots); the raw writer adds the 8 bytes.",
          "", f"## Logging a {a.hours:g}-hour test streamed (5 x 640 Hz)", "",
          f"{int(lg['frames'])} sample frames in {lg['wall_s']:.0f} s, file "
          f"{lg['file_mb']:.0f} MB; peak RSS {lg['rss_start_mb']:.0f} MB before, "
          f"{lg['rss_at_10pct_mb']:.0f} MB at 10 %, {lg['rss_peak_mb']:.0f} MB at the end "
          "(bounded: chunks are written as they fill).", ""]
    a.o.write_text("\n".join(L))
    print("\n".join(L))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
