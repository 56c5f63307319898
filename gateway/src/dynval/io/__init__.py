"""Readers for recorded tests. Every reader returns a Recording; bad input raises
InputFileError naming the file, line and column (or, with lenient=True, recoverable problems
are counted in Recording.warnings and logged — never silently dropped).

Formats: CSV with a header (.csv), whitespace text with a given rate (.txt/.dat/.asc, --fs),
the BRFD JSON layout (.json), the DROPBEAR LabVIEW text (.txt with its header), MCAP files
written by dynval (.mcap), and the test engineers' formats of io.formats: UFF 58 (.uff, .unv),
MDF 4 (.mf4, .mdf), HDF5 (.h5, .hdf5, .hdf), MATLAB (.mat); a pandas DataFrame through
read_dataframe. A channel map (io.channelmap) selects, renames and scales."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from dynval.errors import InputFileError
from dynval.io.brfd import looks_like_brfd, read_brfd
from dynval.io.channelmap import ChannelMap, apply_channel_map, load_channel_map
from dynval.io.csvfile import read_csv
from dynval.io.dropbear import looks_like_dropbear, read_dropbear
from dynval.io.formats import (
    HDF5_SUFFIXES,
    MAT_SUFFIXES,
    MDF_SUFFIXES,
    UFF_SUFFIXES,
    read_dataframe,
    read_hdf5,
    read_mat,
    read_mdf,
    read_uff,
)
from dynval.io.recording import Channel, Recording
from dynval.io.text import read_text

__all__ = ["Channel", "ChannelMap", "Recording", "apply_channel_map", "collect_tests",
           "load_channel_map", "read_brfd", "read_csv", "read_dataframe", "read_dropbear",
           "read_hdf5", "read_mat", "read_mdf", "read_test", "read_text", "read_uff",
           "TEST_SUFFIXES"]

TEST_SUFFIXES = (".csv", ".txt", ".dat", ".asc", ".json", ".mcap", *UFF_SUFFIXES,
                 *MDF_SUFFIXES, *HDF5_SUFFIXES, *MAT_SUFFIXES)
NOT_TESTS = ("meta.json", "declared_model.json")  # names (or name endings) in test folders


def collect_tests(paths: Sequence[Path | str]) -> list[Path]:
    """The tests the paths name: a file as given; a folder's files with a test suffix, sorted by
    name, except its metadata and model (names ending in NOT_TESTS). InputFileError for a path
    that does not exist or a folder without tests. Every command that reads tests uses this."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in
                           TEST_SUFFIXES and not f.name.endswith(NOT_TESTS))
            if not found:
                raise InputFileError(p, f"folder holds no tests ({', '.join(TEST_SUFFIXES)})")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise InputFileError(p, "no such file or folder")
    return out


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
    elif suf in UFF_SUFFIXES:
        rec = read_uff(p, lenient=lenient)
    elif suf in MDF_SUFFIXES:
        rec = read_mdf(p, lenient=lenient)
    elif suf in HDF5_SUFFIXES:
        rec = read_hdf5(p, lenient=lenient)
    elif suf in MAT_SUFFIXES:
        rec = read_mat(p, lenient=lenient)
    elif suf in (".txt", ".dat", ".asc"):
        from dynval.canlog import is_vector_asc

        if suf == ".asc" and is_vector_asc(p):
            raise InputFileError(p, "a Vector ASC CAN log, not a test of numbers: send it with "
                                 "`dynval replay`, or decode it with `dynval convert FILE -o "
                                 "FILE.mcap`", 1)
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
