"""`dynval recover KILLED.mcap -o FIXED.mcap`: rewrite the readable part of an MCAP file a
killed logger left (no footer, no summary) as a complete file, which the official mcap reader
and Foxglove open: every record up to the last complete chunk, the same schemas, channels,
messages and metadata, then a "dynval.recovered" metadata record saying what was cut."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from dynval.errors import InputFileError

log = logging.getLogger(__name__)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("recover", help="make a killed logger's MCAP readable by any MCAP tool")
    p.add_argument("file", type=Path, help="MCAP file without footer (or with a damaged chunk)")
    p.add_argument("-o", "--output", type=Path, required=True, help="complete MCAP to write")
    p.set_defaults(run=run)


def recover(src: Path, dst: Path) -> dict[str, Any]:
    """Copy the readable records of src into a new, complete MCAP dst; returns counts."""
    from mcap.records import Attachment, Channel, Message, Metadata, Schema
    from mcap.writer import Writer

    from dynval.io.mcapfile import Scan, iter_records
    from dynval.mcap_log import compression

    if src.resolve() == dst.resolve():
        raise InputFileError(dst, "recover writes a new file; give another output name")
    sc = Scan()
    counts = {"messages": 0, "channels": 0, "schemas": 0, "metadata": 0}
    with open(dst, "wb") as f:
        w: Any = Writer(f, compression=compression())
        w.start(profile="", library="dynval recover")
        schemas: dict[int, int] = {0: 0}
        chans: dict[int, int] = {}
        for r in iter_records(src, scan_out=sc):
            if isinstance(r, Schema):
                schemas[r.id] = w.register_schema(r.name, r.encoding, r.data)
                counts["schemas"] += 1
            elif isinstance(r, Channel) and r.schema_id in schemas:
                chans[r.id] = w.register_channel(r.topic, r.message_encoding,
                                                 schemas[r.schema_id], dict(r.metadata))
                counts["channels"] += 1
            elif isinstance(r, Message) and r.channel_id in chans:
                w.add_message(chans[r.channel_id], log_time=r.log_time, data=r.data,
                              publish_time=r.publish_time, sequence=r.sequence)
                counts["messages"] += 1
            elif isinstance(r, Metadata):
                w.add_metadata(r.name, dict(r.metadata))
                counts["metadata"] += 1
            elif isinstance(r, Attachment):
                w.add_attachment(r.create_time, r.log_time, r.name, r.media_type, r.data)
        w.add_metadata("dynval.recovered", {
            "source": str(src), "source_bytes": str(sc.size), "read_bytes": str(sc.good_bytes),
            "had_footer": str(sc.complete).lower(), "stopped_at": sc.error or "end of data"})
        w.finish()
    return {**counts, "complete": sc.complete, "cut_bytes": sc.truncated_bytes,
            "error": sc.error}


def run(args: argparse.Namespace) -> int:
    r = recover(args.file, args.output)
    state = "had its footer" if r["complete"] else f"had no footer ({r['cut_bytes']} bytes " \
        "after the last complete record dropped)"
    print(f"{args.output}: {r['messages']} messages on {r['channels']} channels recovered from "
          f"{args.file}, which {state}" + (f"; read stopped at: {r['error']}" if r["error"]
                                            else ""))
    return 0
