"""``adcs-analyze <bag> [<bag> ...]``: the run metrics of recorded bags, and their reports.

The same numbers ``adcs-run`` prints at the end of a run; definitions in
:mod:`adcs_sim.app.analysis`. ``--json`` prints machine-readable output.

Each bag also gets a report (:mod:`adcs_sim.app.report`): ``report.md`` with the scenario, the
metrics and figures (PNG + SVG), written to ``--out DIR``, else to ``<bag>/../report/`` (a
``report`` folder beside the bag folder) when that folder is writable, else to
``<run>-report/`` in the current directory. ``--compare`` writes one comparison of all the bags
instead (``comparison.csv``, ``comparison.md``, overlaid figures) to ``--out DIR`` or
``comparison/`` in the current directory (never among the inputs: bags under ``bags/`` are the
repository's reference data); with ``--reference FILE`` (published figures per run, e.g.
``docs/seed004/paper.yaml``) it adds a published-vs-ours table with the differences.
``--no-report`` only prints the metrics.

A path that is not a readable bag gives a one-line error on stderr and exit status 1 (the other
bags are still analysed).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from adcs_sim.app.analysis import format_metrics, jsonable_metrics, run_metrics


def _report_dir(out: Path | None, path: str, name: str, several: bool) -> Path:
    from adcs_sim.app.report import default_report_dir
    if out is None:
        beside = default_report_dir(path)
        return beside if os.access(beside.parent, os.W_OK) else Path.cwd() / f'{name}-report'
    return out / name if several else out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='adcs-analyze', description=__doc__.splitlines()[0])
    parser.add_argument('bags', nargs='+', help='bag folder(s) or .mcap file(s)')
    parser.add_argument('--tolerance-deg', type=float, default=0.5,
                        help='settling band on the 2-1-3 Euler angles (deg; default 0.5, seed 004)')
    parser.add_argument('--eigen-tolerance-deg', type=float, default=None,
                        help='settling band on the eigenaxis error (deg; default: --tolerance-deg)')
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    parser.add_argument('--out', type=Path, default=None,
                        help='report folder (default <bag>/../report; with several bags, one sub-folder '
                             'per run; with --compare, the comparison folder)')
    parser.add_argument('--compare', action='store_true',
                        help='write one comparison of all the bags (CSV, Markdown, overlaid figures)')
    parser.add_argument('--reference', type=Path, default=None,
                        help='with --compare: a YAML of published figures per run (e.g. a paper\'s), '
                             'added to the comparison with the relative differences')
    parser.add_argument('--no-report', action='store_true', help='only print the metrics')
    args = parser.parse_args(argv)
    from adcs_sim.app.report import BagError, load_run  # matplotlib only after the arguments are parsed
    runs = {}
    status = 0
    for path in args.bags:
        try:
            runs[path] = load_run(path)
        except BagError as exc:
            print(f'adcs-analyze: {path}: {exc}', file=sys.stderr)
            status = 1
    results = {p: run_metrics(r.data, args.tolerance_deg, args.eigen_tolerance_deg) for p, r in runs.items()}
    if args.json:
        print(json.dumps({p: jsonable_metrics(m) for p, m in results.items()}, indent=2))
    else:
        for path, metrics in results.items():
            print(f'{path}:')
            print(format_metrics(metrics))
    if args.no_report or not runs:
        return status
    # Where the reports are goes to stdout with the table, to stderr with --json (stdout stays JSON).
    info = sys.stderr if args.json else sys.stdout
    from adcs_sim.app import report
    if args.compare:
        if len(runs) < 2:
            print('adcs-analyze: --compare needs at least two readable bags', file=sys.stderr)
            return 1
        out = args.out or Path.cwd() / 'comparison'
        try:
            reference = report.load_reference(args.reference) if args.reference else None
            csv_path, md_path = report.write_comparison(list(runs.values()), out, args.tolerance_deg,
                                                        args.eigen_tolerance_deg, reference)
        except ValueError as exc:
            print(f'adcs-analyze: --reference: {exc}', file=sys.stderr)
            return 2
        print(f'comparison: {md_path} ({csv_path.name})', file=info)
        return status
    for (path, run), name in zip(runs.items(), report.unique_names(list(runs.values()))):
        out = _report_dir(args.out, path, name, len(runs) > 1)
        md_path = report.write_report(run, out, args.tolerance_deg, args.eigen_tolerance_deg)
        print(f'report: {md_path}', file=info)
    return status


if __name__ == '__main__':
    raise SystemExit(main())
