"""Writing rosbag2-compatible MCAP bags (crash-tolerant): :class:`BagWriter`.

Layout of a bag (what ``ros2 bag record -s mcap`` makes): a folder with ``<name>_0.mcap`` and
``metadata.yaml`` (rosbag2 format version 9). Schemas are ``ros2msg`` text (from rosbags' type
store), messages CDR bytes exactly as they came off the wire, profile ``ros2``.

Crash tolerance: :class:`BagWriter` writes small chunks and :meth:`BagWriter.flush` closes the
open chunk and flushes the file, so after a SIGKILL everything before the last flush is readable
with :func:`adcs_sim.bag.reader.read_messages` (which reads a file with no summary as well).
``metadata.yaml`` is written on :meth:`BagWriter.close`.

One writer at a time: the writer holds the bag folder's lock (:class:`~adcs_sim.bag.lock.BagLock`,
naming it) from its start to its close, so ``adcs-bag-repair`` never rewrites a bag under it.

A write that fails (a full disk: ENOSPC, EDQUOT; or any other OSError) raises :class:`BagWriteError`:
the writer writes nothing more and lets go of its file and lock, so the bag is what a killed writer
leaves, readable up to the failure (every method raises that same error again;
:meth:`BagWriter.close` returns).

Memory: what the writer keeps does not grow with the recording. The mcap ``Writer`` keeps one
``ChunkIndex`` object per chunk written (a dataclass holding a dict of one offset per channel,
~2 KiB each with 20 channels) for the summary it writes at ``finish()``: a long recording, flushed
every half second, grew by tens of MiB that way (issue 18: the recorder 93 -> 124 MiB over a
230 MB bag). :class:`SpilledChunkIndexes` takes that list's place: each index is serialised, as the
summary will hold it, into an unlinked temporary file when its chunk is written, and copied back
into the summary at the end (same bytes, same order).

Log times are **simulated time**: for message types whose serialisation starts with a stamp
(``std_msgs/Header`` or ``builtin_interfaces/Time`` first, as every topic of the graph) the stamp
is read straight from the CDR bytes (no deserialisation); other types get the latest ``/clock``.
Two lockstep runs therefore produce identical bags.
"""
from __future__ import annotations

import contextlib
import errno
import functools
import os
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from mcap.data_stream import RecordBuilder
from mcap.writer import CompressionType, Writer

from adcs_sim.bag.lock import BagLock
from adcs_sim.bag.storage import typestore

ROSBAG2_VERSION = 9
STAMP_FIRST_TYPES = frozenset({
    'nav_msgs/msg/Odometry', 'sensor_msgs/msg/JointState', 'geometry_msgs/msg/Vector3Stamped',
    'diagnostic_msgs/msg/DiagnosticArray', 'rosgraph_msgs/msg/Clock',
    'geometry_msgs/msg/PoseStamped', 'geometry_msgs/msg/TwistStamped', 'std_msgs/msg/Header',
    'geometry_msgs/msg/TransformStamped',
})
# Types that are a sequence of stamped messages (the graph's markers, the bag's /tf): log time = the
# first element's stamp (after the uint32 length), or the latest /clock when empty or out of range.
STAMPED_ARRAY_TYPES = frozenset({'visualization_msgs/msg/MarkerArray', 'tf2_msgs/msg/TFMessage'})


def cdr_stamp_ns(data: bytes, offset: int = 4) -> int | None:
    """Stamp of a CDR message whose first field is a ``builtin_interfaces/Time``, in ns (``offset``
    8: of the first element of a sequence of such messages)."""
    if len(data) < offset + 8:
        return None
    fmt = '<iI' if data[1] & 1 else '>iI'
    sec, nanosec = struct.unpack_from(fmt, data, offset)
    return sec * 1_000_000_000 + nanosec


def cdr_array_stamp_ns(data: bytes) -> int | None:
    """Stamp of the first element of a CDR sequence of stamped messages (:data:`STAMPED_ARRAY_TYPES`);
    None when the sequence is empty or the stamp is out of range."""
    if len(data) < 16 or struct.unpack_from('<I' if data[1] & 1 else '>I', data, 4)[0] == 0:
        return None
    fmt = '<iI' if data[1] & 1 else '>iI'
    sec, nanosec = struct.unpack_from(fmt, data, 8)
    return sec * 1_000_000_000 + nanosec if sec >= 0 and nanosec < 1_000_000_000 else None


