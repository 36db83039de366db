#!/usr/bin/env python3
"""Monte Carlo throughput: a campaign's runs per second, compiled plant against numpy and Basilisk.

Issue 18's Monte Carlo benchmark, on ``config/campaigns/pd_slew_30deg.yaml`` (1000 PD slews of
600 s, 1 s control period, the scenario's RK4 step) unless ``--campaign`` names another (the seed
003 Table 1 campaign: ``config/campaigns/pointing_table1.yaml``). The campaign is run as
``adcs-montecarlo`` runs it, chunk by chunk (:func:`adcs_sim.app.campaign.plan.run_chunk`: dispersions,
batch simulation, metrics), in this process without Dask:

(a) **fused**: the batch engine's fused compiled closed loop where it applies (PD family on wheels:
    :mod:`adcs_sim.app.batch.fused`, whole runs per compiled call), else as (b);
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

``--end-to-end``: the whole command a user types, ``adcs-montecarlo <campaign> --quiet`` (its own
process: start-up, imports, ``Campaign.load``, the runs, the outputs and figures), with the default
``--scheduler auto`` and with ``none`` and ``local`` forced, alternated ``--repeat`` times (wall
time and the CPU time of the process and its children); and the start-up of a Dask LocalCluster (2
workers) to its first one-run chunk, the cost ``--scheduler auto`` weighs
(:data:`adcs_sim.app.campaign.scheduling.CLUSTER_START_S`). With ``--basilisk``, Basilisk's time
over each.

``--compare OLD_TREE`` (e.g. ``git archive <commit> | tar -x -C /tmp/old``): the campaign as
``adcs-montecarlo --scheduler none`` runs it (``Campaign.load``, then every chunk), this tree and the
old one alternately ``--repeat`` times, each in its own persistent child process (cwd and
``PYTHONPATH`` = its tree; warmed up first), wall and CPU time of the load and of the chunks; the
rows of both trees compared (a hash of their ``repr``: the same bits). With ``--basilisk``, the
Basilisk ratio of both (median totals). ``--fused-only`` skips (b) and (c) (e.g. for the seed 003
Table 1 campaign, whose numpy path takes minutes).
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bsk_support import basilisk_python, run_child  # noqa: E402

from adcs_sim.app.batch import fused as fused_loop  # noqa: E402
from adcs_sim.app.campaign.plan import Campaign, run_chunk  # noqa: E402
from adcs_sim.app.campaign.scheduling import CLUSTER_START_S  # noqa: E402
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


CHILD = r"""
import hashlib, json, sys, time
from adcs_sim.app.campaign.plan import Campaign, run_chunk
path, runs = sys.argv[1], None if sys.argv[2] == 'all' else int(sys.argv[2])
warm = Campaign.load(path, runs=2)
[run_chunk(warm, chunk) for chunk in warm.chunks()]
for _ in sys.stdin:
    t0, c0 = time.perf_counter(), time.process_time()
    campaign = Campaign.load(path, runs=runs)
    t1, c1 = time.perf_counter(), time.process_time()
    rows = [row for chunk in campaign.chunks() for row in run_chunk(campaign, chunk)]
    t2, c2 = time.perf_counter(), time.process_time()
    print(json.dumps({'load': t1 - t0, 'chunks': t2 - t1, 'load_cpu': c1 - c0, 'chunks_cpu': c2 - c1,
                      'runs': campaign.runs, 'rows': hashlib.sha256(repr(rows).encode()).hexdigest()}), flush=True)
