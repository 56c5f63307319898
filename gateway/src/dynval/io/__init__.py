"""Readers for recorded tests. Every reader returns a Recording; bad input raises
InputFileError naming the file, line and column (or, with lenient=True, recoverable problems
are counted in Recording.warnings and logged — never silently dropped).

Formats: CSV with a header (.csv), whitespace text with a given rate (.txt/.dat/.asc, --fs),
the BRFD JSON layout (.json), the DROPBEAR LabVIEW text (.txt with its header) and MCAP files
written by dynval (.mcap). A channel map (io.channelmap) selects, renames and scales."""
from __future__ import annotations

from pathlib import Path

from dynval.errors import InputFileError
from dynval.io.brfd import looks_like_brfd, read_brfd
from dynval.io.channelmap import ChannelMap, apply_channel_map, load_channel_map
from dynval.io.csvfile import read_csv
from dynval.io.dropbear import looks_like_dropbear, read_dropbear
from dynval.io.recording import Channel, Recording
from dynval.io.text import read_text

__all__ = ["Channel", "ChannelMap", "Recording", "apply_channel_map", "load_channel_map",
           "read_brfd", "read_csv", "read_dropbear", "read_test", "read_text", "TEST_SUFFIXES"]

TEST_SUFFIXES = (".csv", ".txt", ".dat", ".asc", ".json", ".mcap")


def read_test(path: Path | str, *, lenient: bool = False, fs_hz: float | None = None,
              channel_map: ChannelMap | None = None) -> Recording:
    """Read a recorded test, choosing the reader from the suffix (and, for .txt, the header),
    then apply the channel map (or the defaults)."""
    p = Path(path)
    suf = p.suffix.lower()
    if not p.is_file():
        raise InputFileError(p, "no such file")
    if suf == ".csv":
        rec = read_csv(p, lenient=lenient)
    elif suf == ".json":
        if not looks_like_brfd(p):
            raise InputFileError(p, "a .json test must have the BRFD layout {\"data\": ...}", 1)
        rec = read_brfd(p, lenient=lenient)
    elif suf == ".mcap":
        from dynval.io.mcapfile import read_mcap

        rec = read_mcap(p, lenient=lenient)
    elif suf in (".txt", ".dat", ".asc"):
        if looks_like_dropbear(p):
            rec = read_dropbear(p, lenient=lenient)
        elif fs_hz is None:
            raise InputFileError(p, "a whitespace text test needs its sampling rate (--fs HZ)")
        else:
            rec = read_text(p, fs_hz, lenient=lenient)
    else:
        raise InputFileError(p, f"unknown test file type '{p.suffix}' (supported: "
                             f"{', '.join(TEST_SUFFIXES)})")
    return apply_channel_map(rec, channel_map)
