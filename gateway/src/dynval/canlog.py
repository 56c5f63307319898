"""Standard CAN log files through python-can's own readers and writers (can.LogReader,
can.Logger): Vector ASC (.asc) and BLF (.blf), PEAK TRC (.trc), candump -L (.log).

- sniff: is a file a CAN log (a Vector .asc is told apart from a whitespace-numeric test by its
  header), so a CAN log is never read as numbers;
- frames(): the frames of a log, bad input as InputFileError naming the file;
- replay_log(): send a log's frames on a bus at their recorded times (or --speed, --asap);
- record(): receive frames from a bus into a log file;
- mcap_to_log() / log_to_mcap(): an MCAP's /can/raw frames to a CAN log (candump for
  can-utils), and a CAN log's frames decoded into a dynval MCAP (mcap_log.McapLog).

Nothing here loads the C core at import (io.read_test sniffs .asc files with it)."""
from __future__ import annotations

import logging
import re
import struct
import time
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from dynval.errors import InputFileError

log = logging.getLogger(__name__)

#: the CAN log formats python-can reads and writes that dynval takes (.csv and .mf4 are test
#: formats here; python-can picks the reader and writer by the same suffixes)
LOG_SUFFIXES = (".asc", ".blf", ".trc", ".log")
_CANDUMP = re.compile(r"^\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]+#")
_ASC_HEAD = re.compile(r"^\s*(date\s|base\s+(hex|dec)\b|internal events logged|"
                       r"no internal events logged|begin\s?triggerblock|//\s*version)",
                       re.IGNORECASE)


def _head(p: Path, n: int = 20) -> list[str]:
    try:
        with open(p, encoding="latin-1", errors="replace") as f:
            return [line for _, line in zip(range(n), f, strict=False)]
    except OSError as exc:
        raise InputFileError(p, f"cannot read: {exc.strerror or exc}") from exc


def is_vector_asc(path: Path | str) -> bool:
    """A Vector ASC log: its header (date, base hex/dec, (no) internal events logged, Begin
    Triggerblock) in its first lines."""
    return any(_ASC_HEAD.match(line) for line in _head(Path(path)))


def is_can_log(path: Path | str) -> bool:
    """A CAN log python-can reads: .blf/.trc by suffix, .asc with a Vector header, .log with
    candump -L lines."""
    p = Path(path)
    suf = p.suffix.lower()
    if suf in (".blf", ".trc"):
        return True
    if suf == ".asc":
        return is_vector_asc(p)
    if suf == ".log":
        return any(_CANDUMP.match(line) for line in _head(p) if line.strip())
    return False


def frames(path: Path | str) -> Iterator[Any]:
    """The can.Message frames of a CAN log in file order (python-can's LogReader); a file it
    cannot parse is an InputFileError naming the file."""
    import can

    p = Path(path)
    if not p.is_file():
        raise InputFileError(p, "no such file")
    if p.suffix.lower() not in LOG_SUFFIXES:
        raise InputFileError(p, f"not a CAN log ({', '.join(LOG_SUFFIXES)})")
    n = 0
    try:
        with can.LogReader(p) as reader:
            for m in reader:
                n += 1
                yield m
    except (ValueError, KeyError, IndexError, OSError, EOFError, struct.error, zlib.error,
            can.CanError) as exc:
        raise InputFileError(p, f"unreadable CAN log after frame {n}: "
                             f"{type(exc).__name__}: {exc}") from None


def open_writer(path: Path | str) -> Any:
    """python-can's writer for the suffix (.asc, .blf, .trc, .log), or InputFileError."""
    import can

    p = Path(path)
    if p.suffix.lower() not in LOG_SUFFIXES:
        raise InputFileError(p, f"a CAN log is written as {', '.join(LOG_SUFFIXES)}")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        return can.Logger(p)
    except OSError as exc:
        raise InputFileError(p, f"cannot write: {exc.strerror or exc}") from exc


