#!/usr/bin/env python3
"""Regenerate the reference recordings in ``bags/``: one ``adcs-run`` per scenario in ``config/``.

``bags/<scenario>/`` gets the run's ``bag/`` (rosbag2 MCAP), ``metrics.json``, ``scenario.yaml``
and ``layouts/`` (Foxglove and PlotJuggler, :mod:`adcs_sim.app.graph.layouts`); the run's ``logs/`` are
not kept. Each run goes to ``bags/<scenario>.tmp/``
first (ignored by git) and replaces the old recording only when it succeeded.

    .venv/bin/python bags/regenerate.py                 # every config/*.yaml (but NOT_RECORDED)
    .venv/bin/python bags/regenerate.py microsat_pd_slew
    .venv/bin/python bags/regenerate.py --check         # no run: do the kept metrics still match?
    .venv/bin/python bags/regenerate.py --reports       # no run: rewrite every report/ from its bag
    .venv/bin/python bags/regenerate.py --metrics       # no run: rewrite every metrics.json from its bag

``adcs-run`` leases its own ROS_DOMAIN_ID and keeps discovery on localhost. ``--check`` recomputes
every recording's metrics from its bag with the current :mod:`adcs_sim.app.analysis.metrics` and compares
them with its ``metrics.json`` (what tests/test_any_bag.py also checks). ``--reports`` rewrites
each kept ``report/`` (``adcs-analyze``'s report, named after the scenario) from the bag beside it,
without running anything: after a change to the reports, or after a merge. ``--metrics`` rewrites
each kept ``metrics.json`` from the bag beside it as ``adcs-run`` computes it (after a metric is
added), and refuses (status 1, nothing written) if a value already kept would change.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CONFIG = ROOT / 'config'
# The seed 000 runs are 10 000 s at 1 Hz (~6 MB each with the report), the fifteen seed 001 runs
# 1 000-9 000 steps each (1-4 MB a bag: the M2S status carries ~25 values a step): 100 MB holds
# every recording the tests and the docs read.
MAX_TOTAL_BYTES = 100_000_000
# Recordings kept without their report/ (1-2 MB each): their docs show paper-style figures made
# from the bags instead (docs/seed001/figures.py); `adcs-analyze bags/<name>/bag` makes the report.
# But one of each seed 001 kind keeps its report (a spin run, a motion-to-rest run: bags/README.md).
NO_REPORT_PREFIXES = ('m2r_', 'm2s_')
WITH_REPORT = ('m2s_nonprincipal_vagc_0p02', 'm2r_umax0p1')
# The GSMN slew on the MEKF estimate: 6000 steps of figures (~5 MB of SVG) would pass the budget; its
# estimation report is shown by microsat_pd_slew_star_tracker_outage's (the same estimator and section).
NO_REPORT = ('microsat_gsmn_slew_mekf',)
# Scenarios in config/ without a kept recording (their figures come from the batch engine).
NOT_RECORDED = {
    'uosat12_gsmn_100mnm': 'the 100 mN m variant of uosat12_gsmn (docs/seed000.md, from the batch engine)',
    # Two orbits at 0.1 s are 107 410 steps: ~24 min through the graph and a ~60 MB bag. The
    # recorded run is its first 300 s, eseo_backstepping_slew; the two-orbit figures (one graph
    # run, not kept) are in docs/seed002.md.
    'eseo_backstepping': 'the two-orbit mission; its first 300 s are eseo_backstepping_slew (docs/seed002.md)',
    # seed 001 at 0.005 N m: 20 000-30 000 steps each (~10 MB a bag); their outcomes are reported,
    # not asserted, in docs/seed001.md from the batch engine (the graph's own code, equal bit for bit)
    'm2s_nonprincipal_vagc_0p005': 'figure 14, VAG-C at 0.005 N m (docs/seed001.md, batch engine)',
    'm2s_nonprincipal_vags_0p005': 'figure 14, VAG-S at 0.005 N m (docs/seed001.md, batch engine)',
    'm2s_nonprincipal_extremum_0p005': 'figure 15, extremum tracking at 0.005 N m (docs/seed001.md, batch engine)',
    # 3000 steps with the IGRF sampled twice a step (truth and the filter's onboard model); its checks run
    # on the batch engine (tests/test_determination_scenarios.py), the environment-fed sensors on the graph
    # in tests/test_sensor_graph.py
    'leo_tle_sun_magnetometer_mekf': 'sun + magnetometer + gyro MEKF through an eclipse (docs/determination.md, batch engine)',
}


def runner_command() -> list[str]:
    exe = Path(sys.executable).parent / 'adcs-run'
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'adcs_sim.app.graph.runner']


def regenerate(name: str) -> Path:
    scenario = CONFIG / f'{name}.yaml'
    if not scenario.exists():
        raise SystemExit(f'regenerate: no scenario {scenario}')
    tmp = HERE / f'{name}.tmp'
    shutil.rmtree(tmp, ignore_errors=True)
    cmd = [*runner_command(), str(scenario), '--out', str(tmp), '--no-progress']
    print('$', ' '.join(cmd), flush=True)
    result = subprocess.run(cmd, cwd=ROOT)
    if result.returncode != 0:
        raise SystemExit(f'regenerate: adcs-run failed for {name} (status {result.returncode}); '
                         f'output kept in {tmp}')
    shutil.rmtree(tmp / 'logs', ignore_errors=True)
    if has_report(name):
        write_report(tmp, name)
    # Its viewer layouts (adcs-analyze --foxglove-layout / --plotjuggler-layout; a recording made
    # now carries the viewer topics: /tf, markers, error/*).
    from adcs_sim.app.analysis.analyze import main as analyze
    layouts = tmp / 'layouts'
    layouts.mkdir()
    if analyze([str(tmp / 'bag'), '--foxglove-layout', str(layouts / 'foxglove.json'),
                '--plotjuggler-layout', str(layouts / 'plotjuggler.xml')]) != 0:
        raise SystemExit(f'regenerate: the layouts failed for {name}; output kept in {tmp}')
    dest = HERE / name
    shutil.rmtree(dest, ignore_errors=True)
    tmp.rename(dest)
    return dest


def has_report(name: str) -> bool:
    return (not name.startswith(NO_REPORT_PREFIXES) and name not in NO_REPORT) or name in WITH_REPORT


def write_report(folder: Path, name: str) -> Path:
    """The run's report (``report/``: report.md + PNG/SVG figures, replaced whole), so the docs can
    show it; named after the scenario (its published values are looked up by that name)."""
    sys.path.insert(0, str(ROOT))
    # matplotlib behind the report: imported only when a report is written
    from adcs_sim.app.report.loading import BagError, load_run
    from adcs_sim.app.report.single_run import write_report as write
    out = folder / 'report'
    shutil.rmtree(out, ignore_errors=True)
    try:
        run = load_run(folder / 'bag', name)
        run.path = run.path.relative_to(ROOT) if run.path.is_relative_to(ROOT) else run.path  # as the docs cite it
        return write(run, out)
    except BagError as exc:
        raise SystemExit(f'regenerate: {folder / "bag"}: {exc}') from None


def check(folder: Path) -> list[str]:
    """Differences between a recording's metrics.json and its bag's metrics computed now."""
    sys.path.insert(0, str(ROOT))
    from adcs_sim.app.analysis.metrics import RunData, jsonable_metrics, run_metrics
    kept = json.loads((folder / 'metrics.json').read_text())
    now = json.loads(json.dumps(jsonable_metrics(run_metrics(RunData.from_bag(folder / 'bag')))))
    return [f'{folder.name}: {k}: kept {kept[k]!r}, now {now.get(k)!r}'
            for k in kept if now.get(k) != kept[k]]


def rewrite_metrics(folder: Path) -> list[str]:
    """Write ``folder/metrics.json`` from its bag (adcs-run's streamed metrics) unless a kept value
    would change; returns those changes (then nothing is written)."""
    sys.path.insert(0, str(ROOT))
    from adcs_sim.app.analysis.metrics import jsonable_metrics
    from adcs_sim.app.analysis.stream_metrics import analyse_bag
    path = folder / 'metrics.json'
    kept = json.loads(path.read_text())
    text = json.dumps(jsonable_metrics(analyse_bag(folder / 'bag').metrics), indent=2)
    now = json.loads(text)
    changed = [f'{folder.name}: {k}: kept {kept[k]!r}, now {now.get(k)!r}' for k in kept if now.get(k) != kept[k]]
    if not changed:
        path.write_text(text)
    return changed


def total_bytes() -> int:
    return sum(f.stat().st_size for d in HERE.iterdir() if d.is_dir() and not d.name.endswith('.tmp')
               for f in d.rglob('*') if f.is_file())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('scenarios', nargs='*', help='scenario names (default: every config/*.yaml)')
    parser.add_argument('--check', action='store_true', help='only compare kept metrics with the bags')
    parser.add_argument('--reports', action='store_true',
                        help='only rewrite the kept reports from the bags (no run)')
    parser.add_argument('--metrics', action='store_true',
                        help='only rewrite the kept metrics.json from the bags (no run; kept values must not change)')
    args = parser.parse_args(argv)
    names = args.scenarios or sorted(p.stem for p in CONFIG.glob('*.yaml') if p.stem not in NOT_RECORDED)
    if args.reports:
        for name in (n for n in names if has_report(n)):
            print(f'{write_report(HERE / name, name).relative_to(ROOT)}', flush=True)
        return 0
    if args.metrics:
        problems = [p for name in names for p in rewrite_metrics(HERE / name)]
        print('\n'.join(problems) or f'ok: {len(names)} metrics.json rewritten, no kept value changed')
        return 1 if problems else 0
    if args.check:
        problems = [p for name in names for p in check(HERE / name)]
        print('\n'.join(problems) or f'ok: {len(names)} recording(s) match their metrics.json')
        return 1 if problems else 0
    for name in names:
        dest = regenerate(name)
        print(f'{dest.relative_to(ROOT)}: ' + ', '.join(sorted(p.name for p in dest.iterdir())))
    size = total_bytes()
    print(f'bags/: {size / 1e6:.2f} MB in recordings')
    if size > MAX_TOTAL_BYTES:
        print(f'regenerate: bags/ exceeds {MAX_TOTAL_BYTES / 1e6:.0f} MB', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
