"""Reading the messages and metadata of any rosbag2 bag, one message at a time (no ROS needed).

MCAP files (ours, ``ros2 bag record``, rosbags' writer; complete or truncated) are read with the
``mcap`` library; other storage (sqlite3 ``.db3``) goes through rosbags' ``AnyReader``.
:func:`read_raw` yields (topic, type, log time, CDR bytes), :func:`read_messages` deserialised
messages, :func:`read_metadata` the MCAP metadata records (e.g. the embedded scenario);
:func:`is_complete` tells a closed bag from one whose writer was killed.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcap.reader import NonSeekingReader, make_reader

from adcs_sim.bag.storage import any_reader, bag_files, mcap_file, typestore


def is_complete(bag: str | os.PathLike) -> bool:
    """Whether a bag folder's MCAP file has its summary and the folder its ``metadata.yaml``."""
    path = Path(bag)
    folder = path if path.is_dir() else path.parent
    with open(mcap_file(bag), 'rb') as f:
        _, complete = _open_reader(f)
    return complete and (folder / 'metadata.yaml').exists()



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
        with any_reader(bag, files[0]) as reader:
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


