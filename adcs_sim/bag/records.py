"""Reading one MCAP file record by record, checked: what is intact, where the damage starts.

Every reader of this package (:mod:`adcs_sim.bag.reader`, :mod:`adcs_sim.bag.batches`,
:mod:`adcs_sim.bag.repair`) walks a file through :class:`McapRecords`, which checks everything
the MCAP format lets a reader check (https://mcap.dev/spec), and stops at the first record that
fails:

* framing: the magic at the start, a Header first, known opcodes (private ones, 0x80-0xFF, are
  skipped as the spec says), no summary-only record in the data section, no record longer than
  the rest of the file (a corrupt length never allocates more than the file holds);
* chunks: bounded uncompressed size (:data:`MAX_CHUNK_BYTES`), the compressed frame's own size
  equal to the chunk's, decompression without error, the chunk CRC (when the writer set one);
* the data-section CRC of the DataEnd record (when set), the summary CRC of the footer (when
  set), and that the summary's chunk index lists exactly the chunks the data section holds.

A file that simply ends (a writer killed mid-chunk, as a SIGKILLed recorder leaves it) is
``truncated``: everything before its last whole record is read. A file that has a fault is
``damaged``: :class:`Damage` says at which byte and why; every record before that byte passed
the checks above. A damage that a CRC over a whole section reveals cannot be located (the
section's CRC does not say where): the readers then refuse the file instead of guessing.

Which policy follows is the reader's: the message readers deliver the intact prefix and then
raise :class:`BagDamaged`; ``adcs-analyze`` analyses the intact prefix with a warning;
``adcs-bag-repair`` keeps it and says what it dropped.
"""
from __future__ import annotations

import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import zstandard

from adcs_sim.bag.storage import MCAP_MAGIC

HEADER, FOOTER, SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07
CHUNK_INDEX, ATTACHMENT, STATISTICS, METADATA, DATA_END = 0x08, 0x09, 0x0B, 0x0C, 0x0F
SUMMARY_ONLY = frozenset({FOOTER, CHUNK_INDEX, 0x0A, STATISTICS, 0x0D, 0x0E})
IN_CHUNK = frozenset({SCHEMA, CHANNEL, MESSAGE})
MAX_CHUNK_BYTES = 1 << 28      # 256 MiB: a chunk claiming more is damaged (writers use 64 KiB - 4 MiB)
MESSAGE_HEAD = 22              # channel id, sequence, log time, publish time
_U16, _U32, _U64 = struct.Struct('<H'), struct.Struct('<I'), struct.Struct('<Q')
_CHUNK_HEAD = struct.Struct('<QQQI')
_FOOTER = struct.Struct('<BQQQI')   # opcode, length, summary start, summary offset start, summary CRC
_FOOTER_BYTES = _FOOTER.size


class BadRecord(ValueError):
    """A record that does not parse or fails a check (the message is the reason)."""


class BagDamaged(ValueError):
    """A bag file with a fault (the message is one line: the file, the byte offset, what was read)."""


@dataclass(frozen=True)
class Damage:
    offset: int            # first byte not trusted: every record before it passed the checks
    reason: str
    located: bool = True   # False: a section CRC failed, the fault is somewhere before ``offset``

    def __str__(self) -> str:
        if self.located:
            return f'damaged at byte {self.offset}: {self.reason}'
        return f'damaged somewhere before byte {self.offset}: {self.reason}'


def string(data, pos: int) -> tuple[str, int]:
    """A length-prefixed UTF-8 string at ``pos`` and the position after it (BadRecord if it overruns)."""
    n = _U32.unpack_from(data, pos)[0]
    if pos + 4 + n > len(data):
        raise BadRecord('a string runs past the end of its record')
    return bytes(data[pos + 4:pos + 4 + n]).decode('utf-8', 'replace'), pos + 4 + n


def string_map(data, pos: int) -> tuple[dict[str, str], int]:
    end = pos + 4 + _U32.unpack_from(data, pos)[0]
    if end > len(data):
        raise BadRecord('a map runs past the end of its record')
    pos += 4
    out = {}
    while pos < end:
        key, pos = string(data, pos)
        out[key], pos = string(data, pos)
    if pos != end:
        raise BadRecord('a map overruns its length')
    return out, end


