"""Where a tool may write: every CLI's and the API's output paths, checked before any work (issue #31).

One checker for every tool (``adcs-run``, ``adcs-analyze``, ``adcs-montecarlo``, the layouts, the
API's graph runs), so that a run of minutes is never lost to an output that cannot be written, and
nothing that is not the tool's own is ever written over:

* :func:`check_folder`: a folder the tool creates or fills must be absent or an empty folder (or
  one the tool wrote itself, when asked to replace it: the tool's ``owned`` test decides, from the
  files it holds), writable, and neither inside one of the tool's inputs nor holding one;
* :func:`check_file`: a file the tool writes must be absent or a regular file the tool wrote
  itself (``owned``, from its content), in an existing writable folder, and not an input or
  inside one;
* :func:`fresh_folder`: a tool's default output folder, ``<parent>/<stem>-<date>-<time>``, numbered
  (``-2``, ``-3``...) when that name is taken: running a command twice never meets its first output.

Writability is probed by creating a file and removing it (``os.access`` says yes to root on a
folder that refuses every write, e.g. an immutable or read-only mounted one); the probe is made in
the folder itself, or in its nearest existing ancestor, whose whole chain must be folders.
Every refusal is an :class:`OutputError` whose message is one line: ``<path>: <why>``.
"""
from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Callable, Iterable
from datetime import datetime
from pathlib import Path

__all__ = ['OutputError', 'check_folder', 'check_file', 'fresh_folder', 'path_kind', 'writable_folder']

# The default parent of every tool's output (git-ignored in the repository).
RUNS = Path('runs')


class OutputError(ValueError):
    """An output path the tool must not or cannot write (one line: ``<path>: <why>``)."""

    def __init__(self, path, why: str):
        super().__init__(f'{path}: {why}')
        self.path, self.why = path, why


def _kind(mode: int) -> str:
    """What a non-folder, non-regular file is, for the message."""
    for test, name in ((stat.S_ISFIFO, 'a FIFO'), (stat.S_ISSOCK, 'a socket'), (stat.S_ISCHR, 'a character device'),
                       (stat.S_ISBLK, 'a block device')):
        if test(mode):
            return name
    return 'not a regular file'


def path_kind(path: Path) -> str:
    """``'absent'``, ``'folder'``, ``'file'`` (regular) or what else ``path`` is (``'is a FIFO'``,
    ``'is a symlink to a socket'``...), symlinks followed; OutputError if it cannot be examined."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        if os.path.lexists(path):
            raise OutputError(path, 'is a symlink to nothing') from None
        return 'absent'
    except NotADirectoryError:
        raise OutputError(path, 'a component of the path is not a folder') from None
    except OSError as exc:
        raise OutputError(path, f'cannot be examined: {exc.strerror or exc}') from None
    if stat.S_ISDIR(mode):
        return 'folder'
    if stat.S_ISREG(mode):
        return 'file'
    return f'is {"a symlink to " if path.is_symlink() else ""}{_kind(mode)}'


def _real(path) -> Path:
    return Path(os.path.realpath(path))


def _check_inputs(path: Path, inputs: Iterable, folder: bool) -> None:
    """Refused: ``path`` is an input, inside one, or (a folder) holds one."""
    real = _real(path)
    for given in inputs:
        if given is None:
            continue
        other = _real(given)
        if real == other:
            raise OutputError(path, f'is an input of this run ({given})')
        if real.is_relative_to(other):
            raise OutputError(path, f'is inside an input of this run ({given})')
        if folder and other.is_relative_to(real):
            raise OutputError(path, f'holds an input of this run ({given})')


def writable_folder(folder) -> str | None:
    """Why files cannot be created in ``folder`` (or in its nearest existing ancestor, where the
    missing part would be created), or None if they can: the chain must be folders, and a probe
    file is created and removed (works for root, unlike ``os.access``)."""
    folder = Path(os.path.abspath(folder))
    probe_in = folder
    while not probe_in.exists():
        if os.path.lexists(probe_in):
            return f'{probe_in} is a symlink to nothing'
        probe_in = probe_in.parent
    if not probe_in.is_dir():
        return f'{probe_in} is not a folder'
    if not os.access(probe_in, os.W_OK | os.X_OK):
        return f'{probe_in} is not writable'
    try:
        fd, name = tempfile.mkstemp(prefix='.adcs-probe-', dir=probe_in)
    except OSError as exc:
        return f'{probe_in} is not writable ({exc.strerror or exc})'
    os.close(fd)
    os.unlink(name)
    return None


def check_folder(path, inputs: Iterable = (), owned: Callable[[Path], bool] | None = None) -> bool:
    """Check an output folder before any work. Returns True when it exists with content the tool
    may replace (``owned(path)`` said it is the tool's own output), False when it is absent or empty.

    ``inputs``: the files and folders the tool reads (never written into, never inside the output);
    ``owned``: given only when the tool is asked to replace its own output (e.g. ``--overwrite``).
    """
    path = Path(path)
    what = path_kind(path)
    if what not in ('absent', 'folder', 'file'):
        raise OutputError(path, f'{what}, not a folder')
    if what == 'file':
        raise OutputError(path, 'is a file, not a folder')
    _check_inputs(path, inputs, folder=True)
    replace = False
    if what == 'folder':
        try:
            empty = next(os.scandir(path), None) is None
        except OSError as exc:
            raise OutputError(path, f'cannot be listed: {exc.strerror or exc}') from None
        if not empty:
            if owned is None:
                raise OutputError(path, 'exists and is not empty')
            try:
                ours = owned(path)
            except OSError as exc:
                raise OutputError(path, f'cannot be examined: {exc.strerror or exc}') from None
            if not ours:
                raise OutputError(path, 'exists and is not an output of this tool: not replaced')
            replace = True
    why = writable_folder(path)
    if why is not None:
        raise OutputError(path, why)
    return replace


def check_file(path, inputs: Iterable = (), owned: Callable[[Path], bool] | None = None) -> bool:
    """Check an output file before any work. Returns True when it exists and ``owned(path)`` says
    it is the tool's own (it may be replaced), False when it is absent. Its folder must exist."""
    path = Path(path)
    what = path_kind(path)
    if what == 'folder':
        raise OutputError(path, 'is a folder, not a file')
    if what not in ('absent', 'file'):
        raise OutputError(path, what)
    _check_inputs(path, inputs, folder=False)
    parent = Path(os.path.abspath(path)).parent
    if not parent.is_dir():
        raise OutputError(path, f'no such folder: {parent}')
    why = writable_folder(parent)
    if why is not None:
        raise OutputError(path, why)
    if what == 'absent':
        return False
    if owned is None or not owned(path):
        raise OutputError(path, 'exists and was not written by this tool: not overwritten')
    if not os.access(path, os.W_OK):
        raise OutputError(path, 'is not writable')
    return True


def fresh_folder(stem: str, parent=RUNS, now: datetime | None = None) -> Path:
    """A default output folder no earlier output holds: ``<parent>/<stem>-<YYYYmmdd-HHMMSS>``,
    or the first of ``...-2``, ``...-3``... that does not exist (the same command run twice in one
    second gets two folders). Nothing is created: the tool's own checks then see an absent folder."""
    base = Path(parent) / f'{stem}-{(now or datetime.now()):%Y%m%d-%H%M%S}'
    path, n = base, 1
    while os.path.lexists(path):
        n += 1
        path = base.with_name(f'{base.name}-{n}')
    return path
