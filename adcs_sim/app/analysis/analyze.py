"""``adcs-analyze <bag> [<bag> ...]``: print the run metrics of recorded bags and write their reports
(or one comparison of them all, or a viewer layout).

The same numbers ``adcs-run`` prints at the end of a run; definitions in
:mod:`adcs_sim.app.analysis.metrics`. ``--json`` prints machine-readable output.

Each bag also gets a report (:mod:`adcs_sim.app.report`): ``report.md`` with the scenario, the
metrics and figures (PNG + SVG), written to ``--out DIR``, else to ``<bag>/../report/`` (a
``report`` folder beside the bag folder) when that folder is writable, else to
``<run>-report/`` in the current directory. ``--compare`` writes one comparison of all the bags
instead (``comparison.csv``, ``comparison.md``, overlaid figures) to ``--out DIR``, default a
new folder ``runs/comparison-<date>-<time>`` (numbered if taken: never an earlier comparison, never
among the inputs: bags under ``bags/`` are the repository's reference data). Every output folder is
checked before any bag is read (:mod:`adcs_sim.app.outputs`): absent, empty, or a report of this
tool (only ``report.md`` / ``comparison.md`` with its CSV and figures: replaced whole, so no figure
of an older report stays), writable, not a file or a FIFO, neither inside an input nor holding one. With ``--reference FILE``
(published figures per run, e.g. ``docs/seed004/paper.yaml``) the comparison adds a published-vs-ours
table with the differences (one bag is enough then: a paper with one run, seed 002). The published
figures are comparison rows or the metrics a run's report leads with for its kind (e.g. seed 000's
q4 settling after the fault).
``--no-report`` only prints the metrics. ``--foxglove-layout OUT.json`` and / or
``--plotjuggler-layout OUT.xml`` write the viewer layouts of one bag instead (no metrics, no
report; :mod:`adcs_sim.app.graph.layouts`): 3D view, attitude error, rates, wheels, torques, controller
mode, from the topics the bag has (the panels left out are named on stderr).

A path that is not a readable bag gives a one-line error on stderr and exit status 1 (the other
bags are still analysed). A damaged bag (a CRC or bounds check fails; every check is in
:mod:`adcs_sim.bag.records`) is analysed up to the damage with a one-line warning on stderr naming
the byte offset and what was read, or refused with a one-line error when nothing before the
damage can be analysed or the damage cannot be located. So is a truncated one (writer killed), and
one still being written (the warning then names its writer: :mod:`adcs_sim.bag.lock`).
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from types import SimpleNamespace

from adcs_msgs_py.help_text import command_parser
from adcs_msgs_py.params_file import one_line_warnings
from adcs_sim.app.analysis.metrics import format_metrics, jsonable_metrics
from adcs_sim.app.graph.layouts import LayoutError, write_layouts
from adcs_sim.app.outputs import OutputError, check_folder, fresh_folder, writable_folder
from adcs_sim.app.report.kinds import run_kind
from adcs_sim.app.report.loading import BagError, bag_folder, default_report_dir, load_run, run_name
from adcs_sim.bag.lock import bag_writer


REPORT_FILES = ('.md', '.png', '.svg', '.csv')   # what a report or a comparison folder holds


def is_report(folder: Path) -> bool:
    """A report or comparison this tool wrote: ``report.md`` or ``comparison.md``, and only
    Markdown, CSV and figure files beside it (no sub-folder, no symlink, nothing else)."""
    entries = list(folder.iterdir())
    return (any(e.name in ('report.md', 'comparison.md') for e in entries)
            and all(e.is_file() and not e.is_symlink() and e.suffix in REPORT_FILES for e in entries))


def _inputs(args) -> list[Path]:
    """What the tool reads: each bag's folder (or file) and the reference file."""
    found = [bag_folder(p) or Path(p) for p in args.bags]
    return found + ([args.reference] if args.reference is not None else [])


def _report_dir(out: Path | None, path: str, name: str, several: bool) -> Path:
    if out is None:
        beside = default_report_dir(path)
        return beside if writable_folder(beside.parent) is None else Path.cwd() / f'{name}-report'
    return out / name if several else out