def qos_dicts(qos) -> list[dict[str, Any]]:
    """rclpy QoSProfile -> rosbag2 v9 ``offered_qos_profiles`` entry."""
    def dur(d):
        ns = d.nanoseconds
        if ns <= 0 or ns >= 2**63 - 1:
            return {'sec': 2147483647, 'nsec': 4294967295}
        return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}
    return [{
        'history': qos.history.name.lower(), 'depth': int(qos.depth),
        'reliability': qos.reliability.name.lower(), 'durability': qos.durability.name.lower(),
        'deadline': dur(qos.deadline), 'lifespan': dur(qos.lifespan),
        'liveliness': qos.liveliness.name.lower(),
        'liveliness_lease_duration': dur(qos.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions),
    }]


class SpilledChunkIndexes:
    """Stands in for the mcap ``Writer``'s private list of chunk indexes (``append`` while writing,
    iterated once by ``finish()``): each ``ChunkIndex`` is serialised at ``append`` into an unlinked
    temporary file (nothing left behind, even after a kill), so the writer's memory stays flat
    however many chunks a recording has. Iterating yields the stored records in blocks of at most
    ``block`` bytes, each with the ``write(builder)`` the summary calls: the summary gets the same
    bytes, in the same order, as from the list of objects."""

    def __init__(self, block: int = 1 << 20) -> None:
        self._file = tempfile.TemporaryFile(prefix='adcs_chunk_index_')
        self._builder = RecordBuilder()
        self._block = block
        self.count = 0

    def append(self, index) -> None:
        index.write(self._builder)
        self._file.write(self._builder.end())
        self.count += 1

    def __len__(self) -> int:
        return self.count

    def __iter__(self):
        self._file.flush()
        self._file.seek(0)
        while block := self._file.read(self._block):
            yield _RawRecords(block)
        self._file.seek(0, os.SEEK_END)

    def close(self) -> None:
        self._file.close()


@dataclass
class _RawRecords:
    """Records already serialised, written as they are into an mcap RecordBuilder."""

    data: bytes

    def write(self, builder: RecordBuilder) -> None:
        builder.write(self.data)


# The mcap Writer's (1.6) private list of chunk indexes, that SpilledChunkIndexes replaces.
_CHUNK_INDEXES_ATTR = '_Writer__chunk_indices'


def spill_chunk_indexes(writer: Writer) -> SpilledChunkIndexes | None:
    """Put a :class:`SpilledChunkIndexes` in place of ``writer``'s list of chunk indexes, before its
    first chunk. None (the writer keeps its list) if this mcap version has no such empty list."""
    if getattr(writer, _CHUNK_INDEXES_ATTR, None) != []:
        return None
    spilled = SpilledChunkIndexes()
    setattr(writer, _CHUNK_INDEXES_ATTR, spilled)
    return spilled


DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


class BagWriteError(OSError):
    """The bag could not be written (:attr:`disk_full`: no space or quota left); the writer stopped."""

    def __init__(self, bag: Path, exc: OSError) -> None:
        super().__init__(exc.errno, f'cannot write the bag {bag}: {exc.strerror or exc}')

    def __str__(self) -> str:
        return self.strerror

    @property
    def disk_full(self) -> bool:
        return self.errno in DISK_FULL


def _writes(method):
    """A :class:`BagWriter` method that writes: its first OSError stops the writer (released, the error
    kept as :class:`BagWriteError`), and once stopped the method only raises that error again."""
    @functools.wraps(method)
    def call(self, *args, **kwargs):
        if self.failed is not None:
            raise self.failed
        try:
            return method(self, *args, **kwargs)
        except OSError as exc:
            self.failed = BagWriteError(self.path, exc)
            self._release()
            raise self.failed from exc
    return call


@dataclass
class _Topic:
    channel_id: int
    type_name: str
    qos: list[dict[str, Any]]
    count: int = 0
    stamped: bool = False
    array: bool = False    # a sequence of stamped messages (STAMPED_ARRAY_TYPES)


