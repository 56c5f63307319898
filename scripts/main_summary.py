#!/usr/bin/env python3
"""The main job's last step: one verdict line per test folder from `dynval discover`'s JSON
reports, and one HTML page (out/index.html) that links everything the job wrote.

    python3 scripts/main_summary.py OUT_DIR NAME=REPORT.json [NAME=REPORT.json ...]
"""
from __future__ import annotations

import html
import json
import math
import sys
from pathlib import Path


def floor_ratio(doc: dict, key: str) -> float:
    """Held-out RMSE over the noise floor, as the mean over channels (1 = at the floor)."""
    rmse = doc[key]["held_out"]
    noise = doc["noise_floor"]
    r = [rmse[c] / noise[c] for c in doc["channels"] if noise.get(c) and rmse.get(c) is not None]
    return sum(r) / len(r) if r else math.nan


def verdict(name: str, doc: dict) -> str:
    before, after = floor_ratio(doc, "rmse_before"), floor_ratio(doc, "rmse_after")
    if doc["effects"]:
        what = "the model lacks " + "; ".join(e["label"] for e in doc["effects"])
        err = f"held-out error {before:.1f}x -> {after:.1f}x the noise floor"
    else:
        what = doc["verdict"]
        err = f"held-out error {before:.1f}x the noise floor"
    return f"{name} tests: {what}; {err}"


def page(out: Path, lines: list[str], reports: dict[str, Path]) -> str:
    files = sorted(p for p in out.rglob("*") if p.is_file() and p.name != "index.html")
    rows = "".join(f'<li><a href="{html.escape(str(p.relative_to(out)))}">'
                   f"{html.escape(str(p.relative_to(out)))}</a> ({p.stat().st_size / 1024:.0f} KiB)"
                   "</li>" for p in files)
    verdicts = "".join(f"<li>{html.escape(s)}</li>" for s in lines)
    links = "".join(f'<li><a href="{html.escape(str(p.with_suffix(".html").relative_to(out)))}">'
                    f"discover report: {html.escape(n)}</a></li>" for n, p in reports.items())
    return ("<!doctype html><html><head><meta charset='utf-8'><title>dynval main job</title>"
            "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto}</style></head>"
            "<body><h1>dynval: the bundled tests against the declared model</h1>"
            f"<h2>Verdicts</h2><ul>{verdicts}</ul><h2>Reports</h2><ul>{links}</ul>"
            f"<h2>Everything this job wrote</h2><ul>{rows}</ul></body></html>")


def main(argv: list[str]) -> int:
    out = Path(argv[1])
    reports = {a.split("=", 1)[0]: Path(a.split("=", 1)[1]) for a in argv[2:]}
    lines = [verdict(n, json.loads(p.read_text(encoding="utf-8"))) for n, p in reports.items()]
    for s in lines:
        sys.stdout.write(s + "\n")
    index = out / "index.html"
    index.write_text(page(out, lines, reports), encoding="utf-8")
    sys.stdout.write(f"report: {index}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
