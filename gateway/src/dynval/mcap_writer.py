"""An MCAP writer that takes messages in blocks: numpy record arrays whose rows are whole MCAP
Message records (header fields + a fixed-layout payload, see mcap_schema), written with one
tobytes() per block instead of one Python call per message. The `mcap` package's Writer costs
about 10 us per message; a logger at bus rate writes a million messages per second.

Chunk and MessageIndex records are packed here (struct and numpy, no copy through mcap's
RecordBuilder); everything else (Header, Schema, Channel, ChunkIndex, Metadata, Statistics,
summary, Footer) is serialised by the `mcap` package's own record classes. The file is what mcap's
Writer makes: compressed chunks with CRCs, a MessageIndex per channel after each chunk (the
indexed readers of mcap and Foxglove need them), the summary with chunk and metadata indexes.
Schema and Channel records go straight to the file (before the chunk that first uses them),
so a file cut after any chunk still reads sequentially.

Compression and every write run in an I/O thread behind a small bounded queue (zstandard, lz4
and file writes release the GIL), in file order; its error (a full disk) is raised by the next
call."""
from __future__ import annotations

import queue
import struct
import threading
import zlib
from collections import defaultdict
from functools import cache
from typing import Any

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
#: a Message record's opcode, length and fields before its payload (packed: 31 bytes)
HEADER_FIELDS: list[tuple[str, str]] = [("_op", "u1"), ("_len", "<u8"), ("_chan", "<u2"),
                                        ("_seq", "<u4"), ("_log", "<u8"), ("_pub", "<u8")]
HEADER_BYTES = 31
_MSG_HEAD = struct.Struct("<BQHIQQ")
# a Chunk record up to its compression string; a MessageIndex record up to its pairs
_CHUNK_HEAD = struct.Struct("<BQQQQII")
_INDEX_HEAD = struct.Struct("<BQHI")


@cache
def record_dtype(payload: tuple[tuple[Any, ...], ...]) -> np.dtype:
    """The dtype of one Message record with this packed payload layout."""
    return np.dtype(HEADER_FIELDS + list(payload))


def _compressor(kind: str) -> Any:
    if kind == "zstd":
        import zstandard

        return zstandard.ZstdCompressor(level=1).compress
    if kind == "lz4":
        import importlib

        return importlib.import_module("lz4.frame").compress
    return None