def parse_schema(body) -> tuple[int, str, str, bytes]:
    """(id, name, encoding, data) of a Schema record."""
    try:
        sid = _U16.unpack_from(body, 0)[0]
        name, pos = string(body, 2)
        encoding, pos = string(body, pos)
        n = _U32.unpack_from(body, pos)[0]
    except struct.error:
        raise BadRecord('schema record too short') from None
    if pos + 4 + n != len(body):
        raise BadRecord('schema data does not end with its record')
    return sid, name, encoding, bytes(body[pos + 4:pos + 4 + n])


def parse_channel(body) -> tuple[int, int, str, str, dict[str, str]]:
    """(id, schema id, topic, message encoding, metadata) of a Channel record."""
    try:
        cid, sid = struct.unpack_from('<HH', body, 0)
        topic, pos = string(body, 4)
        encoding, pos = string(body, pos)
        metadata, pos = string_map(body, pos)
    except struct.error:
        raise BadRecord('channel record too short') from None
    if pos != len(body):
        raise BadRecord('channel fields do not end with its record')
    return cid, sid, topic, encoding, metadata


def parse_metadata(body) -> tuple[str, dict[str, str]]:
    try:
        name, pos = string(body, 0)
        values, pos = string_map(body, pos)
    except struct.error:
        raise BadRecord('metadata record too short') from None
    if pos != len(body):
        raise BadRecord('metadata fields do not end with its record')
    return name, values


def parse_message(body) -> tuple[int, int, int, bytes]:
    """(channel id, sequence, log time, data) of a Message record body (at least 22 bytes)."""
    cid, seq, log_time, _ = struct.unpack_from('<HIQQ', body, 0)
    return cid, seq, log_time, bytes(body[MESSAGE_HEAD:])


def inner_records(buf) -> Iterator[tuple[int, int, int]]:
    """(offset, opcode, length) of the records of a chunk; BadRecord unless they tile it exactly."""
    pos, end = 0, len(buf)
    while pos < end:
        if pos + 9 > end:
            raise BadRecord(f'a record header is cut at byte {pos} of the chunk')
        op, length = buf[pos], _U64.unpack_from(buf, pos + 1)[0]
        if pos + 9 + length > end:
            raise BadRecord(f'the record at byte {pos} of the chunk runs past its end')
        if op not in IN_CHUNK:
            raise BadRecord(f'record opcode 0x{op:02x} inside a chunk')
        if op == MESSAGE and length < MESSAGE_HEAD:
            raise BadRecord(f'a message record of {length} bytes inside a chunk')
        yield pos, op, length
        pos += 9 + length


