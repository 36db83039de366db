"""Output paths of every kind for the edge tests (tests/test_edge_*.py): a FIFO, a
folder that refuses writes even to root, a file, a missing parent; a tiny campaign.

The tests run as root in CI, where ``chmod 0o555`` stops nothing (``os.access`` says writable):
a read-only folder is then made immutable (``FS_IMMUTABLE_FL``, what ``chattr +i`` sets; root
cannot create a file in it either), and ``chmod`` elsewhere. The flag is cleared on exit.
"""
from __future__ import annotations

import array
import contextlib
import fcntl
import os
from pathlib import Path

import pytest
import yaml

from support.scenarios import make_scenario

FS_IOC_GETFLAGS, FS_IOC_SETFLAGS, FS_IMMUTABLE_FL = 0x80086601, 0x40086602, 0x10


def _set_immutable(folder: Path, on: bool) -> None:
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        flags = array.array('l', [0])
        fcntl.ioctl(fd, FS_IOC_GETFLAGS, flags, True)
        flags[0] = flags[0] | FS_IMMUTABLE_FL if on else flags[0] & ~FS_IMMUTABLE_FL
        fcntl.ioctl(fd, FS_IOC_SETFLAGS, flags, True)
    finally:
        os.close(fd)


@contextlib.contextmanager
def read_only(folder: Path):
    """``folder`` (created if absent) refuses every new file, root included, inside the block."""
    folder.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            yield folder
        finally:
            folder.chmod(0o755)
        return
    try:
        _set_immutable(folder, True)
    except OSError as exc:   # a file system without the flag: nothing here refuses root
        pytest.skip(f'cannot make a read-only folder as root here: {exc}')
    try:
        yield folder
    finally:
        _set_immutable(folder, False)


def fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def one_line(err: str, *names) -> str:
    """The one error line of ``err``, checked: no traceback, and every one of ``names`` in it."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and 'Traceback' not in err, err
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


def tiny_campaign(folder: Path, duration: float, seed: int, runs: int = 3) -> Path:
    """A campaign file in ``folder`` (created): ``runs`` PD runs of ``duration`` s, kd dispersed."""
    folder.mkdir(parents=True, exist_ok=True)
    scenario = make_scenario(folder, {'dynamics': {'duration': duration}})
    path = folder / 'campaign.yaml'
    path.write_text(yaml.safe_dump({'campaign': {
        'scenario': str(scenario), 'runs': runs, 'seed': seed, 'chunk_size': runs,
        'dispersions': {'pd_controller.kd': {'distribution': 'uniform', 'plus_minus': 0.01}}}}))
    return path
