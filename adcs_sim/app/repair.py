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
no intact message, a fault that no CRC locates): one line per failure on stderr, the bag left
as it was.
"""
from __future__ import annotations

import argparse
import sys

from adcs_sim.bag.repair import repair


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='adcs-bag-repair', description=__doc__.splitlines()[0])
    parser.add_argument('bags', nargs='+', help='bag folder(s) (or their .mcap file)')
    parser.add_argument('--force', action='store_true', help='rewrite a bag even if it is complete')
    args = parser.parse_args(argv)
    status = 0
    for path in args.bags:
        try:
            result = repair(path, force=args.force)
        except (OSError, ValueError) as exc:
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