"""


def compare_trees(campaign: Path, runs: int | None, old: Path, repeat: int) -> dict[str, list[dict]]:
    """Each tree's timings (module docstring), the two children asked in turn."""
    children = {}
    for name, tree in (('new', ROOT), ('old', old.resolve())):
        env = dict(os.environ, PYTHONPATH=str(tree))
        children[name] = subprocess.Popen([sys.executable, '-c', CHILD, str(campaign.resolve()),
                                           'all' if runs is None else str(runs)], cwd=tree, env=env,
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    out: dict[str, list[dict]] = {'new': [], 'old': []}
    try:
        for i in range(repeat):
            for name in (('new', 'old') if i % 2 == 0 else ('old', 'new')):
                child = children[name]
                child.stdin.write('go\n')
                child.stdin.flush()
                line = child.stdout.readline()
                if not line:
                    raise RuntimeError(f'the {name} tree\'s child died (exit {child.wait()})')
                out[name].append(json.loads(line))
    finally:
        for child in children.values():
            child.stdin.close()
            child.wait()
    return out


def print_comparison(times: dict[str, list[dict]], old: Path, bsk: dict | None) -> bool:
    """Print medians (and ranges) of both trees; whether their rows are the same."""
    med = {name: {k: statistics.median(t[k] for t in ts) for k in ('load', 'chunks', 'load_cpu', 'chunks_cpu')}
           for name, ts in times.items()}
    n = times['new'][0]['runs']
    print(f'--compare {old}: {len(times["new"])} alternated measurements each (median, [min-max]), {n} runs')
    for name in ('new', 'old'):
        ts, m = times[name], med[name]
        total = [t['load'] + t['chunks'] for t in ts]
        print(f'  {name}: Campaign.load {m["load"]:.3f} s, chunks {m["chunks"]:.3f} s '
              f'[{min(t["chunks"] for t in ts):.3f}-{max(t["chunks"] for t in ts):.3f}], total '
              f'{statistics.median(total):.3f} s [{min(total):.3f}-{max(total):.3f}]; CPU load '
              f'{m["load_cpu"]:.3f} s, chunks {m["chunks_cpu"]:.3f} s')
    new_total, old_total = (med[k]['load'] + med[k]['chunks'] for k in ('new', 'old'))
    new_cpu, old_cpu = (med[k]['load_cpu'] + med[k]['chunks_cpu'] for k in ('new', 'old'))
    print(f'  old/new: chunks {med["old"]["chunks"] / med["new"]["chunks"]:.2f}x, with the load '
          f'{old_total / new_total:.2f}x (wall); CPU {old_cpu / new_cpu:.2f}x')
    if bsk is not None:
        wall, cpu = bsk['s_per_run'] * n, bsk.get('cpu_s_per_run', math.nan) * n
        for name in ('new', 'old'):
            m = med[name]
            print(f'  Basilisk ({wall:.1f} s wall, {cpu:.1f} s CPU) / {name}: {wall / m["chunks"]:.1f}x by wall, '
                  f'{wall / (m["load"] + m["chunks"]):.1f}x counting Campaign.load; CPU '
                  f'{cpu / (m["load_cpu"] + m["chunks_cpu"]):.1f}x counting the load  (target >= 100)')
    same = {t['rows'] for ts in times.values() for t in ts}
    print('  rows: the same bits in both trees' if len(same) == 1 else f'  MISMATCH: {len(same)} different row sets')
    return len(same) == 1


def end_to_end(campaign: Path, repeat: int) -> dict[str, list[tuple[float, float]]]:
    """(wall, CPU) of ``adcs-montecarlo <campaign> --quiet --scheduler S`` in a child process, for S
    auto, none and local, alternated ``repeat`` times (outputs in a temporary folder)."""
    out: dict[str, list[tuple[float, float]]] = {'auto': [], 'none': [], 'local': []}
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            for scheduler in (list(out) if i % 2 == 0 else list(out)[::-1]):
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                subprocess.run([sys.executable, '-m', 'adcs_sim.app.campaign.montecarlo', str(campaign), '--quiet',
                                '--scheduler', scheduler, '--out', f'{tmp}/{scheduler}{i}'], env=env, check=True,
                               stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                out[scheduler].append((wall, cpu))
    return out


def cluster_start(campaign_path: Path) -> float:
    """Seconds from LocalCluster(2 workers) to the result of a one-run chunk, that chunk's time in
    this process taken off."""
    # lazy: Dask (1.2 s) only for --end-to-end
    from dask.distributed import Client, LocalCluster
    one = Campaign.load(campaign_path, runs=1)
    run_chunk(one, [0])
    t0 = time.perf_counter()
    run_chunk(one, [0])
    here = time.perf_counter() - t0
    t0 = time.perf_counter()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host='127.0.0.1', dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        client.submit(run_chunk, one, [0], pure=False).result()
        return time.perf_counter() - t0 - here


def print_end_to_end(campaign: Path, repeat: int, bsk: dict | None) -> None:
    times = end_to_end(campaign, repeat)
    runs = Campaign.load(campaign).runs
    print(f'adcs-montecarlo {campaign.name} --quiet, end to end ({runs} runs; median of {repeat}, [min-max]):')
    for scheduler, ts in times.items():
        wall, cpu = statistics.median(t[0] for t in ts), statistics.median(t[1] for t in ts)
        line = (f'  --scheduler {scheduler:5s}: {wall:.2f} s [{min(t[0] for t in ts):.2f}-{max(t[0] for t in ts):.2f}]'
                f' wall, {cpu:.2f} s CPU')
        if bsk is not None:
            line += (f';  Basilisk / this: {bsk["s_per_run"] * runs / wall:.0f}x wall, '
                     f'{bsk.get("cpu_s_per_run", math.nan) * runs / cpu:.0f}x CPU  (target >= 100)')
        print(line)
    print(f'  LocalCluster (2 workers) start-up to a first one-run chunk: {cluster_start(campaign):.2f} s '
          f'(scheduling.CLUSTER_START_S: {CLUSTER_START_S} s)')


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


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--campaign', type=Path, default=DEFAULT)
    parser.add_argument('--runs', type=int, default=None, help='first N runs only (default: all)')
    parser.add_argument('--basilisk', action='store_true', help='also time a sample of bsk 2.12.1 runs')
    parser.add_argument('--bsk-sample', type=int, default=5)
    parser.add_argument('--compare', type=Path, default=None, metavar='OLD_TREE',
                        help='also time the campaign in an old tree, alternated with this one')
    parser.add_argument('--repeat', type=int, default=5, help='--compare, --end-to-end: measurements of each')
    parser.add_argument('--fused-only', action='store_true', help='skip the (b) kernel and (c) numpy paths')
    parser.add_argument('--end-to-end', action='store_true',
                        help='time the adcs-montecarlo command itself (auto, none, local schedulers) and a '
                             "LocalCluster's start-up, then stop")
    return parser


def main() -> int:
    args = _parser().parse_args()
    if args.end_to_end:
        bsk = None
        if args.basilisk:
            bsk, why = basilisk_per_run(Campaign.load(args.campaign, runs=args.runs), args.bsk_sample)
            if bsk is None:
                print(f'Basilisk: not measured ({why})')
        print_end_to_end(args.campaign, args.repeat, bsk)
        return 0
    if args.compare is not None:
        times = compare_trees(args.campaign, args.runs, args.compare, args.repeat)
        bsk = None
        if args.basilisk:
            bsk, why = basilisk_per_run(Campaign.load(args.campaign, runs=args.runs), args.bsk_sample)
            if bsk is None:
                print(f'Basilisk: not measured ({why})')
        if not print_comparison(times, args.compare, bsk):
            return 1
        if args.fused_only:
            return 0
    t0, c0 = time.perf_counter(), time.process_time()
    campaign = Campaign.load(args.campaign, runs=args.runs)
    load = time.perf_counter() - t0   # reading the files and validating every run's draw, once
    load_cpu = time.process_time() - c0
    warm = Campaign.load(args.campaign, runs=min(campaign.chunk_size, campaign.runs))
    timed_campaign(warm, True)
    timed_campaign(warm, True, fused=False)
    fast, rows = timed_campaign(campaign, True)
    if args.fused_only:
        print(f'{args.campaign.name}: {campaign.runs} runs, Campaign.load {load:.2f} s, chunks {fast:.2f} s')
        return 0
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
