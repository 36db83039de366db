#!/usr/bin/env python3
"""The speed of each metric path, this tree against another (a metric path must not get slower when a
metric moves onto its one definition).

Times (process CPU time), best of ``--repeat`` in one process each:

* **in-memory**: :func:`adcs_sim.app.analysis.metrics.run_metrics` of a committed bag's
  :class:`~adcs_sim.app.analysis.run_data.RunData` (read once, not timed), what ``adcs-analyze`` prints;
* **streamed**: :func:`adcs_sim.app.analysis.stream_metrics.analyse_bag` of that bag (what ``adcs-run`` does);
* **campaign**: :func:`adcs_sim.app.analysis.batch_metrics.batch_metric_columns` (a campaign chunk's rows) and
  :func:`~adcs_sim.app.analysis.batch_metrics.batch_run_metrics` of a batch of ``--runs`` runs of
  ``config/campaigns/pd_slew_30deg.yaml`` (simulated once, not timed);
* **long report**: :func:`adcs_sim.app.report.long_run.load_long` of the bag (the 24 h report's two
  streamed passes, ``envelope.MAX_POINTS`` lowered so that it streams).

``--compare OLD_TREE`` (``git archive <commit> | tar -x -C /tmp/old``): each tree in its own child
process (``PYTHONPATH`` = the tree), alternately ``--rounds`` times, and the ratio new / old of the
medians per path (> 1: this tree is slower). Not a test.

    .venv/bin/python benchmarks/metric_paths.py --compare /tmp/old [--bag bags/microsat_gsmn_slew/bag]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BAG = 'bags/microsat_gsmn_slew/bag'   # a regulation run with wheels (the long report streams it)


def best(fn, repeat: int) -> float:
    """The least process CPU time of ``repeat`` calls (on a shared, loaded machine the wall time of
    one call varies several-fold; its CPU time much less)."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def measure(bag: str, runs: int, repeat: int) -> dict[str, float]:
    """Seconds per path (best of ``repeat``) in this process' tree."""
    import numpy as np

    from adcs_sim.app.analysis import batch_metrics

    from adcs_sim.app.analysis import stream_metrics
    from adcs_sim.app.analysis.metrics import run_metrics
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.campaign.plan import Campaign
    from adcs_sim.app.report import envelope, long_run
    from adcs_sim.app.analysis.run_data import RunData

    bag = str(ROOT / bag)
    run = RunData.from_bag(bag)
    out = {'in-memory': best(lambda: run_metrics(run), repeat * 5),
           'streamed': best(lambda: stream_metrics.analyse_bag(bag), repeat)}
    envelope.MAX_POINTS = 1000
    out['long report'] = best(lambda: long_run.load_long(bag), repeat)
    campaign = Campaign.load(ROOT / 'config/campaigns/pd_slew_30deg.yaml', runs=runs)
    indices = list(range(runs))
    result = BatchSimulation(campaign.batch_sections(indices, campaign.draws(indices)), runs).run()
    with np.errstate(all='ignore'):
        batch_metrics.batch_metric_columns(result, campaign.tol_deg)   # compiled once (cached)
        out['campaign columns'] = best(lambda: batch_metrics.batch_metric_columns(result, campaign.tol_deg), repeat)
        out['campaign dicts'] = best(lambda: batch_metrics.batch_run_metrics(result, campaign.tol_deg), repeat)
    return out


def compare(old: Path, args) -> None:
    trees = {'new': ROOT, 'old': old.resolve()}
    samples: dict[str, dict[str, list]] = {name: {} for name in trees}
    for r in range(args.rounds):
        for name, tree in (trees.items() if r % 2 == 0 else reversed(list(trees.items()))):
            env = dict(os.environ, PYTHONPATH=str(tree))
            cmd = [sys.executable, str(ROOT / 'benchmarks/metric_paths.py'), '--bag', args.bag,
                   '--runs', str(args.runs), '--repeat', str(args.repeat), '--json']
            got = json.loads(subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True,
                                            text=True).stdout.strip().splitlines()[-1])
            for path, s in got.items():
                samples[name].setdefault(path, []).append(s)
            print(f'round {r + 1} {name}: ' + ', '.join(f'{k} {v * 1e3:.1f} ms' for k, v in got.items()), flush=True)
    print(f'\nmedians over {args.rounds} rounds (bag {args.bag}, campaign batch of {args.runs} runs):')
    print(f'  {"path":<18} {"old ms":>10} {"new ms":>10} {"new/old":>8}')
    for path in samples['new']:
        a, b = statistics.median(samples['old'][path]), statistics.median(samples['new'][path])
        print(f'  {path:<18} {a * 1e3:>10.2f} {b * 1e3:>10.2f} {b / a:>8.3f}')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--bag', default=DEFAULT_BAG, help='a bag, relative to the tree (default %(default)s)')
    ap.add_argument('--runs', type=int, default=200, help='campaign batch size (default %(default)s)')
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--rounds', type=int, default=3, help='--compare: alternations (default %(default)s)')
    ap.add_argument('--compare', type=Path, metavar='OLD_TREE')
    ap.add_argument('--json', action='store_true', help='print the seconds as JSON (the child of --compare)')
    args = ap.parse_args()
    if args.compare:
        compare(args.compare, args)
        return
    got = measure(args.bag, args.runs, args.repeat)
    if args.json:
        print(json.dumps(got))
    else:
        for path, s in got.items():
            print(f'  {path:<18} {s * 1e3:10.2f} ms')


if __name__ == '__main__':
    main()
