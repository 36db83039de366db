#!/usr/bin/env python3
"""Monte Carlo throughput: a campaign's runs per second, compiled plant against numpy and Basilisk.

Issue 18's Monte Carlo benchmark, on ``config/campaigns/pd_slew_30deg.yaml`` (1000 PD slews of
600 s, 1 s control period, the scenario's RK4 step) unless ``--campaign`` names another (the seed
003 Table 1 campaign: ``config/campaigns/pointing_table1.yaml``). The campaign is run as
``adcs-montecarlo`` runs it, chunk by chunk (:func:`adcs_sim.app.campaign.run_chunk`: dispersions,
batch simulation, metrics), in this process without Dask:

(a) **fused**: the batch engine's fused compiled closed loop where it applies (PD family on wheels:
    :mod:`adcs_sim.app.fused`, whole runs per compiled call), else as (b);
(b) **kernel**: step by step in Python, plants on the compiled kernel (:mod:`adcs_sim.truth.kernel`),
    ``ADCS_FUSED_LOOP=0`` semantics (``fused.ENABLED = False``);
(c) **numpy**: the same campaign with ``ADCS_PLANT_KERNEL=0`` semantics as well (``kernel.ENABLED =
    False``: the numpy plant), all three checked to give the same rows bit for bit.

``--basilisk``: the same slews in Basilisk 2.12.1 one after another (bsk installed into a throwaway
venv under /tmp, :mod:`bsk_support`; hub + 3 wheels, RK4 at the scenario's step, simpleNav,
attTrackingError, mrpFeedback as PD, rwMotorTorque at the control period), a timed sample of
``--bsk-sample`` runs scaled to the campaign's size, and ``ratio = Basilisk / ours``
(issue target >= 100). Says so when Basilisk cannot be installed or run. Wall and CPU time both
(process CPU time, all threads: on a shared, loaded machine the wall times of two measurements taken
a minute apart can differ several-fold, the CPU times much less); the Basilisk ratio also with
``Campaign.load`` (reading the files and validating every run's draw, once per campaign) added to ours.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bsk_support import basilisk_python, run_child  # noqa: E402

from adcs_sim.app import fused as fused_loop  # noqa: E402
from adcs_sim.app.campaign import Campaign, run_chunk  # noqa: E402
from adcs_sim.truth import kernel  # noqa: E402

DEFAULT = ROOT / 'config' / 'campaigns' / 'pd_slew_30deg.yaml'


CPU = {}   # each path's process CPU time (all threads), s: a fairer figure than wall time on a loaded machine


def timed_campaign(campaign: Campaign, compiled: bool, fused: bool = True) -> tuple[float, list]:
    kernel.ENABLED, fused_loop.ENABLED = compiled, fused
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        rows = [row for chunk in campaign.chunks() for row in run_chunk(campaign, chunk)]
        CPU[(compiled, fused)] = time.process_time() - c0
        return time.perf_counter() - t0, rows
    finally:
        kernel.ENABLED = fused_loop.ENABLED = True


def basilisk_per_run(campaign: Campaign, sample: int) -> tuple[dict | None, str]:
    python, why = basilisk_python()
    if python is None:
        return None, why
    sigma0 = []
    for i in range(sample):
        d = campaign.run_sections(i)['dynamics']
        q = np.asarray(d['initial.attitude'], dtype=float)
        q = q / np.linalg.norm(q)
        sigma0.append([float(v) for v in q[:3] / (1.0 + q[3])])  # MRP of the initial attitude
    d = campaign.run_sections(0)['dynamics']
    args = {'inertia': [float(v) for v in np.diag(np.asarray(d['inertia'], dtype=float).reshape(-1))[:3]]
            if np.asarray(d['inertia']).size == 9 else [float(v) for v in d['inertia']],
            'spin_inertia': float(d['wheels.spin_inertia'][0]), 'max_torque': float(d['wheels.max_torque'][0]),
            'max_speed': float(d['wheels.max_speed'][0]), 'max_step': float(d['integrator.max_step']),
            'period': float(d['control_period']), 'duration': float(d['duration']),
            'K': 0.024, 'P': 0.6, 'sigma0': sigma0}
    answer, why = run_child(python, 'bsk_pd_slew.py', args)
    if answer is None:
        return None, why
    print(f"Basilisk: {answer['runs']} slews timed, worst final |sigma| {answer['final_mrp_norm_max']:.2e}")
    return answer, ''


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--campaign', type=Path, default=DEFAULT)
    parser.add_argument('--runs', type=int, default=None, help='first N runs only (default: all)')
    parser.add_argument('--basilisk', action='store_true', help='also time a sample of bsk 2.12.1 runs')
    parser.add_argument('--bsk-sample', type=int, default=5)
    args = parser.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    campaign = Campaign.load(args.campaign, runs=args.runs)
    load = time.perf_counter() - t0   # reading the files and validating every run's draw, once
    load_cpu = time.process_time() - c0
    warm = Campaign.load(args.campaign, runs=min(campaign.chunk_size, campaign.runs))
    timed_campaign(warm, True)
    timed_campaign(warm, True, fused=False)
    fast, rows = timed_campaign(campaign, True)
    step, rows_step = timed_campaign(campaign, True, fused=False)
    slow, rows_numpy = timed_campaign(campaign, False, fused=False)
    if not repr(rows) == repr(rows_step) == repr(rows_numpy):
        print('MISMATCH: the fused, kernel and numpy campaigns differ', file=sys.stderr)
        return 1
    n = campaign.runs
    print(f'{args.campaign.name}: {n} runs in chunks of {campaign.chunk_size}, one process (same rows bit for bit)')
    print(f'  Campaign.load (files, every draw validated once): {load:.2f} s; the chunks:')
    print(f'  (a) fused:  {fast:.2f} s = {n / fast:.1f} runs/s')
    print(f'  (b) kernel: {step:.2f} s = {n / step:.1f} runs/s   (b)/(a) time = {step / fast:.2f}')
    print(f'  (c) numpy:  {slow:.2f} s = {n / slow:.1f} runs/s   (c)/(a) time = {slow / fast:.2f}')
    print(f'  CPU time (all threads): (a) {CPU[True, True]:.2f} s  (b) {CPU[True, False]:.2f} s  '
          f'(c) {CPU[False, False]:.2f} s; Campaign.load {load_cpu:.2f} s')
    if args.basilisk:
        answer, why = basilisk_per_run(campaign, args.bsk_sample)
        if answer is None:
            print(f'Basilisk: not measured ({why})')
        else:
            per_run, cpu = answer['s_per_run'], answer.get('cpu_s_per_run', math.nan)
            print(f'  Basilisk 2.12.1, one run after another: {per_run:.3f} s per run, {n} runs ~ '
                  f'{per_run * n:.1f} s   ratio Basilisk/(a) = {per_run * n / fast:.1f}  (target >= 100)')
            print(f'  CPU time: Basilisk {cpu:.4f} s per run, {n} runs ~ {cpu * n:.1f} s   ratio Basilisk/(a) = '
                  f'{cpu * n / CPU[True, True]:.1f}; with Campaign.load: {cpu * n / (CPU[True, True] + load_cpu):.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