@dataclass
class BagWriter:
    """Write a rosbag2 MCAP bag folder. Refuses to overwrite an existing, non-empty folder, and a folder
    another writer holds (:class:`~adcs_sim.bag.lock.BagInUse`)."""

    path: Path
    chunk_size: int = 65536
    metadata: dict[str, str] = field(default_factory=dict)
    file_name: str | None = None   # default <folder name>_0.mcap, as ros2 bag record names it
    process: str | None = None     # who writes, as the lock names it (default: this program's name)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.path.exists() and any(self.path.iterdir()):
            raise FileExistsError(f'bag folder {self.path} exists and is not empty')
        self.path.mkdir(parents=True, exist_ok=True)
        self.mcap_path = self.path / (self.file_name or f'{self.path.name}_0.mcap')
        self._schemas: dict[str, int] = {}
        self.topics: dict[str, _Topic] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.clock_ns = 0
        self.closed = False
        self.failed: BagWriteError | None = None
        self._file = self._chunk_indexes = None
        self._lock = BagLock(self.path, self.process)
        self._start()

    @_writes
    def _start(self) -> None:
        self._file = open(self.mcap_path, 'wb')
        # Data-section CRC on (the mcap default is off): with the chunk and summary CRCs, every byte
        # of a closed file is covered, so a reader detects any flipped bit.
        self._writer = Writer(self._file, chunk_size=self.chunk_size, compression=CompressionType.ZSTD,
                              enable_data_crcs=True)
        self._chunk_indexes = spill_chunk_indexes(self._writer)
        self._writer.start(profile='ros2', library='adcs_sim')
        for name, text in self.metadata.items():
            self._writer.add_metadata(name, {'text': text})
        self._file.flush()

    @_writes
    def add_topic(self, name: str, type_name: str, qos: list[dict[str, Any]],
                  schema: tuple[str, bytes] | None = None) -> None:
        """Register a topic (idempotent). ``schema`` (encoding, data): the message definition to
        store (default: the ``ros2msg`` text of the Jazzy type store)."""
        if name in self.topics:
            return
        if type_name not in self._schemas:
            if schema is None:
                text, _ = typestore().generate_msgdef(type_name, ros_version=2)
                schema = ('ros2msg', text.encode())
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding=schema[0], data=schema[1])
        cid = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': yaml.safe_dump(qos, sort_keys=False)})
        self.topics[name] = _Topic(cid, type_name, qos, stamped=type_name in STAMP_FIRST_TYPES,
                                   array=type_name in STAMPED_ARRAY_TYPES)

    @_writes
    def write(self, topic: str, data: bytes, log_time_ns: int | None = None) -> None:
        """Append one serialized message; log time = its stamp (or the latest /clock)."""
        t = self.topics[topic]
        if log_time_ns is None:
            stamp = cdr_stamp_ns(data) if t.stamped else cdr_array_stamp_ns(data) if t.array else None
            log_time_ns = stamp if stamp is not None else self.clock_ns
        if t.type_name == 'rosgraph_msgs/msg/Clock':
            self.clock_ns = max(self.clock_ns, log_time_ns)
        self._writer.add_message(channel_id=t.channel_id, log_time=log_time_ns, data=bytes(data),
                                 publish_time=log_time_ns, sequence=t.count)
        t.count += 1
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)

    @_writes
    def flush(self) -> None:
        """Close the open chunk and push everything to the OS (survives a kill of this process)."""
        self._writer.flush()

    def close(self, custom_data: dict[str, str] | None = None) -> None:
        """Write the MCAP summary and ``metadata.yaml``, and let go of the bag. Idempotent; after a
        failed write it only lets go (the bag stays as the failure left it)."""
        if self.closed:
            return
        self.closed = True
        if self.failed is None:
            self._finish(custom_data)
        self._release()

    @_writes
    def _finish(self, custom_data: dict[str, str] | None) -> None:
        info = self.bagfile_information(custom_data)
        self._writer.add_metadata('rosbag2', {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
        self._writer.finish()
        self._file.close()
        tmp = self.path / 'metadata.yaml.tmp'
        tmp.write_text(yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
        os.replace(tmp, self.path / 'metadata.yaml')

    def _release(self) -> None:
        """Let go of the file, the spilled chunk indexes, a half-written ``metadata.yaml`` and the lock
        (on close, or once a write failed: nothing is written after that)."""
        for part in (self._file, self._chunk_indexes):
            if part is not None:
                with contextlib.suppress(OSError):
                    part.close()
        with contextlib.suppress(OSError):
            (self.path / 'metadata.yaml.tmp').unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            self._lock.release()

    def bagfile_information(self, custom_data: dict[str, str] | None = None) -> dict[str, Any]:
        start = self.start_ns or 0
        duration = max(0, self.end_ns - start)
        count = sum(t.count for t in self.topics.values())
        return {
            'version': ROSBAG2_VERSION,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [{
                'topic_metadata': {
                    'name': name, 'type': t.type_name, 'serialization_format': 'cdr',
                    'offered_qos_profiles': t.qos, 'type_description_hash': '',
                },
                'message_count': t.count,
            } for name, t in self.topics.items()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.mcap_path.name],
            'files': [{'path': self.mcap_path.name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration}, 'message_count': count}],
            'custom_data': custom_data or {},
            'ros_distro': 'jazzy',
        }