def _report_dirs(args) -> dict[str, Path]:
    """Each bag's report folder (``--compare``: the one comparison folder, under every bag),
    checked before any bag is read; OutputError names the first unusable one."""
    # lazy: the report modules bring matplotlib (1.3 s): only when a report is written
    from adcs_sim.app.report.comparison import unique_names   # (matplotlib: only when a report is written)
    named = [SimpleNamespace(name=run_name(p), path=p) for p in args.bags]
    if args.compare:
        dirs = dict.fromkeys(args.bags, args.out if args.out is not None else fresh_folder('comparison'))
    else:
        dirs = {p: _report_dir(args.out, p, name, len(args.bags) > 1)
                for p, name in zip(args.bags, unique_names(named))}
    for folder in dict.fromkeys(dirs.values()):
        check_folder(folder, _inputs(args), owned=is_report)
    return dirs


def _old_report(folder: Path) -> list[Path]:
    """The files of the report in ``folder``: its Markdown, the comparison table and every figure
    or table the Markdown links (a file the report does not name is not the tool's: it stays)."""
    texts = [folder / n for n in ('report.md', 'comparison.md') if (folder / n).is_file()]
    named = set(re.findall(r'\(([^()\s/]+\.(?:png|svg|csv))\)', ''.join(p.read_text(errors='replace') for p in texts)))
    return texts + [folder / n for n in sorted(named | {'comparison.csv'}) if (folder / n).is_file()]


def _replace(folder: Path) -> Path:
    """Remove the report of ours in ``folder`` just before its new report is written (not before:
    a bag that does not load leaves the old report as it was), so no figure of the old one stays."""
    if folder.is_dir() and is_report(folder):
        for entry in _old_report(folder):
            entry.unlink()
    return folder


def _load(paths: list[str], args) -> tuple[dict, int]:
    """The runs that load ({path: Run}) and the exit status; one line on stderr per failure or warning.
    A long run is streamed (its report never holds the whole run) unless the runs are compared."""
    runs = {}
    status = 0
    for path in paths:
        writer = bag_writer(path)   # looked at first: what a live writer has flushed is a prefix of its run
        try:
            runs[path] = run = load_run(path, tol_deg=args.tolerance_deg, eigen_tol_deg=args.eigen_tolerance_deg,
                                        stream=not args.compare)
        except BagError as exc:
            print(f'adcs-analyze: {path}: {exc}', file=sys.stderr)
            status = 1
            continue
        if run.data.problem is not None:
            problem = run.data.problem if writer is None else f'still being written by {writer}'
            print(f'adcs-analyze: warning: {path}: {problem}; analysed the {run.message_count} '
                  f'messages read (up to t = {run.data.t_end:.6g} s)', file=sys.stderr)
        if len(run.data.t) and run.data.t[0] > 0:   # every run's first state is stamped 0
            print(f'adcs-analyze: warning: {path}: the recording starts at t = {run.data.t[0]:.6g} s, not at '
                  'the run\'s start (t = 0): the metrics cover what was recorded', file=sys.stderr)
    return runs, status


def _warn_compromised(runs: dict) -> int:
    """A compromised run's numbers are not the run's alone (its bag has ``intrusions``): said on
    stderr, and exit status 1. ``runs``: {path: loaded run}."""
    lines = [f'adcs-analyze: {path}: WARNING: run compromised: {line}' for path, run in runs.items()
             for line in run.data.intrusions]
    for line in lines:
        print(line, file=sys.stderr)
    return 1 if lines else 0


