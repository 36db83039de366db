"""``adcs-bag-repair <bag> [<bag> ...]``: make the bag of a killed recorder complete again.

A recorder killed with SIGKILL leaves an MCAP file without summary or index and no
``metadata.yaml``; ``adcs-analyze`` reads it as it is, but other tools (rosbags' ``AnyReader``,
``ros2 bag info``) need a complete bag. This rewrites every whole record of the truncated file
into a complete one in place (:func:`adcs_sim.bag.repair.repair`) and keeps the original beside it as
``<name>.mcap.truncated``. A complete bag is left alone (``--force`` rewrites it anyway).
Exit status 0 when every bag is complete afterwards, 1 otherwise (one line per failure on stderr).
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
            print(f'adcs-bag-repair: {path}: {exc}', file=sys.stderr)
            status = 1
            continue
        if result.status == 'complete':
            print(f'{result.bag}: already complete, left alone')
        else:
            print(f'{result.bag}: repaired, {result.messages} messages '
                  f'(original kept as {result.kept.name})')
    return status


if __name__ == '__main__':
    raise SystemExit(main())