class BlockWriter:
    """Write an MCAP file to a stream (anything with write() and tell()). chunk_size bounds a
    chunk's uncompressed bytes; flush() finishes the chunk in progress; finish() the file."""

    QUEUE = 4  # chunks (and records) waiting for the I/O thread

    def __init__(self, stream: Any, *, chunk_size: int, compression: str = "zstd",
                 profile: str = "", library: str = "") -> None:
        self._s = stream
        self.chunk_size = chunk_size
        self._kind = compression
        self._compress = _compressor(compression)
        self._pieces: list[bytes] = []
        self._size = 0
        self._index: list[tuple[Any, np.ndarray, np.ndarray]] = []  # (channel, log, offset)
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_idx: list[ChunkIndex] = []  # the I/O thread's, like _meta_idx and _span
        self._meta_idx: list[MetadataIndex] = []
        self._counts: dict[int, int] = defaultdict(int)  # the I/O thread's, per chunk
        self._n = 0
        self._span = [-1, 0]
        self._jobs: queue.Queue[Any] = queue.Queue(self.QUEUE)
        self._done = threading.Condition()
        self._submitted = self._finished = 0
        self._error: BaseException | None = None
        self._io = threading.Thread(target=self._io_loop, name="dv-mcap-io", daemon=True)
        self._io.start()
        self._write_raw(MAGIC)
        self._write(Header(profile, library))

    # -- the I/O thread -------------------------------------------------------------------------
    def _io_loop(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            if self._error is None:
                try:
                    job()
                except BaseException as exc:  # noqa: BLE001 - raised by the next _submit
                    self._error = exc
            with self._done:
                self._finished += 1
                self._done.notify_all()

    def _submit(self, job: Any) -> None:
        if self._error is not None:
            raise self._error
        self._jobs.put(job)
        self._submitted += 1  # after the put: an interrupt between them must not leave a
        # job counted that never reaches the I/O thread (sync() would wait for it forever)

    def sync(self, pending: int = 0) -> None:
        """Wait until at most `pending` of the jobs submitted (chunks, records) are not yet
        written (handed to the OS)."""
        with self._done:
            while self._submitted - self._finished > pending and self._io.is_alive():
                self._done.wait(0.1)
        if self._error is not None:
            raise self._error

    def _drain(self) -> None:
        """Wait for the I/O thread to finish every job; raise its error."""
        if self._io.is_alive():
            self._jobs.put(None)
            self._io.join()
        if self._error is not None:
            raise self._error

    # -- records outside chunks -----------------------------------------------------------------
    def _write_raw(self, b: bytes) -> None:
        self._submit(lambda: self._s.write(b))

    @staticmethod
    def _bytes(*records: Any) -> bytes:
        rb = RecordBuilder()
        for r in records:
            r.write(rb)
        data: bytes = rb.end()  # type: ignore[no-untyped-call]
        return data

    def _write(self, *records: Any) -> None:
        self._write_raw(self._bytes(*records))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        sc = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(sc)
        self._write(sc)
        return sc.id

    def register_channel(self, topic: str, encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        ch = Channel(id=len(self._channels) + 1, topic=topic, message_encoding=encoding,
                     schema_id=schema_id, metadata=dict(metadata or {}))
        self._channels.append(ch)
        self._write(ch)
        return ch.id

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        b = self._bytes(Metadata(name=name, metadata=data))

        def job() -> None:
            self._meta_idx.append(MetadataIndex(offset=int(self._s.tell()), length=len(b),
                                                name=name))
            self._s.write(b)

        self._submit(job)

    # -- messages ---------------------------------------------------------------------------------
    def _note(self, cid: Any, log: np.ndarray, offsets: np.ndarray) -> None:
        self._index.append((cid, log, offsets))  # views of a block: the I/O thread gathers
        self._n += log.size

    @staticmethod
    def template(dtype: np.dtype) -> np.ndarray:
        """One Message record of this layout with its constant header fields (_op, _len)."""
        t = np.zeros(1, dtype)
        t["_op"] = Opcode.MESSAGE
        t["_len"] = dtype.itemsize - 9
        return t

    def new_block(self, cid: int | np.ndarray, template: np.ndarray, n: int) -> np.ndarray:
        """n copies of a template() record (with the payload's constant bytes written) on
        channel cid (a number, or one per record); _seq, _log, _pub and the payload for the
        caller."""
        a = np.repeat(template, n)
        a["_chan"] = cid
        return a

    def add_block(self, block: np.ndarray) -> None:
        """Append a new_block() array to the chunk in progress."""
        if block.size == 0:
            return
        offsets = self._size + np.arange(block.size, dtype=np.uint64) * block.itemsize
        self._note(block["_chan"], block["_log"], offsets)
        b = block.tobytes()
        self._pieces.append(b)
        self._size += len(b)
        if self._size >= self.chunk_size:
            self.flush()

    def add(self, cid: int, log_time: int, publish_time: int, data: bytes,
            sequence: int = 0) -> None:
        """One message of any payload."""
        self._note(cid, np.array([log_time], np.uint64), np.array([self._size], np.uint64))
        b = _MSG_HEAD.pack(Opcode.MESSAGE, 22 + len(data), cid, sequence & 0xFFFFFFFF,
                           log_time, publish_time) + data
        self._pieces.append(b)
        self._size += len(b)
        if self._size >= self.chunk_size:
            self.flush()

    # -- chunks -----------------------------------------------------------------------------------
    def flush(self) -> None:
        """Finish the chunk in progress (if it holds messages): the I/O thread compresses it
        and writes the Chunk and its MessageIndex records at once."""
        if not self._pieces:
            return
        pieces, index = self._pieces, self._index
        self._submit(lambda: self._write_chunk(pieces, index))
        self._pieces = []
        self._index = []
        self._size = 0

    def _write_chunk(self, pieces: list[bytes],
                     index: list[tuple[Any, np.ndarray, np.ndarray]]) -> None:
        """The Chunk record and its MessageIndex records, packed here (struct, numpy) and
        written in one piece: no copy through mcap's RecordBuilder."""
        data = b"".join(pieces)
        packed = self._compress(data) if self._compress is not None else data
        n = [log.size for _, log, _ in index]
        chan = np.concatenate([np.broadcast_to(np.asarray(c, np.uint16), (k,))
                               for (c, _, _), k in zip(index, n, strict=True)])
        log = np.concatenate([lg for _, lg, _ in index])
        off = np.concatenate([o for _, _, o in index])
        t0, t1 = int(log.min()), int(log.max())
        self._span[0] = t0 if self._span[0] < 0 else min(self._span[0], t0)
        self._span[1] = max(self._span[1], t1)
        kind = self._kind.encode()
        head = _CHUNK_HEAD.pack(Opcode.CHUNK, _CHUNK_HEAD.size - 9 + len(kind) + 8 + len(packed),
                                t0, t1, len(data), zlib.crc32(data), len(kind))
        parts: list[Any] = [head, kind, struct.pack("<Q", len(packed)), packed]
        chunk_len = len(head) + len(kind) + 8 + len(packed)
        pos = chunk_len
        offsets: dict[int, int] = {}
        order = np.argsort(chan, kind="stable")  # per channel, in file order
        chans, starts, counts = np.unique(chan[order], return_index=True, return_counts=True)
        for cid, a, k in zip(chans.tolist(), starts.tolist(), counts.tolist(), strict=True):
            pairs = np.empty((k, 2), "<u8")
            sel = order[a:a + k]
            pairs[:, 0], pairs[:, 1] = log[sel], off[sel]
            offsets[cid] = pos
            parts += [_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 2 + 4 + pairs.nbytes, cid,
                                       pairs.nbytes), pairs]
            pos += _INDEX_HEAD.size + pairs.nbytes
            self._counts[cid] += k
        start = int(self._s.tell())
        self._chunk_idx.append(ChunkIndex(
            message_start_time=t0, message_end_time=t1, chunk_start_offset=start,
            chunk_length=chunk_len,
            message_index_offsets={c: start + o for c, o in offsets.items()},
            message_index_length=pos - chunk_len, compression=self._kind,
            compressed_size=len(packed), uncompressed_size=len(data)))
        self._s.write(b"".join(parts))

    def finish(self) -> None:
        """The last chunk, DataEnd, the summary (schemas, channels, statistics, chunk and
        metadata indexes, summary offsets) and the footer."""
        self.flush()
        self._write(DataEnd(data_section_crc=0))
        self._drain()
        start = int(self._s.tell())
        rb = RecordBuilder()
        groups = []
        stats = Statistics(
            message_count=self._n, schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=0,
            metadata_count=len(self._meta_idx), chunk_count=len(self._chunk_idx),
            message_start_time=max(self._span[0], 0), message_end_time=self._span[1],
            channel_message_counts=dict(self._counts))
        for op, recs in ((Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels),
                         (Opcode.STATISTICS, [stats]), (Opcode.CHUNK_INDEX, self._chunk_idx),
                         (Opcode.METADATA_INDEX, self._meta_idx)):
            g = rb.count
            for r in recs:
                r.write(rb)
            groups.append(SummaryOffset(group_opcode=op, group_start=start + g,
                                        group_length=rb.count - g))
        offsets_start = start + rb.count
        for so in groups:
            so.write(rb)
        summary: bytes = rb.end()  # type: ignore[no-untyped-call]
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, start, offsets_start), crc)
        self._s.write(summary)
        self._s.write(self._bytes(Footer(summary_start=start, summary_offset_start=offsets_start,
                                         summary_crc=crc)))
        self._s.write(MAGIC)
