"""``adcs-analyze <bag> [<bag> ...]``: the run metrics of recorded bags (read with rosbags/mcap).

The same numbers ``adcs-run`` prints at the end of a run; definitions in
:mod:`adcs_sim.analysis`. ``--json`` prints machine-readable output.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

from adcs_sim.analysis import RunData, format_metrics, run_metrics


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    return value


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='adcs-analyze', description=__doc__.splitlines()[0])
    parser.add_argument('bags', nargs='+', help='bag folder(s) or .mcap file(s)')
    parser.add_argument('--tolerance-deg', type=float, default=0.5,
                        help='settling band on the 2-1-3 Euler angles (deg; default 0.5, seed 004)')
    parser.add_argument('--eigen-tolerance-deg', type=float, default=None,
                        help='settling band on the eigenaxis error (deg; default: --tolerance-deg)')
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    args = parser.parse_args(argv)
    results = {}
    status = 0
    for path in args.bags:
        try:
            run = RunData.from_bag(path)
        except (OSError, ValueError) as exc:
            print(f'adcs-analyze: {path}: {exc}', file=sys.stderr)
            status = 1
            continue
        results[path] = run_metrics(run, args.tolerance_deg, args.eigen_tolerance_deg)
    if args.json:
        print(json.dumps({p: {k: _jsonable(v) for k, v in m.items()} for p, m in results.items()}, indent=2))
    else:
        for path, metrics in results.items():
            print(f'{path}:')
            print(format_metrics(metrics))
    return status


if __name__ == '__main__':
    raise SystemExit(main())
