"""`dynval inspect FILE.mcap`: topics, message counts, rates, gaps, counters (also of a file
a killed logger left: read up to its last complete chunk)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from dynval.errors import InputFileError
from dynval.io.jsonfile import parse_json
from dynval.io.mcapfile import Message, Scan, iter_messages
from dynval.topics import T_EVENTS, T_STATUS

GAP_FACTOR = 5.0  # an interval this many times the median interval is a gap


def add_parser(sub: Any) -> None:
    p = sub.add_parser("inspect", help="summarise an MCAP file written by dynval")
    p.add_argument("file", type=Path)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def inspect(path: Path) -> dict[str, Any]:
    sc = Scan()
    topics: dict[str, dict[str, Any]] = {}
    events: dict[str, int] = {}
    last_status: dict[str, Any] | None = None
    for m in iter_messages(path, scan_out=sc):
        t = topics.get(m.topic)
        if t is None:
            t = topics[m.topic] = {"count": 0, "first_ns": m.log_time, "last_ns": m.log_time,
                                   "dts": []}
        if t["count"]:
            t["dts"].append(m.log_time - t["last_ns"])
        t["count"] += 1
        t["last_ns"] = m.log_time
        if m.topic == T_EVENTS:
            name, count = _event(path, m)
            events[name] = events.get(name, 0) + count
        elif m.topic == T_STATUS:
            last_status = m.data
    out: dict[str, Any] = {"file": str(path), "complete": sc.complete, "bytes": sc.size,
                           "chunks": sc.chunks, "unreadable_tail_bytes": sc.truncated_bytes,
                           "error": sc.error, "topics": {}, "events": events,
                           "last_status": last_status}
    for name, t in sorted(topics.items()):
        span = (t["last_ns"] - t["first_ns"]) / 1e9
        dts = sorted(t.pop("dts"))
        med = dts[len(dts) // 2] if dts else 0
        gaps = [d for d in dts if med > 0 and d > GAP_FACTOR * med]
        out["topics"][name] = {"count": t["count"], "span_s": span,
                               "rate_hz": (t["count"] - 1) / span if span > 0 else 0.0,
                               "gaps": len(gaps), "max_gap_ms": (dts[-1] / 1e6) if dts else 0.0}
    md = sc.metadata
    out["metadata"] = md.get("dynval", {})
    if "dynval.summary" in md:
        out["summary"] = {k: parse_json(path, v) for k, v in md["dynval.summary"].items()}
        _check_summary(path, out["summary"])
    return out


def _hz(fs: Any) -> str:
    """The metadata's rate as a person reads it: 640 Hz, not 639.9999999998545 Hz (the rate
    a CSV's time column gives)."""
    try:
        return f"{float(fs):.6g} Hz"
    except (TypeError, ValueError):
        return f"{fs if fs is not None else '?'} Hz"


def status_text(st: dict[str, Any]) -> str:
    """A DV_STATUS message in words: its state bits named, then its counters."""
    from dynval import contract

    state = st.get("state")
    if isinstance(state, int) and not isinstance(state, bool):
        bits = [name.replace("_", " ") for name, v in sorted(contract.named("DV_STATE_").items(),
                                                             key=lambda kv: kv[1])
                if state & v]
        words = f"{', '.join(bits) or 'idle'} (state 0x{state:02x})"
    else:
        words = f"state {state}"
    counters = ", ".join(f"{k} {v}" for k, v in st.items() if k != "state")
    return f"{words}, {counters}" if counters else words


def _event(path: Path, m: Message) -> tuple[str, int]:
    name, count = m.data.get("event"), m.data.get("count")
    if not isinstance(name, str) or isinstance(count, bool) or not isinstance(count, int):
        raise InputFileError(path, f"{m.topic} message is not a dynval event (needs 'event' "
                             "and an integer 'count')", None, f"sequence {m.sequence}")
    return name, count


def _check_summary(path: Path, summary: dict[str, Any]) -> None:
    """The parts of the dynval.summary metadata the report reads have their types."""
    seq = summary.get("sequence", {})
    ok = isinstance(seq, dict) and all(
        isinstance(v, dict) and all(isinstance(v.get(k, 0), int) for k in ("ok", "lost"))
        for v in seq.values())
    if not ok:
        raise InputFileError(path, "the dynval.summary metadata's 'sequence' is not a table "
                             "of counts per channel")


def run(args: argparse.Namespace) -> int:
    r = inspect(args.file)
    if args.json:
        json.dump(r, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    md = r["metadata"]
    state = "complete" if r["complete"] else (
        f"NO FOOTER: read up to the last complete chunk, {r['unreadable_tail_bytes']} bytes "
        "unreadable")
    print(f"{r['file']}: {r['bytes']} bytes, {r['chunks']} chunks, {state}")
    if r["error"]:
        print(f"  read error: {r['error']}")
    if md:
        print(f"  test {md.get('test', '?')} ({md.get('source', '')}, sha256 "
              f"{md.get('source_sha256', '')[:12]}), fs {_hz(md.get('fs_hz'))}, "
              f"{md.get('software', '')}")
    print(f"  {'topic':<28} {'messages':>9} {'rate/s':>10} {'span s':>8} {'gaps':>5} "
          f"{'max gap ms':>10}")
    for name, t in r["topics"].items():
        print(f"  {name:<28} {t['count']:>9} {t['rate_hz']:>10.1f} {t['span_s']:>8.2f} "
              f"{t['gaps']:>5} {t['max_gap_ms']:>10.2f}")
    print(f"  events: {r['events'] or 'none'}")
    if r["last_status"]:
        print(f"  last DV_STATUS: {status_text(r['last_status'])}")
    if "summary" in r:
        seq = r["summary"].get("sequence", {})
        lost = {k: v["lost"] for k, v in seq.items() if v.get("lost")}
        print(f"  sequence: {sum(v.get('ok', 0) for v in seq.values())} frames in order, lost "
              f"{lost or 0}")
    return 0
