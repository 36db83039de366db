"""``adcs-bag-repair <bag> [<bag> ...]``: make the bag of a killed recorder, or a damaged bag, complete again.

A recorder killed with SIGKILL leaves an MCAP file without summary or index and no
``metadata.yaml``; a disk or a copy can damage a file anywhere. ``adcs-analyze`` reads such a
bag as it is (with a warning), but other tools (rosbags' ``AnyReader``, ``ros2 bag info``) need a
complete bag. This rewrites every intact record (all those before the truncation or the first
fault a CRC or a bounds check finds) into a complete file in place
(:func:`adcs_sim.bag.repair.repair`) and keeps the original beside it (``<name>.mcap.truncated``
or ``.original``). It prints what it kept and dropped: messages, the byte offset of the damage.
A complete, intact bag is left alone (``--force`` rewrites it anyway).

Exit status 0 when every bag is complete afterwards; 1 when a bag cannot be repaired (not a bag,
no intact message, a fault that no CRC locates, a FIFO, socket or device, a folder where the
repaired file cannot be written, a bag still being written: its writer named): one line per failure
on stderr, the bag left as it was.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from adcs_msgs_py.help_text import command_parser
from adcs_sim.app.outputs import OutputError, path_kind, writable_folder
from adcs_sim.bag.repair import repair


def check_bag_path(path: str) -> None:
    """What a repair rewrites in place is usable, before the bag is opened: a folder or a regular
    file (a FIFO would block the reader, a device is no bag), in a folder where the repaired file
    and the kept original can be created (probed: root too). OutputError (one line) otherwise;
    a missing path is left to :func:`repair`, which names it."""
    kind = path_kind(Path(path))
    if kind == 'absent':
        return
    if kind not in ('folder', 'file'):
        raise OutputError(path, f'{kind}, not a bag')
    folder = Path(path) if kind == 'folder' else Path(os.path.abspath(path)).parent
    why = writable_folder(folder)
    if why is not None:
        raise OutputError(path, f'cannot be repaired in place: {why}')


def main(argv=None) -> int:
    parser = command_parser('adcs-bag-repair', __doc__)
    parser.add_argument('bags', nargs='+', help='bag folder(s) (or their .mcap file)')
    parser.add_argument('--force', action='store_true', help='rewrite a bag even if it is complete')
    args = parser.parse_args(argv)
    status = 0
    for path in args.bags:
        try:
            check_bag_path(path)
            result = repair(path, force=args.force)
        except (OSError, ValueError) as exc:   # (OutputError is a ValueError)
            print(f'adcs-bag-repair: {path}: {_one_line(exc, path)}', file=sys.stderr)
            status = 1
            continue
        print(result.summary())
    return status


def _one_line(exc: Exception, path: str) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[len(path) + 2:] if text.startswith(f'{path}: ') else text


if __name__ == '__main__':
    raise SystemExit(main())
