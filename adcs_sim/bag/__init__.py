"""rosbag2-compatible MCAP bags: writing (crash-tolerant) and reading (no ROS needed).

Layout of a bag (what ``ros2 bag record -s mcap`` makes): a folder with ``<name>_0.mcap`` and
``metadata.yaml`` (rosbag2 format version 9). Schemas are ``ros2msg`` text (from rosbags' type
store), messages CDR bytes exactly as they came off the wire, profile ``ros2``.

Crash tolerance: :class:`BagWriter` writes small chunks and :meth:`BagWriter.flush` closes the
open chunk and flushes the file, so after a SIGKILL everything before the last flush is readable
with :func:`read_messages` (which falls back to a streaming read of a file with no summary).
``metadata.yaml`` is written on :meth:`BagWriter.close`.

Log times are **simulated time**: for message types whose serialisation starts with a stamp
(``std_msgs/Header`` or ``builtin_interfaces/Time`` first, as every topic of the graph) the stamp
is read straight from the CDR bytes (no deserialisation); other types get the latest ``/clock``.
Two lockstep runs therefore produce identical bags.

Reading any rosbag2 bag: MCAP files (ours, ``ros2 bag record``, rosbags' writer; complete or
truncated) are parsed here record by record; other storage (sqlite3 ``.db3``) goes through
rosbags' ``AnyReader``. :func:`read_raw` yields one message at a time; :class:`ColumnReader`
streams the raw CDR bytes of selected topics in large batches, and :func:`decode_batch` turns a
batch into numpy columns without deserialising message by message (the CDR layout of a message
type is fixed up to its string and sequence lengths, so it is computed once per distinct layout).
"""
from __future__ import annotations

import os
import re
import struct
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, Writer
from rosbags.typesys import Stores, get_typestore

ROSBAG2_VERSION = 9
STAMP_FIRST_TYPES = frozenset({
    'nav_msgs/msg/Odometry', 'sensor_msgs/msg/JointState', 'geometry_msgs/msg/Vector3Stamped',
    'diagnostic_msgs/msg/DiagnosticArray', 'rosgraph_msgs/msg/Clock',
    'geometry_msgs/msg/PoseStamped', 'geometry_msgs/msg/TwistStamped', 'std_msgs/msg/Header',
})
_TYPESTORE = None


