"""Repairing a bag whose writer was killed, or whose file is damaged: :func:`repair`.

The intact part of the MCAP file (every record before the first fault that
:class:`~adcs_sim.bag.records.McapRecords` finds, or before the truncation) is rewritten into a
complete bag; :class:`RepairResult` says exactly what was kept and what was dropped. A bag that
is closed and passes every check is left alone; one with no intact message, or whose fault no
CRC locates, is refused (:class:`~adcs_sim.bag.records.BagDamaged`) and left as it is, and so is a
bag still being written (:mod:`adcs_sim.bag.lock`).
"""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from adcs_msgs_py.params_file import YamlError, parse_yaml
from adcs_sim.bag.lock import BagInUse, BagLock, bag_writer
from adcs_sim.bag.reader import McapContents, is_complete, mcap_contents
from adcs_sim.bag.records import BagDamaged
from adcs_sim.bag.storage import bag_files
from adcs_sim.bag.writer import BagWriter

TRUNCATED_SUFFIX = '.truncated'   # the original of a truncated file, kept beside the repaired one
ORIGINAL_SUFFIX = '.original'     # the original of a damaged file (or one rewritten for another reason)
REPAIRER = 'adcs-bag-repair'      # the writer a repair's lock names


@dataclass
class RepairResult:
    bag: Path
    status: str                 # 'repaired' or 'complete' (nothing to do)
    messages: int = 0           # messages in the bag now (all of them for 'complete')
    kept: Path | None = None    # the original file, kept beside the repaired one
    problem: str = ''           # what was wrong (truncation / damage with its byte offset, ...)
    intact_bytes: int = 0       # the original's records before this byte were kept
    dropped_bytes: int = 0      # bytes of the original after them (the truncated or damaged tail)
    dropped_messages: int = 0   # intact messages left out (channel without a schema)

    def summary(self) -> str:
        """One line for the user."""
        if self.status == 'complete':
            return f'{self.bag}: complete, nothing to repair ({self.messages} messages)'
        left = f', {self.dropped_messages} messages of channels without schema left out' \
            if self.dropped_messages else ''
        return (f'{self.bag}: repaired ({self.problem}): kept {self.messages} messages, every record before '
                f'byte {self.intact_bytes}; dropped the {self.dropped_bytes} bytes after it{left} '
                f'(original kept as {self.kept.name})')


def repair(bag: str | os.PathLike, force: bool = False) -> RepairResult:
    """Rewrite the intact part of a bag's MCAP file into a complete rosbag2 bag, in place.

    Every intact record is kept (schemas, channels with their offered QoS, the embedded metadata
    such as the scenario, every message with its log time); the new file has a summary and
    index, and ``metadata.yaml`` is written (format 9, ``custom_data`` notes the repair). The
    original is kept beside it (``<name>.mcap.truncated``, or ``.original`` for a damaged file)
    so nothing is lost if the repair itself is interrupted. A complete, intact bag is left alone
    unless ``force``. Raises FileNotFoundError / ValueError for what is not an MCAP bag,
    :class:`BagDamaged` (a ValueError) when nothing can be salvaged truthfully, and
    :class:`~adcs_sim.bag.lock.BagInUse` naming the writer of a bag still being written (rewritten
    under it, the bag would become a prefix of the run and the rest go to the kept original); the
    lock a killed writer left is taken over, and held while the bag is rewritten.
    """
    path = Path(bag)
    kind, files = bag_files(path)
    if kind != 'mcap' or len(files) != 1:
        raise ValueError(f'{path}: repair handles a one-file MCAP bag (found {kind}, {len(files)} file(s))')
    src = files[0]
    folder = path if path.is_dir() else path.parent
    writer = bag_writer(folder)
    if writer is not None:   # refused before reading it
        raise BagInUse(path, writer, 'nothing repaired (stop it, or let it close the bag, first)')
    read = _identity(src)
    contents = mcap_contents(src)
    records = contents.records
    if not force and records.complete and is_complete(folder):
        return RepairResult(folder, 'complete', contents.count)
    damage = records.damage
    if damage is not None and not damage.located:
        raise BagDamaged(f'{src}: {damage}: which records are intact is unknown; nothing repaired')
    problem = records.problem() or ('metadata.yaml missing or unreadable' if not is_complete(folder)
                                    else 'rewritten on request (--force)')
    with BagLock(folder, REPAIRER):   # one writer at a time: BagInUse if another started since
        if _identity(src) != read:
            raise ValueError(f'{src}: changed while it was read (another writer?); nothing repaired')
        written, kept = _replace(contents, src, folder, problem)
    return RepairResult(folder, 'repaired', written, kept, problem, records.end,
                        records.size - records.end, contents.count - written)


def _identity(path: Path) -> tuple[int, int, int]:
    st = os.stat(path)
    return st.st_ino, st.st_size, st.st_mtime_ns


def _replace(contents: McapContents, src: Path, folder: Path, problem: str) -> tuple[int, Path]:
    """Write the intact records of ``src`` into a folder beside the bag, then move the new file and
    ``metadata.yaml`` into the bag, the original kept; (messages written, where the original is)."""
    records = contents.records
    tmp = folder.parent / f'.{folder.name}.repair-{os.getpid()}'
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        written = _rewrite(contents, tmp, src.name, problem)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)   # its own, half written (a full disk, an interrupt)
        raise
    if written == 0:
        shutil.rmtree(tmp)
        raise BagDamaged(f'{src}: {problem}: no intact message to salvage ({records.end} bytes intact); '
                         f'nothing repaired')
    suffix = TRUNCATED_SUFFIX if records.truncated else ORIGINAL_SUFFIX
    kept, n = src.with_name(src.name + suffix), 1
    while kept.exists():                                    # an earlier original is never overwritten
        kept, n = src.with_name(f'{src.name}{suffix}.{n}'), n + 1
    os.replace(src, kept)                                   # the original, kept
    os.replace(tmp / src.name, src)                         # the complete file
    os.replace(tmp / 'metadata.yaml', folder / 'metadata.yaml')
    tmp.rmdir()
    return written, kept


def _offered_qos(text: str, topic: str) -> list:
    """A channel's ``offered_qos_profiles`` (YAML within every YAML reader's limits); [] when it
    is not a list of profiles (the topic is still rewritten, with no QoS stated)."""
    try:
        qos = parse_yaml(text, f'the QoS profiles of {topic}') or []
    except YamlError:
        return []
    return qos if isinstance(qos, list) else []


def _rewrite(contents: McapContents, tmp: Path, file_name: str, problem: str) -> int:
    """Write the intact records into a new bag folder ``tmp``; the number of messages written."""
    writer = BagWriter(tmp, metadata={name: values.get('text', '') for name, values in contents.metadata
                                      if name != 'rosbag2' and 'text' in values},
                       file_name=file_name, process=REPAIRER)
    names = {}
    for cid, (sid, topic, meta) in contents.channels.items():
        schema = contents.schemas.get(sid)
        if schema is None:
            continue
        qos = _offered_qos(meta.get('offered_qos_profiles', ''), topic)
        writer.add_topic(topic, schema[0], qos, (schema[1], schema[2]))
        names[cid] = topic
    written = 0
    for cid, log_time, data in contents.messages:
        if cid in names:
            writer.write(names[cid], data, log_time_ns=log_time)
            written += 1
    writer.close({'repaired_by': 'adcs-bag-repair', 'repaired_from': file_name, 'repaired_problem': problem,
                  'repaired_messages': str(written)})
    return written
