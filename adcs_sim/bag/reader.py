"""Reading the messages and metadata of any rosbag2 bag, one message at a time (no ROS needed).

MCAP files (ours, ``ros2 bag record``, rosbags' writer; complete or truncated) are read record by
record through :class:`~adcs_sim.bag.records.McapRecords`, which checks every CRC the file has;
other storage (sqlite3 ``.db3``) goes through rosbags' ``AnyReader``. :func:`read_raw` yields
(topic, type, log time, CDR bytes), :func:`read_messages` deserialised messages,
:func:`read_metadata` the MCAP metadata records (e.g. the embedded scenario); :func:`is_complete`
tells a closed, intact bag from one whose writer was killed or whose file is damaged.

A truncated file (writer killed) yields everything before its last whole record and ends
quietly. A damaged one yields its intact part and then raises
:class:`~adcs_sim.bag.records.BagDamaged` naming the byte offset (and, for a fault that only a
section CRC reveals, refuses before trusting any of it: see :func:`mcap_contents`).
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from adcs_msgs_py.params_file import YamlError, load_yaml
from adcs_sim.bag.records import (
    CHANNEL,
    CHUNK,
    MESSAGE,
    METADATA,
    SCHEMA,
    BadRecord,
    BagDamaged,
    McapRecords,
    inner_records,
    parse_channel,
    parse_message,
    parse_metadata,
    parse_schema,
)
from adcs_sim.bag.storage import any_reader, bag_files, mcap_file, typestore


@dataclass
class McapContents:
    """Every intact record of one MCAP file: what :func:`mcap_contents` salvages."""

    records: McapRecords
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)      # id -> (name, encoding, data)
    channels: dict[int, tuple[int, str, dict]] = field(default_factory=dict)      # id -> (schema, topic, metadata)
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)          # (channel, log time, data)
    keep_messages: bool = True     # False: only count them (``count``)
    count: int = 0


def _records_of(records: McapRecords) -> Iterator[tuple[int, int, memoryview]]:
    """(offset of the top-level record, opcode, body) of every record, chunks opened."""
    for offset, op, body in records:
        if op != CHUNK:
            yield offset, op, memoryview(body)
            continue
        try:
            inner = list(inner_records(body))
        except BadRecord as exc:
            records.fail(offset, f'chunk: {exc}')
            return
        view = memoryview(body)
        for pos, op2, length in inner:
            yield offset, op2, view[pos + 9:pos + 9 + length]


def iter_contents(path: Path, out: McapContents) -> Iterator[tuple[str, str, int, bytes]]:
    """Fill ``out`` with the file's intact records; yields (topic, type, log time, data) per message."""
    records = out.records
    for offset, op, body in _records_of(records):
        try:
            if op == MESSAGE:
                cid, _, log_time, data = parse_message(body)
                channel = out.channels.get(cid)
                if channel is None:
                    raise BadRecord(f'a message on channel {cid}, which no channel record declares')
                out.count += 1
                if out.keep_messages:
                    out.messages.append((cid, log_time, data))
                yield channel[1], out.schemas.get(channel[0], ('', '', b''))[0], log_time, data
            elif op == SCHEMA:
                sid, name, encoding, data = parse_schema(body)
                out.schemas[sid] = (name, encoding, data)
            elif op == CHANNEL:
                cid, sid, topic, _, meta = parse_channel(body)
                out.channels[cid] = (sid, topic, meta)
            elif op == METADATA:
                out.metadata.append(parse_metadata(body))
        except BadRecord as exc:
            records.fail(offset, f'record 0x{op:02x}: {exc}')
            return
    records.check_count(out.count)


def mcap_contents(path: str | os.PathLike, keep_messages: bool = True) -> McapContents:
    """Everything intact in one MCAP file, read in full (its state in ``.records``)."""
    out = McapContents(McapRecords(Path(path)), keep_messages=keep_messages)
    for _ in iter_contents(Path(path), out):
        pass
    return out


def is_complete(bag: str | os.PathLike) -> bool:
    """Whether a bag folder's MCAP file is closed (summary, footer) and passes every check, and
    the folder's ``metadata.yaml`` describes it (lists the file, counts its messages)."""
    path = Path(bag)
    folder = path if path.is_dir() else path.parent
    mcap = mcap_file(bag)
    contents = mcap_contents(mcap, keep_messages=False)
    if not contents.records.complete:
        return False
    try:
        info = load_yaml(folder / 'metadata.yaml')['rosbag2_bagfile_information']
        return mcap.name in info['relative_file_paths'] and info['message_count'] == contents.count
    except (YamlError, KeyError, TypeError):
        return False


def read_raw(bag: str | os.PathLike) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type name, log time ns, CDR bytes) for every message, in file order.

    Works on a complete bag and on one whose writer was killed (everything up to the last
    complete record). A damaged file raises :class:`BagDamaged` after its intact part. A bag
    that is not MCAP (e.g. sqlite3) is read with rosbags' ``AnyReader`` (in log-time order).
    """
    kind, files = bag_files(bag)
    if kind == 'rosbag2':
        with any_reader(bag, files[0]) as reader:
            for conn, t, data in reader.messages():
                yield conn.topic, conn.msgtype, t, data
        return
    for path in files:
        out = McapContents(McapRecords(path), keep_messages=False)
        yield from iter_contents(path, out)
        _raise_on_damage(path, out)


def _raise_on_damage(path: Path, out: McapContents) -> None:
    damage = out.records.damage
    if damage is not None:
        raise BagDamaged(f'{path}: {damage} ({out.count} messages before it were read)')


def read_messages(bag: str | os.PathLike, topics: set[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """(topic, log time ns, deserialised message) with rosbags' type store, optionally filtered."""
    store = typestore()
    for topic, type_name, t, data in read_raw(bag):
        if topics is None or topic in topics:
            yield topic, t, store.deserialize_cdr(data, type_name)


def read_metadata(bag: str | os.PathLike) -> dict[str, str]:
    """MCAP metadata records of a bag (e.g. the embedded ``scenario`` file), also when truncated
    (those before the truncation or a located damage; a fault no CRC locates raises BagDamaged).

    Empty for a bag whose storage has no such records (sqlite3)."""
    kind, files = bag_files(bag)
    if kind != 'mcap':
        return {}
    found = {}
    for path in files:
        out = mcap_contents(path, keep_messages=False)
        if out.records.damage is not None and not out.records.damage.located:
            _raise_on_damage(path, out)
        found.update((name, values.get('text', '')) for name, values in out.metadata)
    return found
