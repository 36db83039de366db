#!/usr/bin/env python3
"""The showcase's FULL graph against the transport's round trip, measured in the same run.

Issue 18: the stepping loop of ``config/uosat12_gsmn.yaml`` (10 000 steps of 1 s, RK4 max step
0.25 s, rw_z fails at 500 s, two-wheel GSMN law) run the way ``adcs-run`` runs it - recorder,
fault injector, dynamics and controller as four processes (``--no-progress``: without the runner's
``/clock`` progress bar, which only a terminal gets) - against the ping-pong round-trip rate of :mod:`lockstep_vs_pingpong` (two processes,
``nav_msgs/Odometry``, the lockstep QoS), alternated ``--repeat`` times (default 3) so that a change
of machine load hits both; medians compared. Each showcase run is bracketed by two ping-pongs (the
repeat's own and the next one's, a last one after the last repeat) and its ratio is taken against
their mean: this machine's speed drifts by tens of per cent within a minute, and a ping-pong of
a second measured only before a ten-second run often samples another phase of it.

Each showcase run is ``python -m adcs_sim.app.graph.runner <scenario> --out <tmp> --no-progress`` (its own
leased domain). Timed without touching the loop: the dynamics node's own figure in its log
(``done at ...; stepping loop X s``: monotonic clock from right before the step-0 state to right
after the last step's publications, so without start-up and without the final acknowledgement
wait). Also printed: start-up (runner launch to the dynamics' ``lockstep run:`` line, wall clock)
and the whole ``adcs-run`` wall time (start-up, loop, shutdown, metrics; no report).

``--pd`` also times the PD pair of :mod:`lockstep_vs_pingpong` (dynamics + pd_controller only,
observer-timed) in each repeat, for the same-run ratio of both graphs.

``--profile DIR`` runs the showcase once more with every node under cProfile
(:data:`adcs_sim.app.graph.processes.PROFILE_ENV`) and prints each process's top functions by own time.

``ratio = showcase steps/s / ping-pong round trips/s``: 1.0 would be a step that costs one round
trip and nothing else (issue 18 asks >= 0.7 of the raw rclpy ping-pong, rclpy's
SingleThreadedExecutor); also printed against the ping-pong on the nodes' own LockstepExecutor
(adcs_msgs_py/executor.py), the faster transport limit of this graph's processes;
``real time factor = simulated s / stepping-loop s``.
"""
from __future__ import annotations

import argparse
import itertools
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'benchmarks'))

import lockstep_vs_pingpong as lp  # noqa: E402

SHOWCASE = ROOT / 'config' / 'uosat12_gsmn.yaml'
NODES = ('dynamics', 'snlc_gsmn_controller', 'fault_injector', 'recorder')
RUN_LINE = re.compile(r'\[INFO\] \[(?P<t>[\d.]+)\] \[dynamics\]: lockstep run: (?P<n>\d+) steps')
DONE_LINE = re.compile(r'missed steps: (?P<missed>\d+); stepping loop (?P<loop>[\d.]+) s')


def run_showcase(out: Path, duration: float | None, env: dict, tree: Path = ROOT) -> dict:
    """One ``adcs-run`` of the showcase into ``out`` with the code of ``tree`` (default this
    checkout); its timings from the dynamics log."""
    cmd = [sys.executable, '-m', 'adcs_sim.app.graph.runner', str(tree / 'config' / SHOWCASE.name), '--out', str(out),
           '--no-progress']
    if tree != ROOT:   # the nodes, started with `python -m`, import from the same tree
        env = {**env, 'PYTHONPATH': str(tree)}
    if duration is not None:
        cmd += ['--duration', repr(duration)]
    env = {**env, 'RCUTILS_CONSOLE_OUTPUT_FORMAT': '[{severity}] [{time}] [{name}]: {message}'}
    launch, t0 = time.time(), time.monotonic()
    proc = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, timeout=3600)
    wall = time.monotonic() - t0
    if proc.returncode != 0:
        raise RuntimeError(f'adcs-run failed ({proc.returncode}):\n{proc.stdout[-1500:]}\n{proc.stderr[-1500:]}')
    log = (out / 'logs' / 'dynamics.log').read_text()
    run, done = RUN_LINE.search(log), DONE_LINE.search(log)
    if run is None or done is None:
        raise RuntimeError(f'no lockstep run / stepping loop lines in the dynamics log:\n{log[-1500:]}')
    steps, loop = int(run['n']), float(done['loop'])
    return {'steps': steps, 'seconds': loop, 'rate': steps / loop, 'missed': int(done['missed']),
            'startup': float(run['t']) - launch, 'wall': wall}


