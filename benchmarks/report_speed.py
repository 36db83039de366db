#!/usr/bin/env python3
"""How long does a run's report take, and how much memory, old tree vs this one?

``adcs-analyze <bag> --out DIR`` (the metrics and the report: what ``adcs-run --report`` does after
its run), each in a fresh process that prints its own wall time and peak resident set
(``ru_maxrss``), alternated between this tree and ``--compare`` (another checkout, run with
``PYTHONPATH`` on it and this tree's venv; e.g. ``/tmp/s9_base``, the tree before issue #18's report
work), ``--repeat`` times:

* **showcase**: the committed ``bags/uosat12_gsmn`` bag (the 10 000-step showcase, ``make run``'s);
  both trees' reports are then compared file by file (SVG ids made reproducible with a fixed
  ``svg.hashsalt``): identical PNG and SVG bytes and ``report.md`` expected;
* **long** (``--hours H``, default 24; ``--hours 0`` skips it): a synthetic H-hour run at
  ``--rate`` Hz written as ``benchmarks/analysis_speed.py`` writes it (or ``--bag DIR``, an
  existing one): the report's time and peak memory (the target: <= 300 MB at 24 h, 10 Hz; this
  tree streams it, :mod:`adcs_sim.app.report.long_run`); with ``--compare``, both trees' reports
  compared file by file too.

Prints best-of-``--repeat`` wall and CPU times (user + system: less disturbed by a loaded
machine) and peaks, and their ratios (old / new). Not a test (minutes).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHOWCASE = ROOT / 'bags' / 'uosat12_gsmn' / 'bag'
# One adcs-analyze in this process: its wall time and peak RSS as a JSON line on stdout's last line.
CHILD = '''
import json, resource, runpy, sys, time
t0 = time.perf_counter()
sys.argv = ['adcs-analyze'] + sys.argv[1:]
try:
    runpy.run_module('adcs_sim.app.analysis.analyze', run_name='__main__')
except SystemExit as exc:
    assert not exc.code, exc.code
usage = resource.getrusage(resource.RUSAGE_SELF)
import adcs_sim, pathlib
print(json.dumps({'code': str(pathlib.Path(adcs_sim.__file__).parents[1]),
                  'seconds': time.perf_counter() - t0, 'cpu_s': usage.ru_utime + usage.ru_stime,
                  'peak_mib': usage.ru_maxrss / 1024}))
'''


def measure(tree: Path | None, bag: Path, out: Path, env: dict) -> dict:
    """One report of ``bag`` into ``out`` by ``tree``'s code (None: this tree's)."""
    env = dict(env)
    if tree is not None:
        env['PYTHONPATH'] = str(tree)
    shutil.rmtree(out, ignore_errors=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    # (not from the tree's folder: `python -c` puts the current directory before PYTHONPATH)
    done = subprocess.run([sys.executable, '-c', CHILD, str(bag.resolve()), '--out', str(out)], env=env, cwd=out.parent,
                          capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f'report of {bag} failed ({tree or "this tree"}):\n{done.stderr[-2000:]}')
    row = json.loads(done.stdout.strip().splitlines()[-1])
    if row['code'] != str(tree or ROOT):
        raise SystemExit(f'the report ran {row["code"]}\'s code, not {tree or ROOT}\'s')
    return row


def alternate(label: str, bag: Path, base: Path | None, repeat: int, tmp: Path, env: dict) -> None:
    trees = {'new': None} if base is None else {'old': base, 'new': None}
    rows: dict[str, list] = {k: [] for k in trees}
    for _ in range(repeat):
        for kind, tree in trees.items():
            rows[kind].append(measure(tree, bag, tmp / label / kind, env))
    best = {k: {'seconds': min(r['seconds'] for r in v), 'cpu_s': min(r['cpu_s'] for r in v),
                'peak_mib': min(r['peak_mib'] for r in v)} for k, v in rows.items()}
    for kind, b in best.items():
        every = ', '.join(f'{r["seconds"]:.2f}' for r in rows[kind])
        print(f'{label:<9} {kind}: {b["seconds"]:7.2f} s wall (best of {repeat}: {every}), {b["cpu_s"]:7.2f} s CPU   '
              f'peak RSS {b["peak_mib"]:7.1f} MiB')
    if base is not None:
        o, n = best['old'], best['new']
        print(f'{label:<9} old / new: wall {o["seconds"] / n["seconds"]:.2f}x, CPU {o["cpu_s"] / n["cpu_s"]:.2f}x, '
              f'peak memory {o["peak_mib"] / n["peak_mib"]:.2f}x')


def same_reports(a: Path, b: Path) -> str:
    names = sorted(p.name for p in a.iterdir())
    if names != sorted(p.name for p in b.iterdir()):
        return 'no: different files'
    differ = [n for n in names if (a / n).read_bytes() != (b / n).read_bytes()]
    return 'yes, every file byte for byte' if not differ else 'no: ' + ', '.join(differ)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--compare', type=Path, default=None, metavar='TREE',
                        help='another checkout to alternate with (e.g. /tmp/s9_base)')
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--hours', type=float, default=24.0, help='the long run (0: skip it)')
    parser.add_argument('--rate', type=float, default=10.0, help='its control rate, Hz')
    parser.add_argument('--long-repeat', type=int, default=1, help='repeats of the long run')
    parser.add_argument('--bag', type=Path, default=None, help='an existing long bag instead of writing one')
    args = parser.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix='adcs_report_speed_'))
    try:
        rc = tmp / 'matplotlibrc'
        rc.write_text('svg.hashsalt: report_speed\n')   # reproducible SVG ids: the two trees' files compare
        env = {**os.environ, 'MATPLOTLIBRC': str(rc)}
        alternate('showcase', SHOWCASE, args.compare, args.repeat, tmp, env)
        if args.compare is not None:
            print(f'showcase  reports identical (old vs new): {same_reports(tmp / "showcase" / "old", tmp / "showcase" / "new")}')
        if args.hours > 0 or args.bag:
            bag = args.bag
            if bag is None:
                sys.path.insert(0, str(ROOT / 'benchmarks'))
                from analysis_speed import write_bag
                bag = tmp / 'long'
                t0 = time.perf_counter()
                written, _ = write_bag(bag, args.hours, args.rate)
                print(f'long bag: {args.hours:g} h at {args.rate:g} Hz, {written} messages '
                      f'(written in {time.perf_counter() - t0:.0f} s)')
            alternate('long', bag, args.compare, args.long_repeat, tmp, env)
            if args.compare is not None:
                print(f'long      reports identical (old vs new): {same_reports(tmp / "long" / "old", tmp / "long" / "new")}')
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