def typestore():
    """The rosbags type store for ROS 2 Jazzy (message definitions and CDR (de)serialisation)."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def cdr_stamp_ns(data: bytes) -> int | None:
    """Stamp of a CDR message whose first field is a ``builtin_interfaces/Time``, in ns."""
    if len(data) < 12:
        return None
    fmt = '<iI' if data[1] & 1 else '>iI'
    sec, nanosec = struct.unpack_from(fmt, data, 4)
    return sec * 1_000_000_000 + nanosec


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


@dataclass
class _Topic:
    channel_id: int
    type_name: str
    qos: list[dict[str, Any]]
    count: int = 0
    stamped: bool = False


@dataclass
class BagWriter:
    """Write a rosbag2 MCAP bag folder. Refuses to overwrite an existing, non-empty folder."""

    path: Path
    chunk_size: int = 65536
    metadata: dict[str, str] = field(default_factory=dict)
    file_name: str | None = None   # default <folder name>_0.mcap, as ros2 bag record names it

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.path.exists() and any(self.path.iterdir()):
            raise FileExistsError(f'bag folder {self.path} exists and is not empty')
        self.path.mkdir(parents=True, exist_ok=True)
        self.mcap_path = self.path / (self.file_name or f'{self.path.name}_0.mcap')
        self._file = open(self.mcap_path, 'wb')
        self._writer = Writer(self._file, chunk_size=self.chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile='ros2', library='adcs_sim')
        self._schemas: dict[str, int] = {}
        self.topics: dict[str, _Topic] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.clock_ns = 0
        self.closed = False
        for name, text in self.metadata.items():
            self._writer.add_metadata(name, {'text': text})
        self._file.flush()

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
        self.topics[name] = _Topic(cid, type_name, qos, stamped=type_name in STAMP_FIRST_TYPES)

    def write(self, topic: str, data: bytes, log_time_ns: int | None = None) -> None:
        """Append one serialized message; log time = its stamp (or the latest /clock)."""
        t = self.topics[topic]
        if log_time_ns is None:
            stamp = cdr_stamp_ns(data) if t.stamped else None
            log_time_ns = stamp if stamp is not None else self.clock_ns
        if t.type_name == 'rosgraph_msgs/msg/Clock':
            self.clock_ns = max(self.clock_ns, log_time_ns)
        self._writer.add_message(channel_id=t.channel_id, log_time=log_time_ns, data=bytes(data),
                                 publish_time=log_time_ns, sequence=t.count)
        t.count += 1
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)

    def flush(self) -> None:
        """Close the open chunk and push everything to the OS (survives a kill of this process)."""
        self._writer.flush()

    def close(self, custom_data: dict[str, str] | None = None) -> None:
        """Write the MCAP summary and ``metadata.yaml``. Idempotent."""
        if self.closed:
            return
        self.closed = True
        info = self.bagfile_information(custom_data)
        self._writer.add_metadata('rosbag2', {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
        self._writer.finish()
        self._file.close()
        tmp = self.path / 'metadata.yaml.tmp'
        tmp.write_text(yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
        os.replace(tmp, self.path / 'metadata.yaml')

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


# --- repairing a bag whose writer was killed -------------------------------------------------

TRUNCATED_SUFFIX = '.truncated'


@dataclass
class RepairResult:
    bag: Path
    status: str                 # 'repaired' or 'complete' (nothing to do)
    messages: int = 0
    kept: Path | None = None    # the original truncated file, kept beside the repaired one


def _salvage(path: Path):
    """Every whole record of an MCAP file, in file order, up to its first damaged or missing byte:
    (schemas {id: Schema}, channels {id: Channel} in order, metadata [Metadata], messages
    [Message]). A killed writer's file ends mid-chunk; the records before it are intact."""
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    schemas, channels, metadata, messages = {}, {}, [], []
    with open(path, 'rb') as f:
        try:
            for record in StreamReader(f, skip_magic=False, emit_chunks=False, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Metadata):
                    metadata.append(record)
                elif isinstance(record, Message):
                    messages.append(record)
        except Exception:  # noqa: BLE001 - the truncated tail (EOF, short record, bad CRC)
            pass
    return schemas, channels, metadata, messages


def is_complete(bag: str | os.PathLike) -> bool:
    """Whether a bag folder's MCAP file has its summary and the folder its ``metadata.yaml``."""
    path = Path(bag)
    folder = path if path.is_dir() else path.parent
    with open(mcap_file(bag), 'rb') as f:
        _, complete = _open_reader(f)
    return complete and (folder / 'metadata.yaml').exists()


def repair(bag: str | os.PathLike, force: bool = False) -> RepairResult:
    """Rewrite the MCAP file of a bag whose writer was killed into a complete rosbag2 bag, in place.

    Every whole record of the truncated file is kept (schemas, channels with their offered QoS,
    the embedded metadata such as the scenario, every message with its log time); the new file
    has a summary and index, and ``metadata.yaml`` is written (format 9, ``custom_data`` notes the
    repair). The original is kept beside it as ``<name>.mcap.truncated`` (so nothing is lost if
    the repair itself is interrupted). A bag that is already complete is left alone unless
    ``force``. Raises FileNotFoundError / ValueError for what is not an MCAP bag.
    """
    path = Path(bag)
    kind, files = bag_files(path)
    if kind != 'mcap' or len(files) != 1:
        raise ValueError(f'{path}: repair handles a one-file MCAP bag (found {kind}, {len(files)} file(s))')
    src = files[0]
    folder = path if path.is_dir() else path.parent
    if not force and is_complete(folder):
        return RepairResult(folder, 'complete')
    schemas, channels, metadata, messages = _salvage(src)
    tmp = folder.parent / f'.{folder.name}.repair-{os.getpid()}'
    if tmp.exists():
        import shutil
        shutil.rmtree(tmp)
    writer = BagWriter(tmp, metadata={m.name: m.metadata.get('text', '') for m in metadata
                                      if m.name != 'rosbag2' and 'text' in m.metadata},
                       file_name=src.name)
    names = {}
    for cid, ch in channels.items():
        schema = schemas.get(ch.schema_id)
        if schema is None:
            continue
        try:
            qos = yaml.safe_load(ch.metadata.get('offered_qos_profiles', '')) or []
        except yaml.YAMLError:
            qos = []
        writer.add_topic(ch.topic, schema.name, qos, (schema.encoding, schema.data))
        names[cid] = ch.topic
    written = 0
    for m in messages:
        if m.channel_id in names:
            writer.write(names[m.channel_id], m.data, log_time_ns=m.log_time)
            written += 1
    writer.close({'repaired_by': 'adcs-bag-repair',
                  'repaired_from': src.name + TRUNCATED_SUFFIX,
                  'repaired_messages': str(written)})
    kept = src.with_name(src.name + TRUNCATED_SUFFIX)
    os.replace(src, kept)                                   # the original, kept
    os.replace(tmp / src.name, src)                         # the complete file
    os.replace(tmp / 'metadata.yaml', folder / 'metadata.yaml')
    tmp.rmdir()
    return RepairResult(folder, 'repaired', written, kept)


