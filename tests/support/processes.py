"""Processes, found through /proc (not ps, whose output is cut to the terminal's width), the
:class:`Spawner` behind the ``spawn`` fixture, and the Fast DDS shared-memory segments a process maps."""
from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path


def _stat(pid: int) -> tuple[str, int] | None:
    """(state letter, parent pid) of ``pid``, or None if there is no such process."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except (OSError, IndexError):
        return None
    return fields[0], int(fields[1])


def cmdline(pid: int) -> str:
    """The full command line of ``pid`` ('' for a zombie or a process gone)."""
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            return f.read().replace(b'\0', b' ').decode(errors='replace').strip()
    except OSError:
        return ''


def children(pid: int) -> dict[int, str]:
    """The direct children of ``pid``: {child pid: command line}."""
    kids = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            stat = _stat(int(entry))
            if stat is not None and stat[1] == pid:
                kids[int(entry)] = cmdline(int(entry))
    return kids


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie whose parent has not reaped it yet is gone for our purpose)."""
    stat = _stat(pid)
    return stat is not None and stat[0] not in 'ZX'


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (children, their children, ...)."""
    found, todo = set(), [pid]
    while todo:
        for child in children(todo.pop()):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def kill_tree(proc: subprocess.Popen) -> None:
    """SIGKILL ``proc``'s process group and every process below it, and reap ``proc``."""
    targets = descendants(proc.pid)
    for pgid in {proc.pid, *targets}:
        try:
            os.killpg(pgid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    for pid in targets:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait()


class Spawner:
    """``spawn(args, **popen_kwargs)``: a process in a session of its own. ``spawn.adopt(pids)``
    adds processes seen below it (they may outlive it). :meth:`cleanup` kills them all."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen] = []
        self.adopted: set[int] = set()

    def __call__(self, args, **kwargs) -> subprocess.Popen:
        kwargs.setdefault('start_new_session', True)
        proc = subprocess.Popen(args, **kwargs)
        self.procs.append(proc)
        return proc

    def adopt(self, pids) -> None:
        self.adopted |= set(pids)

    def cleanup(self) -> None:
        for pid in self.adopted:
            if alive(pid):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for proc in self.procs:
            kill_tree(proc)


def shm_segments(pid: int | str) -> set[Path]:
    """Fast DDS shared-memory segment files (not the shared port files) mapped by a process."""
    try:
        maps = Path(f'/proc/{pid}/maps').read_text()
    except OSError:
        return set()
    out = set()
    for line in maps.splitlines():
        parts = line.split(None, 5)
        if len(parts) == 6 and parts[5].startswith('/dev/shm/fastrtps_') \
                and not parts[5].startswith('/dev/shm/fastrtps_port'):
            out.add(Path(parts[5].removesuffix(' (deleted)')))
    return out
