#!/usr/bin/env python3
"""Seed 003 Table 1 Monte Carlo: vectorised batch vs the same runs one at a time.

Issue #9's benchmark: ``config/campaigns/pointing_table1.yaml`` (controller B; ``--campaign`` for
another, e.g. ``pointing_table1_a.yaml``): ``--runs`` runs (default 1000) of 1500 simulated s at
a 1 s control period, the paper's 20 mN m torque limit, random initial attitudes. Both paths run
the very same code (:func:`adcs_sim.app.campaign.plan.run_chunk`: batch engine, law, actuation, metrics):

(a) **vectorised**: the campaign's chunks (``chunk_size`` runs per batch), all runs;
(b) **one at a time**: batches of one. The whole serial campaign would take tens of minutes, so
    (b) is timed over the first ``--serial-runs`` runs (default 20) and EXTRAPOLATED to all runs
    (runs per second x runs); it says so in its output.

Also checks that (a) and (b) give the same metrics for the runs of (b), bit for bit. Prints the
wall time of each, ``ratio = serial / vectorised`` (extrapolated) and the real-time factor per
run (simulated seconds per wall second of one run: 1500 s x runs / wall time).
One process, one core (run it alone for clean numbers; the machine may be shared).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adcs_sim.app.campaign.plan import Campaign, run_chunk  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--campaign', default='pointing_table1.yaml')
    parser.add_argument('--runs', type=int, default=1000)
    parser.add_argument('--serial-runs', type=int, default=20)
    args = parser.parse_args(argv)
    campaign = Campaign.load(ROOT / 'config' / 'campaigns' / args.campaign, args.runs)
    campaign.series_every = 0          # metrics only (what the timing is about)
    sim_s = float(campaign.defaults['dynamics']['duration'])

    t0 = time.perf_counter()
    rows = []
    for chunk in campaign.chunks():
        rows += run_chunk(campaign, chunk)
    vec = time.perf_counter() - t0

    n_serial = min(args.serial_runs, campaign.runs)
    t0 = time.perf_counter()
    serial_rows = [run_chunk(campaign, [i])[0] for i in range(n_serial)]
    ser = time.perf_counter() - t0
    ser_all = ser / n_serial * campaign.runs

    same = all(a['metrics'] == b['metrics'] for a, b in zip(serial_rows, rows))
    converged = sum(r['status'] == 'ok' for r in rows)
    print(f'{args.campaign}: {campaign.runs} runs x {sim_s:g} s simulated, chunk_size {campaign.chunk_size}')
    print(f'  vectorised : {vec:8.1f} s wall for all {campaign.runs} runs '
          f'({campaign.runs / vec:.2f} runs/s); {converged} ok')
    print(f'  one at a time: {ser:8.1f} s for {n_serial} runs -> {ser_all:8.1f} s for {campaign.runs} '
          f'(EXTRAPOLATED from {n_serial} runs)')
    print(f'  ratio (one at a time / vectorised): {ser_all / vec:.1f}')
    print(f'  real-time factor per run: vectorised {sim_s * campaign.runs / vec:.0f}x, '
          f'one at a time {sim_s * n_serial / ser:.0f}x (simulated s per wall s)')
    print(f'  metrics of the {n_serial} serial runs equal the vectorised ones bit for bit: {same}')
    return 0 if same else 1


if __name__ == '__main__':
    raise SystemExit(main())
