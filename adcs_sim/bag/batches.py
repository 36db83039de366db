"""Streaming the raw CDR bytes of selected topics of a bag, in large batches: :class:`ColumnReader`.

One pass over the file: MCAP files are parsed here record by record (each chunk decompressed
once, its messages located from its message index); other storage (sqlite3) is read with
rosbags' ``AnyReader``. Each :class:`TopicBatch` holds the CDR bytes of many messages of one
topic in one numpy buffer, for :mod:`adcs_sim.bag.columns` to decode into numpy columns.
"""
from __future__ import annotations

import os
import struct
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard

from adcs_sim.bag.storage import MCAP_MAGIC, any_reader, bag_files

_U16 = struct.Struct('<H')
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_CHUNK_HEAD = struct.Struct('<QQQI')
MESSAGE_DATA_OFFSET = 31   # opcode, record length, channel id, sequence, log time, publish time
BATCH_BYTES = 16 << 20


@dataclass
class TopicBatch:
    """Messages of one topic: ``buf[starts[i] : starts[i] + sizes[i]]`` is message i's CDR."""

    topic: str
    type_name: str
    buf: np.ndarray                    # uint8
    starts: np.ndarray                 # int64
    sizes: np.ndarray                  # int64

    def __len__(self) -> int:
        return int(self.starts.size)

    def message(self, i: int) -> bytes:
        return self.buf[self.starts[i]:self.starts[i] + self.sizes[i]].tobytes()


def _string(data, pos: int) -> tuple[str, int]:
    n = _U32.unpack_from(data, pos)[0]
    return bytes(data[pos + 4:pos + 4 + n]).decode('utf-8', 'replace'), pos + 4 + n


def _string_map(data, pos: int) -> dict[str, str]:
    end = pos + 4 + _U32.unpack_from(data, pos)[0]
    pos += 4
    out = {}
    while pos < end:
        key, pos = _string(data, pos)
        out[key], pos = _string(data, pos)
    return out


class ColumnReader:
    """One streaming pass over a bag: the raw CDR bytes of the selected topics, in batches.

    ``select(topic, type_name)`` picks the topics to deliver (others are only counted). Iterating
    yields :class:`TopicBatch` objects of about ``batch_bytes`` of storage data each, in file
    order per topic. After the iteration:

    * ``topics`` — every topic of the bag with its type name;
    * ``topic_counts`` — messages read per topic (all topics, selected or not);
    * ``message_count`` — their sum;
    * ``truncated`` — an MCAP file did not end with its summary and footer (the writer did not
      close it): what was read is everything up to its last complete chunk;
    * ``metadata`` — MCAP metadata records ``{name: {key: value}}`` (e.g. ``scenario``).

    MCAP files are parsed here: each chunk is decompressed once and its messages located from the
    chunk's message index (checked to tile the chunk exactly; otherwise, or without an index, the
    chunk's records are walked). Other storage (sqlite3) is read with rosbags' ``AnyReader``.
    """

    def __init__(self, bag: str | os.PathLike, select: Callable[[str, str], bool],
                 batch_bytes: int = BATCH_BYTES) -> None:
        self.bag = bag
        self.select = select
        self.batch_bytes = batch_bytes
        self.kind, self.files = bag_files(bag)
        self.topics: dict[str, str] = {}
        self.topic_counts: dict[str, int] = defaultdict(int)
        self.truncated = False
        self.metadata: dict[str, dict[str, str]] = {}

    @property
    def message_count(self) -> int:
        return sum(self.topic_counts.values())

    def __iter__(self) -> Iterator[TopicBatch]:
        if self.kind == 'rosbag2':
            yield from self._rosbags()
            return
        for path in self.files:
            yield from _McapScan(self, path).batches()

    def _rosbags(self) -> Iterator[TopicBatch]:
        with any_reader(self.bag, self.files[0]) as reader:
            selected = []
            for conn in reader.connections:
                self.topics.setdefault(conn.topic, conn.msgtype)
                self.topic_counts[conn.topic] += conn.msgcount
                if self.select(conn.topic, conn.msgtype):
                    selected.append(conn)
            if not selected:
                return
            pending: dict[str, list[bytes]] = defaultdict(list)
            size = 0
            for conn, _, data in reader.messages(connections=selected):
                pending[conn.topic].append(data)
                size += len(data)
                if size >= self.batch_bytes:
                    yield from self._flush_lists(pending)
                    pending, size = defaultdict(list), 0
            yield from self._flush_lists(pending)

    def _flush_lists(self, pending: dict[str, list[bytes]]) -> Iterator[TopicBatch]:
        for topic, datas in pending.items():
            sizes = np.fromiter((len(d) for d in datas), dtype=np.int64, count=len(datas))
            starts = np.zeros_like(sizes)
            np.cumsum(sizes[:-1], out=starts[1:])
            yield TopicBatch(topic, self.topics[topic], np.frombuffer(b''.join(datas), np.uint8),
                             starts, sizes)