# --- reading --------------------------------------------------------------------------------

def mcap_file(bag: str | os.PathLike) -> Path:
    """The ``.mcap`` file of a bag folder (or the file itself)."""
    path = Path(bag)
    if path.is_dir():
        files = sorted(path.glob('*.mcap'))
        if not files:
            raise FileNotFoundError(f'no .mcap file in bag folder {path}')
        return files[0]
    return path


def _open_reader(f):
    """(reader, complete): indexed reader for a file with a summary, else a streaming reader."""
    try:
        complete = make_reader(f).get_summary() is not None
    except Exception:  # noqa: BLE001 - no footer / damaged summary: the writer was killed
        complete = False
    f.seek(0)
    return (make_reader(f), True) if complete else (NonSeekingReader(f, validate_crcs=False), False)


def _records(bag, method: str):
    """Iterate ``reader.<method>()`` over a bag's file; a truncated file ends at its last whole record.

    A complete file is read through its index and any damage raises; a file without summary
    (writer killed) is streamed and the iteration stops quietly at the first incomplete record.
    """
    with open(mcap_file(bag), 'rb') as f:
        reader, complete = _open_reader(f)
        it = getattr(reader, method)(**({'log_time_order': False} if method == 'iter_messages' else {}))
        if complete:
            yield from it
            return
        try:
            yield from it
        except Exception:  # noqa: BLE001 - truncated tail
            return


def read_raw(bag: str | os.PathLike) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type name, log time ns, CDR bytes) for every message, in file order.

    Works on a complete bag and on one whose writer was killed (everything up to the last
    complete record). A bag that is not MCAP (e.g. sqlite3) is read with rosbags' ``AnyReader``
    (in log-time order).
    """
    kind, files = bag_files(bag)
    if kind == 'rosbag2':
        with _any_reader(bag, files[0]) as reader:
            for conn, t, data in reader.messages():
                yield conn.topic, conn.msgtype, t, data
        return
    for path in files:
        for schema, channel, message in _records(path, 'iter_messages'):
            yield channel.topic, schema.name, message.log_time, message.data


def read_messages(bag: str | os.PathLike, topics: set[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """(topic, log time ns, deserialised message) with rosbags' type store, optionally filtered."""
    store = typestore()
    for topic, type_name, t, data in read_raw(bag):
        if topics is None or topic in topics:
            yield topic, t, store.deserialize_cdr(data, type_name)


def read_metadata(bag: str | os.PathLike) -> dict[str, str]:
    """MCAP metadata records of a bag (e.g. the embedded ``scenario`` file), also when truncated.

    Empty for a bag whose storage has no such records (sqlite3)."""
    kind, files = bag_files(bag)
    if kind != 'mcap':
        return {}
    return {record.name: record.metadata.get('text', '')
            for path in files for record in _records(path, 'iter_metadata')}