def median(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def print_profiles(folder: Path, top: int) -> None:
    import pstats
    for name in NODES:
        path = folder / f'{name}.prof'
        if not path.exists():
            print(f'\n--- {name}: no profile written')
            continue
        stats = pstats.Stats(str(path))
        print(f'\n--- {name}: {stats.total_tt:.2f} s of CPU under cProfile; top {top} by own time ---')
        stats.sort_stats('tottime').print_stats(top)


def _describe(tag: str, label: str, sh: dict) -> None:
    print(f'{tag} {label}: {sh["steps"]} steps in {sh["seconds"]:.3f} s of stepping loop -> {sh["rate"]:.0f} '
          f'steps/s ({1e6 / sh["rate"]:.0f} us each), real-time factor {sh["steps"] / sh["seconds"]:.0f}x '
          f'(1 s steps); missed {sh["missed"]}; start-up {sh["startup"]:.2f} s; adcs-run {sh["wall"]:.2f} s '
          'end to end', flush=True)


def _pingpongs(args, env: dict, runs: dict, tag: str) -> None:
    """One ping-pong on rclpy's executor and one on the nodes' LockstepExecutor, into ``runs``."""
    pp = lp.run_pingpong(env, args.round_trips, args.warmup)
    runs['pp'].append(pp['rate'])
    print(f'{tag} ping-pong : {pp["rate"]:.0f} round trips/s ({1e6 / pp["rate"]:.0f} us each)', flush=True)
    lean = lp.run_pingpong(env, args.round_trips, args.warmup, executor='lockstep')
    runs['pp_lean'].append(lean['rate'])
    print(f'{tag} ping-pong on the nodes\' LockstepExecutor: {lean["rate"]:.0f} round trips/s', flush=True)


def _repeats(args, env: dict, run_env: dict, tmp: Path) -> dict:
    """The alternated measurements: ping-pong, showcase (this tree), compared tree, PD pair; and a
    last ping-pong, so that every run has one before and one after it."""
    runs = {'pp': [], 'pp_lean': [], 'showcase': [], 'compared': [], 'pd': []}
    for i in range(args.repeat):
        tag = f'[{i + 1}/{args.repeat}]'
        _pingpongs(args, env, runs, tag)
        runs['showcase'].append(run_showcase(tmp / f'run{i}', args.duration, run_env))
        _describe(tag, 'showcase ', runs['showcase'][-1])
        if args.compare:
            runs['compared'].append(run_showcase(tmp / f'cmp{i}', args.duration, run_env, args.compare.resolve()))
            _describe(tag, 'compared ', runs['compared'][-1])
        if args.pd:
            pd = lp.run_lockstep(env, args.pd_duration)
            runs['pd'].append(pd['rate'])
            print(f'{tag} PD pair   : {pd["steps"]} steps in {pd["seconds"]:.3f} s -> {pd["rate"]:.0f} steps/s',
                  flush=True)
    _pingpongs(args, env, runs, '[after]')
    return runs


def bracketed(rates: list[float]) -> list[float]:
    """The ping-pong rate of each repeat's window: the mean of the round-trip rates measured right
    before and right after it (``rates`` has one more entry than there are repeats)."""
    return [(a + b) / 2 for a, b in itertools.pairwise(rates)]


def _summary(runs: dict, compare: Path | None) -> None:
    pps, shs, cmps, pds = bracketed(runs['pp']), runs['showcase'], runs['compared'], runs['pd']
    pp = statistics.median(pps)
    rate, startup, wall = (median(shs, k) for k in ('rate', 'startup', 'wall'))
    print(f'median      : ping-pong {pp:.0f} round trips/s; showcase {rate:.0f} steps/s; start-up '
          f'{startup:.2f} s; adcs-run {wall:.2f} s')
    per = ', '.join(f'{s["rate"] / p:.3f}' for s, p in zip(shs, pps))
    print(f'ratio       : showcase full graph / ping-pong = {rate / pp:.3f} (per repeat: {per}; median of the '
          f'per-repeat ratios {statistics.median(s["rate"] / p for s, p in zip(shs, pps)):.3f}; each against '
          'the mean of the ping-pongs before and after it)')
    leans = bracketed(runs['pp_lean'])
    lean = statistics.median(leans)
    per = ', '.join(f'{s["rate"] / p:.3f}' for s, p in zip(shs, leans))
    print(f'ratio       : showcase full graph / ping-pong on LockstepExecutor ({lean:.0f} round trips/s) = '
          f'{rate / lean:.3f} (per repeat: {per})')
    if cmps:
        c, c_startup, c_wall = (median(cmps, k) for k in ('rate', 'startup', 'wall'))
        per = ', '.join(f'{s["rate"] / p:.3f}' for s, p in zip(cmps, pps))
        print(f'ratio       : compared tree ({compare}) / ping-pong = {c / pp:.3f} (per repeat: {per}); this '
              f'tree / compared = {rate / c:.2f}; there start-up {c_startup:.2f} s, adcs-run {c_wall:.2f} s')
    if pds:
        per = ', '.join(f'{d / p:.3f}' for d, p in zip(pds, pps))
        print(f'ratio       : PD pair / ping-pong = {statistics.median(pds) / pp:.3f} (per repeat: {per})')


def _parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--duration', type=float, default=None, help='override the showcase duration (s)')
    ap.add_argument('--round-trips', type=int, default=5000)
    ap.add_argument('--warmup', type=int, default=200)
    ap.add_argument('--pd', action='store_true', help='also time the PD pair (lockstep_vs_pingpong)')
    ap.add_argument('--pd-duration', type=float, default=3000.0)
    ap.add_argument('--profile', type=Path, metavar='DIR', help='also one profiled showcase run')
    ap.add_argument('--top', type=int, default=20)
    ap.add_argument('--compare', type=Path, metavar='TREE',
                    help="also run the showcase with another checkout's code (e.g. the commit before a "
                         'change, `git archive <rev> | tar -x -C TREE`), alternated: before/after in one run')
    args = ap.parse_args()
    for name in ('repeat', 'round_trips', 'warmup'):
        if getattr(args, name) < (0 if name == 'warmup' else 1):
            ap.error(f'--{name.replace("_", "-")} must be at least {0 if name == "warmup" else 1}')
    return args


def main() -> int:
    args = _parse_args()
    from adcs_sim.app.graph.domains import DomainLease
    lease = DomainLease()
    env = lease.env()
    env.pop('FASTDDS_BUILTIN_TRANSPORTS', None)
    env['RCUTILS_CONSOLE_OUTPUT_FORMAT'] = lp.LOG_FORMAT
    env['PYTHONUNBUFFERED'] = '1'
    run_env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}   # adcs-run leases its own
    print(f'ping-pong on ROS_DOMAIN_ID={lease.domain_id}; {os.cpu_count()} CPUs, load average '
          f'{" ".join(f"{x:.2f}" for x in os.getloadavg())}', flush=True)
    try:
        with tempfile.TemporaryDirectory(prefix='showcase_graph_') as tmp:
            _summary(_repeats(args, env, run_env, Path(tmp)), args.compare)
            if args.profile:
                from adcs_sim.app.graph.processes import PROFILE_ENV
                args.profile.mkdir(parents=True, exist_ok=True)
                sh = run_showcase(Path(tmp) / 'profiled', args.duration,
                                  {**run_env, PROFILE_ENV: str(args.profile.resolve())})
                print(f'\nprofiled showcase: {sh["rate"]:.0f} steps/s under cProfile')
                print_profiles(args.profile, args.top)
    finally:
        lp._stop_all()
        lease.release()
    return 0


if __name__ == '__main__':
    sys.exit(main())
