"""Repairing a bag whose writer was killed: :func:`repair` rewrites it into a complete bag."""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import yaml
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from adcs_sim.bag.reader import is_complete
from adcs_sim.bag.storage import bag_files
from adcs_sim.bag.writer import BagWriter

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