@dataclass
class McapRecords:
    """The checked records of one MCAP file's data section, in file order.

    Iterating yields ``(offset, opcode, body)``; a chunk is yielded with its decompressed,
    checked records as ``body``. A reader that finds a fault in a record it was given calls
    :meth:`fail` (the iteration then stops). Afterwards: ``end`` (the intact part is
    ``[0, end)``), ``truncated``, ``damage``, ``summary_problem`` (the data section is intact,
    the summary after it is not), ``complete`` and ``message_count`` (from the summary's
    Statistics, if any, for the readers to compare with what they counted).
    """

    path: Path
    size: int = 0
    end: int = 8
    truncated: bool = False
    damage: Damage | None = None
    summary_problem: str | None = None
    data_end: bool = False
    closed: bool = False                  # ends with a footer and the magic
    message_count: int | None = None
    chunks: list[tuple[int, int]] = field(default_factory=list)
    _zstd: zstandard.ZstdDecompressor = field(default_factory=zstandard.ZstdDecompressor)

    @property
    def complete(self) -> bool:
        return self.data_end and self.closed and self.damage is None and self.summary_problem is None

    def fail(self, offset: int, reason: str, located: bool = True) -> None:
        """Mark the first fault (later ones are not trusted to be independent of it)."""
        if self.damage is None:
            self.damage = Damage(offset, reason, located)
            self.end = min(self.end, offset)

    def problem(self) -> str | None:
        """One line for a reader's warning: damage, truncation or a damaged summary (else None)."""
        if self.damage is not None:
            return str(self.damage)
        if self.truncated:
            return f'truncated at byte {self.end} of {self.size} (no data end: the writer did not close it)'
        if self.summary_problem is not None:
            return f'summary damaged ({self.summary_problem}); its data section is intact'
        return None

    def __iter__(self) -> Iterator[tuple[int, int, bytes]]:
        with open(self.path, 'rb') as f:
            self.size = os.fstat(f.fileno()).st_size
            if f.read(8) != MCAP_MAGIC:
                raise ValueError(f'{self.path}: not a bag: no MCAP magic at its start (empty or not MCAP)')
            footer = self._footer(f)
            f.seek(8)
            yield from self._data_section(f)
            if self.data_end and self.damage is None:
                self._summary(f, footer)

    def _footer(self, f) -> tuple | None:
        if self.size < 8 + _FOOTER_BYTES + 8:
            return None
        f.seek(self.size - 8 - _FOOTER_BYTES)
        tail = f.read(_FOOTER_BYTES + 8)
        self.closed = tail[-8:] == MCAP_MAGIC and tail[0] == FOOTER and _U64.unpack_from(tail, 1)[0] == 20
        return _FOOTER.unpack_from(tail, 0) if self.closed else None

    def _data_section(self, f) -> Iterator[tuple[int, int, bytes]]:
        crc = zlib.crc32(MCAP_MAGIC)
        pos = 8
        while self.damage is None:
            head = f.read(9)
            if len(head) < 9:
                self.truncated = True
                return
            op, length = head[0], _U64.unpack_from(head, 1)[0]
            if length > self.size - pos - 9:
                if self.closed:
                    self.fail(pos, f'record 0x{op:02x} claims {length} bytes, past the end of the file')
                else:
                    self.truncated = True
                return
            body = f.read(length)
            reason = _framing_problem(pos, op, length) or _body_problem(op, body)
            if reason:
                self.fail(pos, reason)
                return
            if op == DATA_END:
                self._check_data_end(pos, body, crc)
                return
            crc = zlib.crc32(body, zlib.crc32(head, crc))
            if op == CHUNK:
                try:
                    body = self._chunk(body)
                except BadRecord as exc:
                    self.fail(pos, str(exc))
                    return
                self.chunks.append((pos, 9 + length))
            if op < 0x80 and op != ATTACHMENT:
                yield pos, op, body
                if self.damage is not None:
                    return
            pos += 9 + length
            self.end = pos

    def _check_data_end(self, pos: int, body: bytes, crc: int) -> None:
        stored = _U32.unpack_from(body, 0)[0]
        if stored and stored != crc:
            self.fail(pos, f'data section CRC mismatch (stored 0x{stored:08x}, computed 0x{crc:08x})',
                      located=False)
            return
        self.data_end = True
        self.end = pos + 9 + len(body)

    def _chunk(self, body: bytes) -> bytes:
        try:
            _, _, usize, ucrc = _CHUNK_HEAD.unpack_from(body, 0)
            compression, pos = string(body, _CHUNK_HEAD.size)
            rlen = _U64.unpack_from(body, pos)[0]
        except struct.error:
            raise BadRecord('chunk record too short') from None
        if pos + 8 + rlen != len(body):
            raise BadRecord(f'chunk records of {rlen} bytes in a chunk record of {len(body)}')
        if usize > MAX_CHUNK_BYTES:
            raise BadRecord(f'chunk claims {usize} bytes uncompressed (more than {MAX_CHUNK_BYTES})')
        data = decompress(compression, memoryview(body)[pos + 8:pos + 8 + rlen], usize, self._zstd)
        if len(data) != usize:
            raise BadRecord(f'chunk decompresses to {len(data)} bytes, its header says {usize}')
        if ucrc and zlib.crc32(data) != ucrc:
            raise BadRecord(f'chunk CRC mismatch (stored 0x{ucrc:08x}, computed 0x{zlib.crc32(data):08x})')
        return data

    def _summary(self, f, footer: tuple | None) -> None:
        if footer is None:
            self.summary_problem = 'no footer after the data end: the writer stopped while closing'
            return
        _, _, start, _, crc = footer
        footer_at = self.size - 8 - _FOOTER_BYTES
        if start == 0:
            return
        if start != self.end or start > footer_at:
            self.summary_problem = f'the footer puts the summary at byte {start}'
            return
        f.seek(start)
        summary = f.read(footer_at - start)
        if crc and zlib.crc32(f.read(_FOOTER_BYTES - 4), zlib.crc32(summary)) != crc:
            self.summary_problem = 'summary CRC mismatch'
            return
        try:
            listed = self._summary_records(summary)
        except (BadRecord, struct.error):
            self.summary_problem = 'summary records do not parse'
            return
        if listed is not None and sorted(listed) != sorted(self.chunks):
            self.fail(self.end, f'the summary lists {len(listed)} chunks, the data section holds '
                                f'{len(self.chunks)} others or at other places', located=False)

    def _summary_records(self, summary: bytes) -> list[tuple[int, int]] | None:
        pos, listed = 0, []
        while pos < len(summary):
            op, length = summary[pos], _U64.unpack_from(summary, pos + 1)[0]
            body = memoryview(summary)[pos + 9:pos + 9 + length]
            if len(body) != length:
                raise BadRecord('summary record runs past the summary')
            if op == CHUNK_INDEX:
                listed.append(tuple(struct.unpack_from('<QQ', body, 16)))
            elif op == STATISTICS:
                self.message_count = _U64.unpack_from(body, 0)[0]
            pos += 9 + length
        return listed if listed or self.message_count is not None else None

    def check_count(self, counted: int) -> None:
        """Compare the messages a reader counted with the summary's Statistics (if the file has them)."""
        if self.complete and self.message_count is not None and counted != self.message_count:
            self.fail(self.end, f'{counted} messages in the data section, the summary counts '
                                f'{self.message_count}', located=False)


