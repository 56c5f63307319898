"""Run the gateway benchmarks and write bench/RESULTS.gateway.md.
    python3 bench/gateway_bench.py [--hours H]   (H = 1 by default; the 1-hour log takes minutes)
    python3 bench/gateway_bench.py --logging-only   (re-measure the logging sections and keep
                                                     the file's replay sections as they are)
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
    ap.add_argument("--logging-only", action="store_true")
    ap.add_argument("--reps", type=int, default=5, help="MCAP write repeats")
    a = ap.parse_args()
    cpu = platform.processor() or platform.machine()
    head = [f"# Gateway benchmarks ({time.strftime('%Y-%m-%d')}, {cpu}, "
            f"Python {platform.python_version()})", "",
            "Made by `python3 bench/gateway_bench.py` (code: bench/bench_gateway.py). Host, "
            "python-can's `virtual` bus (this kernel has no vcan; the VM's emulated vcan is "
            "3-5x slower and not a performance reference).", ""]
    if a.logging_only:
        old = a.o.read_text().split("\n")
        cut = next(i for i, x in enumerate(old) if x.startswith("## MCAP write"))
        lines = old[:cut]  # the replay sections as they were measured, with their date
    else:
        lines = head + replay_lines(a.seconds)
    lines += logging_lines(a.hours, a.reps)
    a.o.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


def replay_lines(seconds: float) -> list[str]:
    fid = B.replay_fidelity(seconds)
    asap = B.replay_asap(seconds)
    L = [f"## Replay timing fidelity, 5 channels x 2560 Hz ({seconds:g} s, "
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
          f"{int(asap['lost'])} (a receiver thread counted them).", ""]
    return L


def logging_lines(hours: float, reps: int) -> list[str]:
    mw = B.mcap_write(60000, reps)
    lg = B.log_1h(3600.0 * hours)  # before the bus runs: its RSS is the logger's alone
    bl = B.log_bus_16x5k(10.0)
    ba = B.log_bus_16x5k(10.0, paced=False)
    cs = B.logger_cpu_split()  # last: its messages would raise the others' peak RSS
    d, r0 = mw["dynval_logger"], mw["mcap_raw_writer"]
    L = [f"## MCAP write (60000 sample frames, 5 x 2560 Hz; {time.strftime('%Y-%m-%d')}, "
         f"medians of {reps} alternating runs, each writer in a fresh process)", "",
         "| writer | frames/s | messages/s | MB/s written | file MB | peak RSS MB |",
         "|---|---|---|---|---|---|"]
    for who, r in mw.items():
        L.append(f"| {who} | {r['frames_per_s']:.0f} | {r['messages_per_s']:.0f} | "
                 f"{r['mb_per_s']:.2f} | {r['file_mb']:.2f} | {r['rss_peak_mb']:.0f} |")
    L += ["", f"dynval_logger / mcap_raw_writer frames/s, pair by pair: median "
          f"{d['ratio_median']:.1f}x (min {d['ratio_min']:.1f}x, max {d['ratio_max']:.1f}x; "
          "target >= 5x; the logger this replaced, JSON decoded one frame at a time, was "
          "0.19x on 2026-11-22: 13105 vs 69471 frames/s).", "",
          f"Per frame the logger writes {d['messages'] / 60000:.0f} messages where the raw "
          f"writer writes 1: {d['messages_per_s'] / r0['messages_per_s']:.1f}x its "
          f"messages/s and {d['mb_per_s'] / r0['mb_per_s']:.1f}x its MB/s.", "",
          "Where the time goes (bench_gateway.logger_cpu_split: CPU time per frame of each "
          "part run alone in one thread, the minimum of 7 runs of 61440 frames): "
          f"the reader's AsyncLog.put {cs['put']:.2f} us, the writer thread reading the "
          f"python-can Messages' fields {cs['fields']:.2f} us, decoding and building the "
          f"records {cs['records']:.2f} us, the I/O thread finishing chunks (lz4, CRC, "
          f"message indexes, write) {cs['chunks']:.2f} us: "
          f"{sum(cs.values()):.2f} us in all, against "
          f"{1e6 / r0['frames_per_s']:.2f} us per frame for the raw writer "
          f"({r0['frames_per_s'] * sum(cs.values()) / 1e6:.2f} of its time). Everything "
          "but lz4, the CRC and the write holds the GIL (more than "
          f"{cs['put'] + cs['fields'] + cs['records']:.2f} us per frame: put, fields and "
          "records), so 5x needs a free core for the I/O thread and is out of reach while "
          "the host's other jobs take the cores; past it, the Python work per python-can "
          f"Message (put and reading its fields) is "
          f"{100 * (cs['put'] + cs['fields']) / sum(cs.values()):.0f} % of the logger's "
          "CPU: a writer in another process, fed arrays rather than Messages, is the next "
          "step.", "",
          "dynval_logger is the path of `dynval log`: the bus reader's AsyncLog.put per "
          "python-can Message, the writer thread decoding blocks of 2048 frames with the C "
          "codec (dv_codec_decode_n, dv_seq_track_n, dv_codec_sample_values), four messages "
          "per sample frame (/can/raw and one protobuf dynval.Sample per sample on "
          "/dv/samples/<ch>, for Foxglove's plots) built as numpy record arrays, chunks "
          "compressed with CRCs and message indexes in an I/O thread. Both writers use lz4 "
          "(the logger's default: with zstd the logger ran at about 0.7x its lz4 rate in a "
          "same-run check, for files 0.7x the size). The raw writer adds the 8 bytes of "
          "each frame with mcap's Writer.add_message.", "",
          f"## Logging {int(bl['channels'])} channels x {bl['fs_hz']:.0f} Hz from the virtual "
          f"bus ({bl['seconds']:g} s of data)", "",
          "| sender | frames sent | received | logged frames/s | dropped by the logger | "
          "sequence gaps | samples per channel in the file | file MB | peak RSS MB |",
          "|---|---|---|---|---|---|---|---|---|"]
    for who, r in (("paced", bl), ("as fast as it can", ba)):
        L.append(f"| {who} | {r['frames_sent']:.0f} | {r['frames_received']:.0f} | "
                 f"{r['frames_per_s']:.0f} | {r['dropped']:.0f} | {r['seq_lost']:.0f} | "
                 f"{r['samples_in_file_min']:.0f} of {r['samples_expected']:.0f} | "
                 f"{r['file_mb']:.1f} | {r['rss_peak_mb']:.0f} |")
    L += ["", f"The bus rate is {bl['channels'] * bl['fs_hz'] / 3:.0f} frames/s; a sender "
          "thread in the same process (python-can's virtual bus is in-process) sends "
          "pre-built frames, paced at their due times (lateness p95 "
          f"{bl['send_late_p95_us'] / 1e3:.1f} ms: when it is large, the sender sharing the "
          "interpreter and the host's cores with the logger, not the logger, set the rate "
          "achieved) or unpaced. Dropped = frames the writer thread could not take "
          "(logger_overflow events in the file).", "",
          f"## Logging a {hours:g}-hour test streamed (5 x 640 Hz)", "",
          f"{int(lg['frames'])} sample frames in {lg['wall_s']:.0f} s, file "
          f"{lg['file_mb']:.0f} MB; peak RSS {lg['rss_start_mb']:.0f} MB before, "
          f"{lg['rss_at_10pct_mb']:.0f} MB at 10 %, {lg['rss_peak_mb']:.0f} MB at the end "
          "(bounded: chunks are written as they fill; the JSON logger of 2026-11-22: 513 s, "
          "314 MB with zstd).", ""]
    return L


if __name__ == "__main__":
    raise SystemExit(main())
