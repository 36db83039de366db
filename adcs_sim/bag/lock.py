"""One writer at a time for a bag folder: :class:`BagLock`, :func:`bag_writer`, :class:`BagInUse`.

Whoever writes a bag folder (the recorder's :class:`~adcs_sim.bag.writer.BagWriter`,
``adcs-bag-repair`` while it rewrites one) holds an exclusive ``flock`` on ``<bag>/.writer.lock``
for as long as it writes, and the file says who that is (pid, host, process, since when). The
lock is the kernel's: it goes with its process, so the file a SIGKILLed recorder leaves blocks no
one (repair takes it over and removes it); a clean close removes it. Only a live writer makes
``adcs-bag-repair`` refuse (a bag rewritten under its writer became a prefix of the run while the
complete recording was renamed aside) and ``adcs-analyze`` say that it read a prefix.

The lock file is untrusted input: a symlink, FIFO or folder in its place is neither followed nor
waited on (``O_NOFOLLOW``, ``O_NONBLOCK``; taking the lock then fails with one line), and its record
is shown clipped to printable characters, or as an unknown writer.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import stat
import sys
from datetime import datetime, timezone
from pathlib import Path

LOCK_FILE = '.writer.lock'
_RECORD_MAX = 4096          # bytes of a lock file read to name its holder
_FIELD_MAX = 120            # characters of each field shown


class BagInUse(OSError):
    """A bag whose writer is alive: ``holder`` names it (``note``: what was not done, then)."""

    def __init__(self, bag: str | os.PathLike, holder: str, note: str = '') -> None:
        super().__init__(errno.EBUSY, f'{bag}: being written by {holder}' + (f'; {note}' if note else ''))
        self.holder = holder

    def __str__(self) -> str:
        return self.strerror


def _open(path: Path, flags: int) -> int:
    """A descriptor of the regular file ``path`` (OSError for anything else, a symlink included)."""
    fd = os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OSError(errno.EINVAL, f'{path}: not a regular file')
    return fd


def _holder(fd: int) -> str:
    """Who the lock file open on ``fd`` says holds it, in one printable line."""
    try:
        record = json.loads(os.pread(fd, _RECORD_MAX, 0))
        fields = [str(record[k])[:_FIELD_MAX] for k in ('process', 'pid', 'host', 'since')]
    except (OSError, ValueError, TypeError, KeyError):
        return 'a process that left no readable record'
    process, pid, host, since = (''.join(c if c.isprintable() else '?' for c in f) for f in fields)
    return f'{process} (pid {pid} on {host}, writing since {since})'


def _same_file(fd: int, path: Path) -> bool:
    try:
        now = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (held.st_dev, held.st_ino) == (now.st_dev, now.st_ino)


class BagLock:
    """The exclusive writer lock of bag folder ``folder``, held from construction to :meth:`release`,
    recording ``process`` (default: this program's name). Raises :class:`BagInUse` naming a live
    holder, or OSError when the lock file cannot be made."""

    def __init__(self, folder: str | os.PathLike, process: str | None = None) -> None:
        self.path = Path(folder) / LOCK_FILE
        while True:
            fd = _open(self.path, os.O_RDWR | os.O_CREAT)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise BagInUse(folder, holder) from None
            except OSError:
                os.close(fd)
                raise
            if _same_file(fd, self.path):
                break
            os.close(fd)   # its holder removed it between our open and our lock: lock the one there now
        record = {'process': process or Path(sys.argv[0]).name or 'python', 'pid': os.getpid(),
                  'host': socket.gethostname(), 'since': datetime.now(timezone.utc).isoformat(timespec='seconds')}
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(record).encode(), 0)
        except OSError:
            self.fd = fd
            self.release()
            raise
        self.fd: int | None = fd

    def release(self) -> None:
        """Remove the lock file (still holding it: no one can lock it as it goes) and let go. Idempotent."""
        if self.fd is None:
            return
        try:
            if _same_file(self.fd, self.path):
                self.path.unlink()
        finally:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> BagLock:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def bag_writer(bag: str | os.PathLike) -> str | None:
    """Who is writing bag ``bag`` (a bag folder, or a file in one) now, or None: no live process
    holds its lock (none ever did, or it closed the bag, or it died)."""
    path = Path(bag)
    folder = path if path.is_dir() else path.parent
    try:
        fd = _open(folder / LOCK_FILE, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _holder(fd)
    except OSError:
        return None
    finally:
        os.close(fd)   # (a shared lock taken here goes with it)
    return None