def replay_log(bus_obj: Any, path: Path | str, *, speed: float = 1.0, asap: bool = False,
               on_progress: Callable[[int], None] | None = None) -> Any:
    """Send a CAN log's data frames on a bus, each at its recorded time relative to the first
    (absolute deadlines, / speed), or as fast as the bus takes them (asap); error and remote
    frames are skipped. Returns a bus.ReplayResult with the send-time errors."""
    import can

    from dynval.bus import ReplayResult, TimingStats
    from dynval.errors import ConfigError
    from dynval.pacing import wait_until

    if not asap and not speed > 0:
        raise ConfigError(f"--speed must be > 0, got {speed}")
    stats = TimingStats()
    sent = errors = skipped = 0
    t_first: float | None = None
    t0 = time.perf_counter_ns() + 2_000_000
    for m in frames(path):
        if m.is_error_frame or m.is_remote_frame:
            skipped += 1
            continue
        if t_first is None:
            t_first = m.timestamp
        off = round((m.timestamp - t_first) * 1e9)
        due = t0 + int(off / speed)
        if not asap:
            wait_until(due)
        try:
            bus_obj.send(can.Message(arbitration_id=m.arbitration_id, data=m.data,
                                     is_extended_id=m.is_extended_id, is_fd=m.is_fd,
                                     bitrate_switch=m.bitrate_switch))
        except can.CanError as exc:
            errors += 1
            log.warning("send of 0x%03X failed: %s", m.arbitration_id, exc)
            continue
        sent += 1
        if not asap:
            stats.add_batch(off / speed / 1e9, [time.perf_counter_ns() - due])
        if on_progress is not None and sent % 512 == 0:
            on_progress(512)
    if skipped:
        log.info("%s: %d error/remote frames not sent", path, skipped)
    wall = (time.perf_counter_ns() - t0) / 1e9
    rep = stats.report() if not asap else {"frames": float(sent)}
    return ReplayResult(sent, sent, wall, rep, errors)


def record(bus_obj: Any, path: Path | str, *, stop: Callable[[], bool] | None = None,
           idle_timeout_s: float | None = None) -> int:
    """Receive frames from a bus into a CAN log (python-can's writer for the suffix) until
    stop() is true, a KeyboardInterrupt, or idle_timeout_s without a frame; the file is
    finished in any case. Returns the frames written."""
    from can.util import channel2int

    n = 0
    w = open_writer(path)
    try:
        idle_since = time.monotonic()
        while stop is None or not stop():
            m = bus_obj.recv(timeout=0.05)
            if m is None:
                if idle_timeout_s is not None and time.monotonic() - idle_since > idle_timeout_s:
                    break
                continue
            idle_since = time.monotonic()
            if isinstance(m.channel, str) and (channel2int(m.channel) or 0) > 0xFFFE:
                m.channel = None  # BLF numbers channels by a name's trailing digits (16 bits)
            w.on_message_received(m)
            n += 1
    finally:
        w.stop()
    return n


def mcap_to_log(mcap: Path | str, out: Path | str, *, channel: str = "can0") -> int:
    """Write the /can/raw frames of a dynval MCAP as a CAN log (candump -L for .log), each at
    its log time (the test's clock in a replay run). Returns the frames written."""
    import can

    from dynval.io.mcapfile import iter_messages
    from dynval.topics import T_RAW

    src = Path(mcap)
    n = 0
    w = open_writer(out)
    try:
        for m in iter_messages(src, topics={T_RAW}):
            d = m.data
            try:
                data = bytes.fromhex(str(d["data"]))
                msg = can.Message(timestamp=m.log_time / 1e9, arbitration_id=int(d["id"]),
                                  is_extended_id=bool(d.get("extended", False)), data=data,
                                  channel=channel)
            except (KeyError, ValueError, TypeError) as exc:
                raise InputFileError(src, f"{T_RAW} message {n + 1} is not a CAN frame: "
                                     f"{exc}", None, f"sequence {m.sequence}") from None
            w.on_message_received(msg)
            n += 1
    finally:
        w.stop()
    if n == 0:
        raise InputFileError(src, f"no {T_RAW} frames to convert (logged without raw frames?)")
    return n


def log_to_mcap(path: Path | str, out: Path | str, *, meta: dict[str, Any] | None = None,
                channel_names: list[str] | None = None) -> dict[str, Any]:
    """Decode a CAN log's frames (the dynval protocol, by the C codec) into a dynval MCAP as
    `dynval log` writes it; the frames' own timestamps are the receive times. Returns the
    log's summary."""
    from dynval.mcap_log import McapLog

    with McapLog(out, meta=meta, channel_names=channel_names) as mc:
        for m in frames(path):
            t_ns = round(m.timestamp * 1e9)
            if m.is_error_frame:
                mc.event(t_ns, "error_frame", can_id=m.arbitration_id)
                continue
            if m.is_remote_frame:
                continue
            mc.on_frame(t_ns, m.arbitration_id, bytes(m.data), m.is_extended_id)
        return mc.close()