def _layouts(args) -> int:
    """``--foxglove-layout`` / ``--plotjuggler-layout``: the layouts of one bag, exit status."""
    if len(args.bags) != 1:
        print('adcs-analyze: --foxglove-layout / --plotjuggler-layout take exactly one bag', file=sys.stderr)
        return 2
    try:
        layout = write_layouts(args.bags[0], args.foxglove_layout, args.plotjuggler_layout,
                               inputs=_inputs(args))
    except LayoutError as exc:
        print(f'adcs-analyze: {exc}', file=sys.stderr)
        return 1
    for what in layout.left_out:
        print(f'adcs-analyze: note: left out: {what}', file=sys.stderr)
    for name, path in (('foxglove', args.foxglove_layout), ('plotjuggler', args.plotjuggler_layout)):
        if path is not None:
            print(f'{name} layout ({layout.kind}): {path}')
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = command_parser('adcs-analyze', __doc__)
    parser.add_argument('bags', nargs='+', help='bag folder(s) or .mcap file(s)')
    parser.add_argument('--tolerance-deg', type=float, default=0.5,
                        help='settling band on the 2-1-3 Euler angles (deg; default 0.5)')
    parser.add_argument('--eigen-tolerance-deg', type=float, default=None,
                        help='settling band on the eigenaxis error (deg; default: --tolerance-deg)')
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    parser.add_argument('--out', type=Path, default=None,
                        help='report folder (default <bag>/../report; with several bags, one sub-folder '
                             'per run; with --compare, the comparison folder, default a new '
                             'runs/comparison-<time>): absent, empty or a report of this tool (replaced)')
    parser.add_argument('--compare', action='store_true',
                        help='write one comparison of all the bags (CSV, Markdown, overlaid figures)')
    parser.add_argument('--reference', type=Path, default=None,
                        help='with --compare: a YAML of published figures per run (e.g. a paper\'s), '
                             'added to the comparison with the relative differences (one bag is enough)')
    parser.add_argument('--no-report', action='store_true', help='only print the metrics')
    parser.add_argument('--foxglove-layout', type=Path, default=None, metavar='OUT.json',
                        help="write a Foxglove layout for the bag's topics (3D view, errors, rates, wheels, "
                             'torques, mode) and exit')
    parser.add_argument('--plotjuggler-layout', type=Path, default=None, metavar='OUT.xml',
                        help='write a PlotJuggler layout for the bag (the same plots) and exit')
    return parser


def _print_table(runs: dict, results: dict) -> None:
    """The metrics of each bag, with the kind of run it is (adcs_sim.app.report.kinds)."""
    for path, metrics in results.items():
        kind = run_kind(runs[path].data.scenario)
        print(f'{path}: a {kind.kind} run ({kind.why})')
        if kind.kind in ('spin', 'pointing'):
            print(f'  (the rest-to-rest metrics below measure the attitude against a fixed target: not '
                  f'meaningful for a {kind.kind} run; the report leads with its own)')
        print(format_metrics(metrics))


@one_line_warnings('adcs-analyze')   # a section written twice, named once per line
def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.foxglove_layout is not None or args.plotjuggler_layout is not None:
        return _layouts(args)
    if args.compare and len(args.bags) < (1 if args.reference else 2):
        print('adcs-analyze: --compare needs at least two readable bags (one with --reference)', file=sys.stderr)
        return 1
    try:
        dirs = {} if args.no_report else _report_dirs(args)
    except OutputError as exc:
        print(f'adcs-analyze: {"--out " if args.out is not None else ""}{exc}', file=sys.stderr)
        return 2
    runs, status = _load(args.bags, args)
    results = {p: r.metrics(args.tolerance_deg, args.eigen_tolerance_deg) for p, r in runs.items()}
    status = max(status, _warn_compromised(runs))
    if args.json:
        print(json.dumps({p: jsonable_metrics(m) for p, m in results.items()}, indent=2))
    else:
        _print_table(runs, results)
    if args.no_report or not runs:
        return status
    # Where the reports are goes to stdout with the table, to stderr with --json (stdout stays JSON).
    info = sys.stderr if args.json else sys.stdout
    # matplotlib (behind the figures) only when a report is written: --help and --no-report stay quick
    # lazy: matplotlib (1.3 s) behind the figures: only when a report is written
    from adcs_sim.app.report import comparison, single_run
    if args.compare:
        if len(runs) < (1 if args.reference else 2):
            print('adcs-analyze: --compare needs at least two readable bags (one with --reference)', file=sys.stderr)
            return 1
        out = _replace(dirs[args.bags[0]])
        try:
            reference = comparison.load_reference(args.reference) if args.reference else None
            csv_path, md_path = comparison.write_comparison(list(runs.values()), out, args.tolerance_deg,
                                                            args.eigen_tolerance_deg, reference)
        except ValueError as exc:
            print(f'adcs-analyze: --reference: {exc}', file=sys.stderr)
            return 2
        print(f'comparison: {md_path} ({csv_path.name})', file=info)
        return status
    for path, run in runs.items():
        md_path = single_run.write_report(run, _replace(dirs[path]), args.tolerance_deg, args.eigen_tolerance_deg)
        print(f'report: {md_path}', file=info)
    return status


if __name__ == '__main__':
    raise SystemExit(main())