# --- locating the storage of a bag ----------------------------------------------------------

MCAP_MAGIC = b'\x89MCAP0\r\n'
SQLITE_MAGIC = b'SQLite format 3\x00'


def _natural_key(path: Path):
    return [int(x) if x.isdigit() else x for x in re.split(r'(\d+)', path.name)]


def bag_files(bag: str | os.PathLike) -> tuple[str, list[Path]]:
    """``('mcap', [files in order])`` or ``('rosbag2', [folder])`` (storage read by rosbags).

    ``bag`` is a bag folder, an ``.mcap`` file, or a storage file of a rosbag2 folder (``.db3``).
    Raises FileNotFoundError (no such path, or a folder without a bag) or ValueError (a file that
    is not a bag), each with a one-line message.
    """
    path = Path(bag)
    if not path.exists():
        raise FileNotFoundError(f'{path}: no such bag (file or folder)')
    if path.is_dir():
        files = sorted(path.glob('*.mcap'), key=_natural_key)
        listed = _listed_files(path)
        if listed and all((path / f).suffix == '.mcap' and (path / f).exists() for f in listed):
            files = [path / f for f in listed]
        if files:
            return 'mcap', files
        if (path / 'metadata.yaml').exists():
            return 'rosbag2', [path]
        raise FileNotFoundError(f'{path}: no .mcap file and no metadata.yaml: not a bag folder')
    try:
        with open(path, 'rb') as f:
            head = f.read(16)
    except OSError as exc:
        raise OSError(f'{path}: cannot read: {exc.strerror}') from None
    if head.startswith(MCAP_MAGIC):
        return 'mcap', [path]
    if head.startswith(SQLITE_MAGIC) and (path.parent / 'metadata.yaml').exists():
        return 'rosbag2', [path.parent]
    raise ValueError(f'{path}: not a bag: neither an MCAP file nor a rosbag2 bag folder')


