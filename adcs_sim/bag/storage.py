"""Where the storage of a bag is and what it is: MCAP files or other rosbag2 storage (sqlite3).

:func:`bag_files` tells an MCAP bag (read by this package) from other rosbag2 storage (read with
rosbags' ``AnyReader`` through :class:`any_reader`); :func:`typestore` is the ROS 2 Jazzy type
store (message definitions, CDR (de)serialisation) every module of the package shares.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from adcs_msgs_py.params_file import YamlError, load_yaml
from adcs_msgs_py.typestore import typestore  # noqa: F401 - the bag code's, shared with the CDR codec

# rosbags' type store and AnyReader are imported when first used (typestore(), any_reader): the
# highlevel reader alone took ~0.1-0.5 s to import, in every process that writes or reads a bag
# (the recorder node, adcs-run), most of which never read a non-MCAP bag.

MCAP_MAGIC = b'\x89MCAP0\r\n'
SQLITE_MAGIC = b'SQLite format 3\x00'


def mcap_file(bag: str | os.PathLike) -> Path:
    """The ``.mcap`` file of a bag folder (or the file itself)."""
    path = Path(bag)
    if path.is_dir():
        files = sorted(path.glob('*.mcap'))
        if not files:
            raise FileNotFoundError(f'no .mcap file in bag folder {path}')
        return files[0]
    return path



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
        info = load_yaml(folder / 'metadata.yaml')['rosbag2_bagfile_information']
        return [str(x) for x in info.get('relative_file_paths') or []]
    except (KeyError, TypeError, AttributeError, YamlError):
        return []


class any_reader:
    """rosbags' AnyReader on a rosbag2 folder, its errors turned into one-line ValueErrors."""

    def __init__(self, bag, folder: Path) -> None:
        self.bag, self.folder = bag, folder
        self.reader = None

    def __enter__(self):
        from rosbags.highlevel import AnyReader
        try:   # rosbags reads metadata.yaml itself (ruamel): within every YAML reader's limits first
            load_yaml(Path(self.folder) / 'metadata.yaml')
        except YamlError as exc:
            raise ValueError(f'{self.bag}: cannot read bag: {exc}') from None
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


