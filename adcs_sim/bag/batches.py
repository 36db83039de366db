"""Streaming the raw CDR bytes of selected topics of a bag, in large batches: :class:`ColumnReader`.

One pass over the file: MCAP files are walked through the checked
:class:`~adcs_sim.bag.records.McapRecords` (each chunk decompressed and CRC-checked once, its
messages located from its message index, which is verified against the chunk's own records
before it is trusted); other storage (sqlite3) is read with
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

import numpy as np

from adcs_sim.bag.records import (
    CHANNEL,
    CHUNK,
    MESSAGE,
    MESSAGE_HEAD,
    MESSAGE_INDEX,
    METADATA,
    SCHEMA,
    BadRecord,
    BagDamaged,
    McapRecords,
    inner_records,
    parse_channel,
    parse_metadata,
    parse_schema,
)
from adcs_sim.bag.storage import any_reader, bag_files

_U16 = struct.Struct('<H')
_U32 = struct.Struct('<I')
_RECORD_HEAD = struct.Struct('<BQ')
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
    * ``problem`` — one line naming the first damage (byte offset, reason), truncation or damaged
      summary, else None; ``damaged`` — a fault was found (not a plain truncation): what was read
      is every record before it. A fault that a section CRC reveals without locating it raises
      :class:`~adcs_sim.bag.records.BagDamaged` at the end of the iteration;
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
        self.problem: str | None = None    # the first file's damage or truncation, one line
        self.damaged = False               # a located damage: what was read is the part before it
        self.metadata: dict[str, dict[str, str]] = {}

    @property
    def message_count(self) -> int:
        return sum(self.topic_counts.values())

    def __iter__(self) -> Iterator[TopicBatch]:
        if self.kind == 'rosbag2':
            yield from self._rosbags()
            return
        for path in self.files:
            scan = _McapScan(self, path)
            yield from scan.batches()
            records = scan.records
            self.truncated = self.truncated or not records.complete
            problem = records.problem()
            if problem is not None and self.problem is None:
                self.problem = f'{path.name}: {problem}' if len(self.files) > 1 else problem
            if records.damage is not None and not records.damage.located:
                raise BagDamaged(f'{path}: {records.damage}; refused: which messages are intact is unknown')
            if records.damage is not None:
                self.damaged = True
                break                          # what follows the damage is not read (not even other files)

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
    """The record-level parse of one MCAP file for :class:`ColumnReader` (checked by :class:`McapRecords`)."""

    def __init__(self, owner: ColumnReader, path: Path) -> None:
        self.owner = owner
        self.records = McapRecords(path)
        self.channels: dict[int, tuple[str, str]] = {}    # id -> (topic, type name)
        self.schemas: dict[int, str] = {}
        self.wanted: dict[int, bool] = {}
        self.pending: list[tuple[np.ndarray, dict[int, np.ndarray]]] = []
        self.pending_bytes = 0
        self.loose = bytearray()                          # top-level (unchunked) message records
        self.counted = 0

    # records ---------------------------------------------------------------------------------
    def _schema(self, body) -> None:
        sid, name, _, _ = parse_schema(body)
        self.schemas[sid] = name

    def _channel(self, body) -> None:
        cid, sid, topic, _, _ = parse_channel(body)
        type_name = self.schemas.get(sid, '')
        self.channels[cid] = (topic, type_name)
        self.owner.topics.setdefault(topic, type_name)
        self.owner.topic_counts.setdefault(topic, 0)
        self.wanted[cid] = bool(self.owner.select(topic, type_name))

    def _walk(self, buf) -> dict[int, list[int]]:
        """Message record offsets per channel of a chunk's records; registers schemas/channels.
        Raises BadRecord if the records do not tile the chunk."""
        offsets: dict[int, list[int]] = defaultdict(list)
        view = memoryview(buf)
        for pos, op, length in inner_records(buf):
            if op == MESSAGE:
                offsets[_U16.unpack_from(buf, pos + 9)[0]].append(pos)
            elif op == SCHEMA:
                self._schema(view[pos + 9:pos + 9 + length])
            else:
                self._channel(view[pos + 9:pos + 9 + length])
        return offsets

    def _indexed(self, buf: bytes, index: dict[int, np.ndarray]) -> dict[int, np.ndarray] | None:
        """Offsets per channel from a chunk's message index, if they tile the chunk exactly with
        message records of the channel each index entry names."""
        if not index or any(cid not in self.channels for cid in index):
            return None
        offs = np.concatenate(list(index.values()))
        cids = np.concatenate([np.full(v.size, cid) for cid, v in index.items()])
        order = np.argsort(offs, kind='stable')
        offs, cids = offs[order], cids[order]
        arr = np.frombuffer(buf, np.uint8)
        if offs.size == 0 or offs[0] != 0 or offs[-1] + 9 + MESSAGE_HEAD > arr.size:
            return None
        lengths = arr[(offs + 1)[:, None] + np.arange(8)].view('<u8')[:, 0]
        if np.any(lengths < MESSAGE_HEAD) or np.any(lengths > arr.size):
            return None
        ends = offs + 9 + lengths.astype(np.int64)
        if ends[-1] != arr.size or np.any(ends[:-1] != offs[1:]) or np.any(arr[offs] != MESSAGE):
            return None
        if np.any(arr[offs + 9] + 256 * arr[offs + 10].astype(np.int64) != cids):
            return None
        return index

    def _add_chunk(self, buf: bytes, offsets: dict) -> None:
        counts = self.owner.topic_counts
        keep = {}
        for cid, offs in offsets.items():
            topic = self.channels.get(cid, (f'<channel {cid}>', ''))[0]
            counts[topic] += len(offs)
            self.counted += len(offs)
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
            yield TopicBatch(topic, self.owner.topics[topic], buf, rec + MESSAGE_DATA_OFFSET, lengths - MESSAGE_HEAD)

    def _take_loose(self) -> None:
        if self.loose:
            buf = bytes(self.loose)
            self.loose = bytearray()
            self._add_chunk(buf, self._walk(buf))

    # the pass --------------------------------------------------------------------------------
    def batches(self) -> Iterator[TopicBatch]:
        """The batches of the intact part of the file; the file's state is left in ``records``."""
        chunk = None                       # (offset, decompressed bytes, message index) awaiting its index
        for offset, op, body in self.records:
            if op == MESSAGE_INDEX:
                if chunk is not None:
                    _message_index(body, chunk[2])
                continue
            if chunk is not None and not self._finish_chunk(*chunk):
                chunk = None
                break
            chunk = None
            if op != MESSAGE:
                self._take_loose()
            if self.pending_bytes >= self.owner.batch_bytes:
                yield from self._flush()
            try:
                chunk = self._record(offset, op, body)
            except (BadRecord, struct.error) as exc:
                self.records.fail(offset, f'record 0x{op:02x}: {exc}')
                break
        if chunk is not None:
            self._finish_chunk(*chunk)
        self._take_loose()
        self.records.check_count(self.counted)
        yield from self._flush()

    def _record(self, offset: int, op: int, body: bytes):
        """Handle one top-level record; a chunk is returned to wait for its message index."""
        if op == CHUNK:
            return offset, body, {}
        if op == MESSAGE:
            self.loose += _RECORD_HEAD.pack(MESSAGE, len(body)) + body
            if len(self.loose) >= self.owner.batch_bytes:
                self._take_loose()
        elif op == SCHEMA:
            self._schema(body)
        elif op == CHANNEL:
            self._channel(body)
        elif op == METADATA:
            name, values = parse_metadata(body)
            self.owner.metadata[name] = values
        return None

    def _finish_chunk(self, offset: int, buf: bytes, index: dict[int, np.ndarray]) -> bool:
        offsets = self._indexed(buf, index)
        if offsets is None:
            try:
                offsets = self._walk(buf)
            except (BadRecord, struct.error) as exc:
                self.records.fail(offset, f'chunk: {exc}')
                return False
        self._add_chunk(buf, offsets)
        return True


def _message_index(body: bytes, index: dict[int, np.ndarray]) -> None:
    """Add a MessageIndex record's offsets to ``index`` (a malformed one is left out: the chunk is
    then walked record by record, so an index never decides which bytes are a message)."""
    if len(body) < 6:
        return
    cid = _U16.unpack_from(body, 0)[0]
    nbytes = _U32.unpack_from(body, 2)[0]
    if nbytes % 16 or 6 + nbytes != len(body):
        index[cid] = np.array([-1], dtype=np.int64)      # poisons the index: walk the chunk
        return
    index[cid] = np.frombuffer(body, '<u8', nbytes // 8, 6)[1::2].astype(np.int64)