def _listed_files(folder: Path) -> list[str]:
    """``relative_file_paths`` of a bag folder's metadata.yaml (empty if absent or unreadable)."""
    try:
        info = yaml.safe_load((folder / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        return [str(x) for x in info.get('relative_file_paths') or []]
    except (OSError, KeyError, TypeError, yaml.YAMLError):
        return []


class _any_reader:
    """rosbags' AnyReader on a rosbag2 folder, its errors turned into one-line ValueErrors."""

    def __init__(self, bag, folder: Path) -> None:
        self.bag, self.folder = bag, folder
        self.reader = None

    def __enter__(self):
        from rosbags.highlevel import AnyReader
        try:
            self.reader = AnyReader([Path(self.folder)], default_typestore=typestore())
            self.reader.open()
        except Exception as exc:  # noqa: BLE001 - rosbags raises several types; one message for all
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ValueError(f'{self.bag}: cannot read bag: {first}') from exc
        if not self.reader.is2:
            self.reader.close()
            raise ValueError(f'{self.bag}: not a rosbag2 bag')
        return self.reader

    def __exit__(self, *exc) -> None:
        if self.reader is not None:
            self.reader.close()


# --- streaming raw bytes of selected topics, in batches ---------------------------------------

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
        with _any_reader(self.bag, self.files[0]) as reader:
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
                import zstandard
                self._zstd = zstandard.ZstdDecompressor()
            return self._zstd.decompress(data, max_output_size=size)
        if compression == 'lz4':
            import lz4.frame
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


# --- CDR columns ------------------------------------------------------------------------------

class _Cursor:
    """Walks one CDR message (XCDR1, as ROS 2 writes) and records what pins its layout."""

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise ValueError('unsupported CDR encapsulation')
        self.data = data
        self.little = data[1] == 1
        self.pos = 4
        self.checks: list[tuple[int, bytes]] = [(0, bytes(data[:2]))]
        self.u32 = struct.Struct('<I' if self.little else '>I')

    def _need(self, n: int) -> None:
        if self.pos + n > len(self.data):
            raise ValueError('CDR message shorter than its layout')

    def align(self, n: int) -> None:
        self.pos += -(self.pos - 4) % n

    def skip(self, n: int, align: int) -> None:
        self.align(align)
        self._need(n)
        self.pos += n

    def uint32(self) -> int:
        """A length or count: pinned (messages with another value have another layout)."""
        self.align(4)
        self._need(4)
        self.checks.append((self.pos, bytes(self.data[self.pos:self.pos + 4])))
        value = self.u32.unpack_from(self.data, self.pos)[0]
        self.pos += 4
        return value

    def string(self, pin_text: bool = False) -> str:
        n = self.uint32()
        self._need(n)
        text = bytes(self.data[self.pos:self.pos + n])
        if pin_text:
            self.checks.append((self.pos, text))
        self.pos += n
        return text.rstrip(b'\x00').decode('utf-8', 'replace')

    def float64(self, count: int) -> int:
        """Offset of ``count`` doubles (an empty array is not aligned, as CDR writers do)."""
        if count:
            self.align(8)
        self._need(8 * count)
        pos = self.pos
        self.pos += 8 * count
        return pos


@dataclass
class _Layout:
    little: bool
    end: int
    checks: list[tuple[int, bytes]]
    fields: dict[str, tuple[int, int]]   # name -> (offset, number of float64)
    extra: Any = None

    @property
    def key(self):
        return tuple(self.checks)


def _header(c: _Cursor) -> None:
    c.skip(8, 4)          # builtin_interfaces/Time: int32 sec, uint32 nanosec
    c.string()            # frame_id


def _odometry(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    c.string()                                   # child_frame_id
    fields = {'position': (c.float64(3), 3), 'orientation': (c.float64(4), 4)}
    c.float64(36)
    fields['linear'] = (c.float64(3), 3)
    fields['angular'] = (c.float64(3), 3)
    c.float64(36)
    return fields, None


def _vector3_stamped(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    return {'vector': (c.float64(3), 3)}, None


def _joint_state(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    names = tuple(c.string(pin_text=True) for _ in range(c.uint32()))
    fields = {}
    for name in ('position', 'velocity', 'effort'):
        n = c.uint32()
        fields[name] = (c.float64(n), n)
    return fields, names


LAYOUTS: dict[str, Callable[[_Cursor], tuple[dict, Any]]] = {
    'nav_msgs/msg/Odometry': _odometry,
    'geometry_msgs/msg/Vector3Stamped': _vector3_stamped,
    'sensor_msgs/msg/JointState': _joint_state,
}
MAX_TEMPLATES = 16


class _TemplateBudget:
    """When to stop vectorising a batch by layout templates and parse the rest one by one.

    A template that matched only its own message (a one-off layout) cost a pass over the batch
    for nothing: after ``MAX_TEMPLATES`` of those, or ``4 * MAX_TEMPLATES`` passes in all, the
    remaining messages are parsed individually (so many distinct layouts stay linear in time).
    """

    def __init__(self) -> None:
        self.passes = self.misses = 0

    def left(self) -> bool:
        return self.misses < MAX_TEMPLATES and self.passes < 4 * MAX_TEMPLATES

    def used(self, matched: int) -> None:
        self.passes += 1
        self.misses += matched <= 1


def _layout(type_name: str, data: bytes) -> _Layout | None:
    try:
        c = _Cursor(data)
        fields, extra = LAYOUTS[type_name](c)
    except (ValueError, struct.error, UnicodeDecodeError):
        return None
    return _Layout(c.little, c.pos, c.checks, fields, extra)


@dataclass
class Columns:
    """Decoded messages of one layout: ``rows`` index the batch's messages (ascending)."""

    rows: np.ndarray
    sec: np.ndarray                 # int64 stamp seconds
    nanosec: np.ndarray             # int64 stamp nanoseconds
    fields: dict[str, np.ndarray]   # float64 (n, k) per field
    extra: Any = None               # JointState: the joint names

    @property
    def stamp(self) -> np.ndarray:
        """Stamps in seconds (``sec + nanosec * 1e-9``)."""
        return self.sec + self.nanosec * 1e-9

    @property
    def stamp_ns(self) -> np.ndarray:
        return self.sec * 1_000_000_000 + self.nanosec


def _gather(buf: np.ndarray, starts: np.ndarray, nbytes: int) -> np.ndarray:
    return buf[starts[:, None] + np.arange(nbytes)]


def _columns(batch: TopicBatch, rows: np.ndarray, layout: _Layout) -> Columns:
    starts = batch.starts[rows]
    e = '<' if layout.little else '>'
    stamp = _gather(batch.buf, starts + 4, 8)
    sec = stamp[:, :4].copy().view(e + 'i4')[:, 0].astype(np.int64)
    nsec = stamp[:, 4:].copy().view(e + 'u4')[:, 0].astype(np.int64)
    fields = {}
    for name, (off, n) in layout.fields.items():
        if n:
            fields[name] = _gather(batch.buf, starts + off, 8 * n).view(e + 'f8').astype(np.float64)
        else:
            fields[name] = np.zeros((rows.size, 0))
    return Columns(rows, sec, nsec, fields, layout.extra)


def _matching(batch: TopicBatch, rows: np.ndarray, layout: _Layout) -> np.ndarray:
    """Boolean mask over ``rows``: messages with exactly ``layout``."""
    mask = batch.sizes[rows] >= layout.end
    for off, expected in layout.checks:
        sub = rows[mask]
        if not sub.size:
            break
        got = _gather(batch.buf, batch.starts[sub] + off, len(expected))
        ok = np.all(got == np.frombuffer(expected, np.uint8), axis=1)
        mask[np.flatnonzero(mask)[~ok]] = False
    return mask


def decode_batch(batch: TopicBatch) -> list[Columns]:
    """The stamps and float fields of every message of ``batch``, one :class:`Columns` per layout.

    Types: ``nav_msgs/Odometry`` (fields ``position``, ``orientation``, ``linear``, ``angular``),
    ``geometry_msgs/Vector3Stamped`` (``vector``) and ``sensor_msgs/JointState`` (``position``,
    ``velocity``, ``effort``; ``extra`` = names). Each distinct layout (string and sequence
    lengths, byte order, joint names) is parsed once in Python from its first message; the fields
    of all messages sharing it are gathered with numpy. Messages that do not parse are skipped.
    """
    if batch.type_name not in LAYOUTS:
        raise ValueError(f'no column decoder for {batch.type_name}')
    out = []
    rows = np.arange(len(batch))
    budget = _TemplateBudget()
    while rows.size and budget.left():
        layout = _layout(batch.type_name, batch.message(rows[0]))
        if layout is None:
            budget.used(0)
            rows = rows[1:]
            continue
        mask = _matching(batch, rows, layout)
        out.append(_columns(batch, rows[mask], layout))
        budget.used(int(mask.sum()))
        rows = rows[~mask]
    if rows.size:  # many distinct layouts: parse each message, gather per layout
        groups: dict[Any, tuple[_Layout, list[int]]] = {}
        for r in rows.tolist():
            layout = _layout(batch.type_name, batch.message(r))
            if layout is not None:
                groups.setdefault(layout.key, (layout, []))[1].append(r)
        out.extend(_columns(batch, np.array(r, dtype=np.int64), lay) for lay, r in groups.values())
    return out


def decode_diagnostics(batch: TopicBatch) -> tuple[np.ndarray, list[list[tuple]]]:
    """``diagnostic_msgs/DiagnosticArray`` messages: (stamps in s, statuses per message).

    Each status is a tuple ``(level, name, message, hardware_id, {key: value})``; names and keys
    are shared string objects across messages. No rosbags deserialisation: the first message of
    a structure (number of statuses, their names, their keys) is parsed in Python, then every
    message with the same structure is walked with numpy (only the value strings' lengths
    differ from message to message) and its strings cut from one decoded blob. Messages that do
    not parse are skipped (their stamp is not returned either).
    """
    n = len(batch)
    stamps = np.zeros(n)
    out: list = [None] * n
    names: dict[bytes, str] = {}
    rows = np.arange(n)
    budget = _TemplateBudget()
    while rows.size and budget.left():
        try:
            template = _diagnostic_array(batch.message(rows[0]), names)
        except (ValueError, struct.error, IndexError, UnicodeDecodeError):
            budget.used(0)
            rows = rows[1:]
            continue
        done = _diagnostics_like(batch, rows, batch.message(rows[0])[:2], template[1], stamps, out)
        if not done[0]:  # (cannot happen: a message has its own structure) parse it on its own
            stamps[rows[0]], out[rows[0]] = template
            done[0] = True
        budget.used(int(done.sum()))
        rows = rows[~done]
    for r in rows.tolist():
        try:
            stamps[r], out[r] = _diagnostic_array(batch.message(r), names)
        except (ValueError, struct.error, IndexError, UnicodeDecodeError):
            pass
    keep = [i for i, x in enumerate(out) if x is not None]
    if len(keep) == n:
        return stamps, out
    return stamps[keep], [out[i] for i in keep]


class _VecWalk:
    """CDR walk of many messages at once; messages that leave the expected structure drop out."""

    def __init__(self, batch: TopicBatch, rows: np.ndarray, little: bool) -> None:
        self.buf = batch.buf
        self.sel = np.arange(rows.size)             # indices into rows still matching
        self.start = batch.starts[rows]
        self.size = batch.sizes[rows]
        self.r = np.full(rows.size, 4, dtype=np.int64)
        self.e = '<' if little else '>'
        self.cols: list[np.ndarray] = []            # recorded per-message arrays, aligned with sel

    def keep(self, ok: np.ndarray) -> None:
        if not ok.all():
            self.sel, self.r = self.sel[ok], self.r[ok]
            self.cols = [c[ok] for c in self.cols]

    def need(self, width) -> None:
        self.keep(self.r + width <= self.size[self.sel])

    def at(self) -> np.ndarray:
        return self.start[self.sel] + self.r

    def octet(self) -> int:
        self.need(1)
        self.cols.append(self.buf[self.at()].astype(np.int64))
        self.r = self.r + 1
        return len(self.cols) - 1

    def uint32(self) -> np.ndarray:
        self.r = (self.r + 3) & ~3
        self.need(4)
        value = _gather(self.buf, self.at(), 4).view(self.e + 'u4')[:, 0].astype(np.int64)
        self.r = self.r + 4
        return value

    def count(self, expected: int) -> None:
        self.keep(self.uint32() == expected)

    def const_string(self, text: bytes) -> None:
        self.keep(self.uint32() == len(text))
        self.need(len(text))
        if text:
            got = _gather(self.buf, self.at(), len(text))
            self.keep(np.all(got == np.frombuffer(text, np.uint8), axis=1))
        self.r = self.r + len(text)

    def string(self) -> int:
        """Record (start, length without the NUL) of a string; returns the column index."""
        n = self.uint32()
        ok = self.r + n <= self.size[self.sel]
        if not ok.all():
            self.sel, self.r, n = self.sel[ok], self.r[ok], n[ok]
            self.cols = [c[ok] for c in self.cols]
        self.cols.append(self.at())
        self.cols.append(np.maximum(n - 1, 0))
        self.r = self.r + n
        return len(self.cols) - 2


def _cdr_text(value: str) -> bytes:
    return value.encode() + b'\x00'


def _strings(buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> list[str]:
    """Decode many strings at once: gather their bytes into one blob, decode once, cut."""
    total = int(lengths.sum())
    if total == 0:
        return [''] * int(lengths.size)
    ends = np.cumsum(lengths)
    blob = buf[np.repeat(starts - (ends - lengths), lengths) + np.arange(total)].tobytes()
    bounds = ends.tolist()
    lo = [0] + bounds[:-1]
    if blob.isascii():
        text = blob.decode('ascii')
        return [text[a:b] for a, b in zip(lo, bounds)]
    return [blob[a:b].decode() for a, b in zip(lo, bounds)]


def _diagnostics_like(batch: TopicBatch, rows: np.ndarray, encapsulation: bytes, template: list,
                      stamps: np.ndarray, out: list) -> np.ndarray:
    """Decode the messages of ``rows`` with the structure of ``template``; the mask of those done."""
    walk = _VecWalk(batch, rows, encapsulation[1:2] == b'\x01')
    enc = _gather(batch.buf, walk.start, 2)
    walk.keep(np.all(enc == np.frombuffer(encapsulation, np.uint8), axis=1))
    walk.need(12)
    walk.r = walk.r + 8                                  # the stamp
    walk.string()                                        # header.frame_id
    walk.count(len(template))
    layout = []
    for level, name, _, _, values in template:
        lv = walk.octet()
        walk.const_string(_cdr_text(name))
        msg, hw = walk.string(), walk.string()
        walk.count(len(values))
        cols = []
        for key in values:
            walk.const_string(_cdr_text(key))
            cols.append(walk.string())
        layout.append((lv, name, msg, hw, list(values), cols))
    done = np.zeros(rows.size, dtype=bool)
    if not walk.sel.size:
        return done
    try:
        def text(col):
            return _strings(batch.buf, walk.cols[col], walk.cols[col + 1])
        per_status = []
        for lv, name, msg, hw, keys, cols in layout:
            levels = walk.cols[lv].tolist()
            values = [text(c) for c in cols]
            per_status.append([(level, name, m, h, dict(zip(keys, vs)))
                               for level, m, h, *vs in zip(levels, text(msg), text(hw), *values)])
    except UnicodeDecodeError:
        return done
    picked = rows[walk.sel]
    st = _gather(batch.buf, walk.start[walk.sel] + 4, 8)
    sec = st[:, :4].copy().view(walk.e + 'i4')[:, 0].astype(np.int64)
    nsec = st[:, 4:].copy().view(walk.e + 'u4')[:, 0].astype(np.int64)
    stamps[picked] = sec + nsec * 1e-9
    if not per_status:
        lists = [[] for _ in range(picked.size)]
    elif len(per_status) == 1:
        lists = [[s] for s in per_status[0]]
    else:
        lists = [list(x) for x in zip(*per_status)]
    for i, statuses in zip(picked.tolist(), lists):
        out[i] = statuses
    done[walk.sel] = True
    return done


_LE_U32, _BE_U32 = struct.Struct('<I').unpack_from, struct.Struct('>I').unpack_from


def _diagnostic_array(data: bytes, names: dict[bytes, str]) -> tuple[float, list[tuple]]:
    """One DiagnosticArray. Positions are absolute: with the 4-byte encapsulation header in front,
    CDR's 4-byte alignment is ``(pos + 3) & ~3``; a string is followed by unaligned data.
    ``names`` caches the decoded repeating strings (bytes -> str)."""
    if len(data) < 16 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError('unsupported CDR encapsulation')
    little = data[1] == 1
    u32 = _LE_U32 if little else _BE_U32
    sec, nsec = struct.unpack_from('<iI' if little else '>iI', data, 4)
    pos = (19 + u32(data, 12)[0]) & ~3               # past header.frame_id, aligned
    count = u32(data, pos)[0]
    pos += 4
    statuses = []
    for _ in range(count):
        level = data[pos]
        pos = (pos + 4) & ~3                            # the level octet, then align
        strs = []
        for _ in range(3):                              # name, message, hardware_id
            n = u32(data, pos)[0]
            raw = data[pos + 4:pos + 3 + n]
            text = names.get(raw)
            if text is None:
                text = names[raw] = raw.decode()
            strs.append(text)
            pos = (pos + 7 + n) & ~3
        nv = u32(data, pos)[0]
        pos += 4
        values = {}
        for _ in range(nv):
            pos = (pos + 3) & ~3
            n = u32(data, pos)[0]
            raw = data[pos + 4:pos + 3 + n]
            key = names.get(raw)
            if key is None:
                key = names[raw] = raw.decode()
            pos = (pos + 7 + n) & ~3
            n = u32(data, pos)[0]
            values[key] = data[pos + 4:pos + 3 + n].decode()
            pos += 4 + n                                # unaligned: a level octet may follow
        statuses.append((level, strs[0], strs[1], strs[2], values))
    if pos > len(data):
        raise ValueError('DiagnosticArray past the end of its message')
    return sec + nsec * 1e-9, statuses