class _McapScan:
    """The record-level parse of one MCAP file for :class:`ColumnReader`."""

    def __init__(self, owner: ColumnReader, path: Path) -> None:
        self.owner = owner
        self.path = path
        self.channels: dict[int, tuple[str, str]] = {}    # id -> (topic, type name)
        self.schemas: dict[int, str] = {}
        self.wanted: dict[int, bool] = {}
        self.pending: list[tuple[np.ndarray, dict[int, np.ndarray]]] = []
        self.pending_bytes = 0
        self.loose = bytearray()                          # top-level (unchunked) message records
        self._zstd = None

    # records ---------------------------------------------------------------------------------
    def _schema(self, data, pos: int) -> None:
        sid = _U16.unpack_from(data, pos)[0]
        self.schemas[sid], _ = _string(data, pos + 2)

    def _channel(self, data, pos: int) -> None:
        cid, sid = struct.unpack_from('<HH', data, pos)
        topic, _ = _string(data, pos + 4)
        type_name = self.schemas.get(sid, '')
        self.channels[cid] = (topic, type_name)
        self.owner.topics.setdefault(topic, type_name)
        self.owner.topic_counts.setdefault(topic, 0)
        self.wanted[cid] = bool(self.owner.select(topic, type_name))

    def _decompress(self, compression: str, data, size: int) -> bytes:
        if compression == '':
            return bytes(data)
        if compression == 'zstd':
            if self._zstd is None:
                self._zstd = zstandard.ZstdDecompressor()
            return self._zstd.decompress(data, max_output_size=size)
        if compression == 'lz4':
            return lz4.frame.decompress(data)
        raise ValueError(f'{self.path}: unsupported MCAP chunk compression {compression!r}')

    def _walk(self, buf) -> dict[int, list[int]]:
        """Message record offsets per channel of a record sequence; registers schemas/channels."""
        offsets: dict[int, list[int]] = defaultdict(list)
        pos, end = 0, len(buf)
        while pos + 9 <= end:
            op = buf[pos]
            length = _U64.unpack_from(buf, pos + 1)[0]
            if pos + 9 + length > end:
                break
            if op == 0x05:
                offsets[_U16.unpack_from(buf, pos + 9)[0]].append(pos)
            elif op == 0x03:
                self._schema(buf, pos + 9)
            elif op == 0x04:
                self._channel(buf, pos + 9)
            pos += 9 + length
        return offsets

    def _indexed(self, buf: bytes, index: dict[int, np.ndarray]) -> dict[int, np.ndarray] | None:
        """Offsets per channel from a chunk's message index, if they tile the chunk exactly."""
        if not index:
            return None
        offs = np.sort(np.concatenate(list(index.values())))
        arr = np.frombuffer(buf, np.uint8)
        if offs.size == 0 or offs[0] != 0 or offs[-1] + 9 > arr.size:
            return None
        lengths = arr[(offs + 1)[:, None] + np.arange(8)].view('<u8')[:, 0]
        ends = offs + 9 + lengths
        if ends[-1] != arr.size or np.any(ends[:-1] != offs[1:]) or np.any(arr[offs] != 0x05):
            return None
        if any(cid not in self.channels for cid in index):
            return None
        return index

    def _add_chunk(self, buf: bytes, offsets: dict) -> None:
        counts = self.owner.topic_counts
        keep = {}
        for cid, offs in offsets.items():
            topic = self.channels.get(cid, (f'<channel {cid}>', ''))[0]
            counts[topic] += len(offs)
            if self.wanted.get(cid) and len(offs):
                keep[cid] = np.sort(np.asarray(offs, dtype=np.int64))
        if keep:
            self.pending.append((np.frombuffer(buf, np.uint8), keep))
            self.pending_bytes += len(buf)

    def _flush(self) -> Iterator[TopicBatch]:
        if not self.pending:
            return
        bufs = [b for b, _ in self.pending]
        base = np.zeros(len(bufs), dtype=np.int64)
        np.cumsum([b.size for b in bufs[:-1]], out=base[1:])
        buf = np.concatenate(bufs) if len(bufs) > 1 else bufs[0]
        per_topic: dict[str, list[np.ndarray]] = defaultdict(list)
        for (_, offsets), b0 in zip(self.pending, base):
            for cid, offs in offsets.items():
                per_topic[self.channels[cid][0]].append(offs + b0)
        self.pending, self.pending_bytes = [], 0
        for topic, parts in per_topic.items():
            rec = np.concatenate(parts)
            lengths = buf[(rec + 1)[:, None] + np.arange(8)].view('<u8')[:, 0].astype(np.int64)
            yield TopicBatch(topic, self.owner.topics[topic], buf, rec + MESSAGE_DATA_OFFSET, lengths - 22)

    def _take_loose(self) -> None:
        if self.loose:
            buf = bytes(self.loose)
            self.loose = bytearray()
            self._add_chunk(buf, self._walk(buf))

    # the pass --------------------------------------------------------------------------------
    def batches(self) -> Iterator[TopicBatch]:
        owner = self.owner
        complete = False
        with open(self.path, 'rb') as f:
            if f.read(8) != MCAP_MAGIC:
                raise ValueError(f'{self.path}: not a bag: no MCAP magic at its start (empty or not MCAP)')
            chunk = None                       # (decompressed bytes, message index) awaiting its index
            while True:
                head = f.read(9)
                if len(head) < 9:
                    break
                op, length = head[0], _U64.unpack_from(head, 1)[0]
                body = f.read(length) if length < (1 << 40) else b''
                if len(body) < length:
                    break                      # truncated record: the writer was killed
                if op == 0x07 and chunk is not None:
                    cid = _U16.unpack_from(body, 0)[0]
                    n = _U32.unpack_from(body, 2)[0] // 16
                    chunk[1][cid] = np.frombuffer(body, '<u8', 2 * n, 6)[1::2].astype(np.int64)
                    continue
                if chunk is not None:
                    self._finish_chunk(*chunk)
                    chunk = None
                if op != 0x05:
                    self._take_loose()
                if self.pending_bytes >= owner.batch_bytes:
                    yield from self._flush()
                if op == 0x06:
                    _, _, usize, _ = _CHUNK_HEAD.unpack_from(body, 0)
                    compression, pos = _string(body, 28)
                    rlen = _U64.unpack_from(body, pos)[0]
                    data = memoryview(body)[pos + 8:pos + 8 + rlen]
                    chunk = (self._decompress(compression, data, usize), {})
                elif op == 0x05:
                    self.loose += head + body
                    if len(self.loose) >= owner.batch_bytes:
                        self._take_loose()
                elif op == 0x03:
                    self._schema(body, 0)
                elif op == 0x04:
                    self._channel(body, 0)
                elif op == 0x0C:
                    name, pos = _string(body, 0)
                    owner.metadata[name] = _string_map(body, pos)
                elif op == 0x0F:                   # data end: the summary repeats what we have
                    f.seek(0, os.SEEK_END)
                    if f.tell() >= 16:
                        f.seek(-8, os.SEEK_END)
                        complete = f.read(8) == MCAP_MAGIC
                    break
            if chunk is not None:
                self._finish_chunk(*chunk)
            self._take_loose()
        owner.truncated = owner.truncated or not complete
        yield from self._flush()

    def _finish_chunk(self, buf: bytes, index: dict[int, np.ndarray]) -> None:
        offsets = self._indexed(buf, index)
        self._add_chunk(buf, offsets if offsets is not None else self._walk(buf))


