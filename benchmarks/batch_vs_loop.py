#!/usr/bin/env python3
"""How much faster is the vectorised batch engine than the same runs one at a time?

Issue #4's benchmark: the PD slew of seed 004 III.F (``config/microsat_pd_slew.yaml``) for
600 s at a 1 s control period with 0.1 s RK4 steps, over ``--runs`` runs (default 1000) with the
attitude dispersed as in ``config/campaigns/pd_slew_30deg.yaml``. Both paths run the very same
code (:class:`adcs_sim.app.batch.engine.BatchSimulation`: plant, law, actuation, metrics):

(a) **vectorised**: all runs in one batch, arrays of shape (N, ...);
(b) **loop**: the same runs one at a time (batches of one). A full loop of 1000 runs takes
    several minutes, so (b) is timed over the first ``--loop-runs`` runs (default 40) and its
    rate (runs per second) extrapolated; (a) is timed over all runs.

Each path is timed ``--repeat`` times (default 3), alternating, and the medians compared (the
machine is shared). Metrics are computed per run in both paths. It also checks that (a) and (b)
give the same numbers for the runs of (b), bit for bit.

Prints runs/s for each and ``ratio = vectorised / loop`` (issue #4 target: >= 50).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adcs_sim.app.batch.engine import BatchSimulation  # noqa: E402
from adcs_sim.app.campaign.plan import Campaign  # noqa: E402


def runs_for(campaign: Campaign, indices: list[int]) -> list[dict]:
    runs = [campaign.run_sections(i) for i in indices]
    for r in runs:
        r['dynamics']['integrator.max_step'] = 0.1
        r['dynamics']['duration'] = 600.0
    return runs


def run(runs: list[dict], n: int) -> tuple[float, list]:
    t0 = time.perf_counter()
    result = BatchSimulation.from_runs(runs).run()
    metrics = [result.metrics(i) for i in range(n)]
    return time.perf_counter() - t0, [result.q, metrics]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=1000)
    parser.add_argument('--loop-runs', type=int, default=40)
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    campaign = Campaign.load(ROOT / 'config' / 'campaigns' / 'pd_slew_30deg.yaml', runs=args.runs)
    everything = runs_for(campaign, list(range(args.runs)))
    singles = [runs_for(campaign, [i]) for i in range(args.loop_runs)]
    vec_times, loop_times = [], []
    for _ in range(args.repeat):
        dt, (q_all, _) = run(everything, args.runs)
        vec_times.append(dt)
        t0 = time.perf_counter()
        for i, s in enumerate(singles):
            _, (q_one, _) = run(s, 1)
            if not np.array_equal(q_one[0], q_all[i]):
                print(f'MISMATCH: run {i} differs between the batch and alone', file=sys.stderr)
                return 1
        loop_times.append(time.perf_counter() - t0)
    vec_rate = args.runs / statistics.median(vec_times)
    loop_rate = args.loop_runs / statistics.median(loop_times)
    print(f'PD slew, 600 s, 1 s control period, 0.1 s RK4 steps; {args.repeat} repeats, medians')
    print(f'(a) vectorised: {args.runs} runs in {statistics.median(vec_times):.2f} s = {vec_rate:.1f} runs/s')
    print(f'(b) one at a time: {args.loop_runs} runs in {statistics.median(loop_times):.2f} s = '
          f'{loop_rate:.2f} runs/s (same numbers as (a), bit for bit)')
    print(f'ratio (a)/(b) = {vec_rate / loop_rate:.1f}  (target >= 50)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