def _framing_problem(pos: int, op: int, length: int) -> str | None:
    if pos == 8 and op != HEADER:
        return f'the first record is opcode 0x{op:02x}, not a header'
    if pos > 8 and op == HEADER:
        return 'a second header record'
    if op == 0 or 0x10 <= op < 0x80:
        return f'unknown record opcode 0x{op:02x}'
    if op in SUMMARY_ONLY:
        return f'summary record 0x{op:02x} in the data section'
    if op == MESSAGE and length < MESSAGE_HEAD:
        return f'a message record of {length} bytes'
    if op == DATA_END and length != 4:
        return f'a data end record of {length} bytes (4 expected)'
    return None


def _body_problem(op: int, body: bytes) -> str | None:
    """Records whose fields give their own length: the record must end where they do (a corrupt
    length is found at its record, not later where the framing it broke ends up)."""
    if op == MESSAGE_INDEX:
        if len(body) < 6 or _U32.unpack_from(body, 2)[0] + 6 != len(body) or (len(body) - 6) % 16:
            return 'a message index record whose entries do not fill it'
        return None
    if op != HEADER:
        return None
    try:
        _, pos = string(body, 0)                    # profile
        _, pos = string(body, pos)                  # library
    except (BadRecord, struct.error):
        return 'the header record does not parse'
    return None if pos == len(body) else 'the header fields do not end with its record'


def decompress(compression: str, data, size: int, zstd: zstandard.ZstdDecompressor) -> bytes:
    """A chunk's records, never more than ``size`` bytes (BadRecord if they do not decompress)."""
    try:
        if compression == '':
            return bytes(data)
        if compression == 'zstd':
            declared = zstandard.frame_content_size(data)
            if declared not in (-1, size):
                raise BadRecord(f'zstd frame of {declared} bytes in a chunk of {size}')
            return zstd.decompress(data, max_output_size=size)
        if compression == 'lz4':
            return lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
    except (zstandard.ZstdError, RuntimeError, ValueError) as exc:
        if isinstance(exc, BadRecord):
            raise
        raise BadRecord(f'{compression} chunk does not decompress ({str(exc).splitlines()[0][:80]})') from None
    raise BadRecord(f'unsupported chunk compression {compression!r}')
