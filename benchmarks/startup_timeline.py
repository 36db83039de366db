#!/usr/bin/env python3
"""Where the wall time of ``adcs-run config/microsat_pd_slew.yaml`` goes, from the command to its exit.

Issue 18 asks the PD slew (600 steps) in <= 5 s end to end. This benchmark runs it ``--repeat``
times (default 3) and prints a timeline: each phase of the runner and of every node process, in
wall seconds since the command was launched (medians over the repeats). With ``--compare TREE``
(e.g. ``/tmp/s9_base``, a checkout of an older commit) it alternates runs of that tree's code with
this one's, so that both see the same machine load, and prints both columns.

How it is timed without editing any node: each process of the run (the runner and the nodes it
starts, which inherit its environment) imports a ``sitecustomize`` written to a temporary folder
put first on ``PYTHONPATH``. It wraps, from outside, the functions whose entry or exit marks a
phase (``rclpy.init``, ``main_for``, the node's constructor, ``run``, ``close``, the plant kernel's
``warm``, the graph handshake's ``wait_for_publishers``, the dynamics' ``publish_state`` - its 1st
call is the t = 0 state, its 2nd the first completed step, the last the final one - and, in the
runner, validation, the domain lease, each ``Graph.start``, the wait for the recorder, the
supervision, the shutdown, the streamed metrics) and appends ``(wall time, pid, event)`` lines to
one file. Process start (exec) comes from ``/proc/<pid>/stat`` (10 ms ticks). The wrappers cost a
few microseconds per call. "interpreter exit" is the last ``atexit`` handler: a node started through
:mod:`adcs_sim.app.graph.launch` ends with ``os._exit`` once its ``main`` has returned and has none.

Also printed, measured apart (``python -X importtime``, one process each, warm file cache): the
import time of the runner and of each node module, with the largest top-level packages.

    .venv/bin/python benchmarks/startup_timeline.py [--repeat 3] [--compare /tmp/s9_base]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = 'config/microsat_pd_slew.yaml'
EVENTS_ENV = 'ADCS_TIMELINE_EVENTS'

# The hooks every process of a timed run imports first (sitecustomize): they only append events.
HOOKS = r'''
import os, sys, time
_T0 = time.time()
_FILE = os.environ.get('ADCS_TIMELINE_EVENTS')


def mark(event, t=None):
    if _FILE:
        fd = os.open(_FILE, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, f'{time.time() if t is None else t:.6f} {os.getpid()} {event}\n'.encode())
        finally:
            os.close(fd)


def _exec_time():
    with open('/proc/self/stat') as f:
        start = int(f.read().rsplit(')', 1)[1].split()[19])
    with open('/proc/stat') as f:
        btime = next(int(line.split()[1]) for line in f if line.startswith('btime'))
    return btime + start / os.sysconf('SC_CLK_TCK')


def wrap(owner, name, before=None, after=None, when=None):
    fn = getattr(owner, name, None)
    if fn is None or getattr(fn, '_timed', False):
        return
    def timed(*a, **k):
        on = when is None or when()
        if on and before:
            mark(before)
        try:
            return fn(*a, **k)
        finally:
            if on and after:
                mark(after)
    timed._timed = True
    setattr(owner, name, timed)


def _on_node_module(mod):
    import rclpy
    wrap(rclpy, 'init', 'rclpy.init', 'rclpy.init done')
    wrap(rclpy, 'try_shutdown', 'rclpy shutdown', 'rclpy shutdown done')
    wrap(mod.AdcsNode, 'wait_for_publishers', 'matching', 'matched')
    main_for = mod.main_for
    def timed_main_for(node_class, *a, **k):
        mark(f'name {node_class.schema.node}')
        mark('imports done')
        wrap(node_class, '__init__', None, 'node built')
        wrap(node_class, 'run', 'run', 'run done')
        wrap(node_class, 'close', 'close', 'close done')
        if hasattr(node_class, 'publish_state'):
            calls = [0]
            fn = node_class.publish_state
            def publish_state(self, *a, **k):
                calls[0] += 1
                out = fn(self, *a, **k)
                if calls[0] <= 2:
                    mark('state 0' if calls[0] == 1 else 'step 1 done')
                elif calls[0] == self.n_steps + 1:
                    mark('last step done')
                return out
            node_class.publish_state = publish_state
        try:
            return main_for(node_class, *a, **k)
        finally:
            mark('main returned')
    mod.main_for = timed_main_for


def _on_plant(mod):
    wrap(mod.Plant, 'warm', 'kernel load', 'kernel loaded')


def _on_runner(mod):
    wrap(mod, 'validate_scenario', 'validate', 'validated')
    wrap(mod, 'lease_domain', 'lease', 'leased')
    wrap(mod, '_start_graph', None, 'recorder ready seen')
    wrap(mod, '_supervise', 'supervise', 'dynamics exit seen')
    wrap(mod, '_stop_graph', 'stop graph', 'graph stopped')
    wrap(mod, 'analyse_bag', 'metrics', 'metrics done')   # (older trees: imported at the top)
    wrap(mod, 'format_metrics', 'print')
    graph = mod.Graph
    start = graph.start
    def timed_start(self, name, *a, **k):
        mark(f'spawn {name}')
        return start(self, name, *a, **k)
    graph.start = timed_start
    stop = graph.stop
    def timed_stop(self, name, *a, **k):
        mark(f'stop {name}')
        try:
            return stop(self, name, *a, **k)
        finally:
            mark(f'stopped {name}')
    graph.stop = timed_stop
    together = getattr(graph, 'stop_together', None)
    if together is not None:
        def timed_together(self, names, *a, **k):
            for name in names:
                mark(f'stop {name}')
            try:
                return together(self, names, *a, **k)
            finally:
                for name in names:
                    mark(f'stopped {name}')
        graph.stop_together = timed_together


def _on_stream_metrics(mod):
    wrap(mod, 'analyse_bag', 'metrics', 'metrics done')


def _on_analysis(mod):
    wrap(mod, 'format_metrics', 'print')


_HOOKED = {'adcs_msgs_py.node': _on_node_module, 'adcs_sim.truth.plant': _on_plant,
           'adcs_sim.app.graph.runner': _on_runner, 'adcs_sim.app.analysis.stream_metrics': _on_stream_metrics,
           'adcs_sim.app.analysis.metrics': _on_analysis}


class _Finder:
    """Runs a hook right after one of _HOOKED's modules has executed."""
    def find_spec(self, name, path=None, target=None):
        if name not in _HOOKED:
            return None
        import importlib.machinery
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None:
            return None
        loader = spec.loader
        exec_module = loader.exec_module
        def exec_and_hook(module):
            exec_module(module)
            _HOOKED[name](module)
        loader.exec_module = exec_and_hook
        return spec


if _FILE:
    sys.meta_path.insert(0, _Finder())
    mark('exec', _exec_time())
    mark('python ready', _T0)
    import atexit
    atexit.register(mark, 'exit')
'''

DRIVER = r'''
import sys, time
from sitecustomize import mark
t = time.time()
from adcs_sim.app.graph import runner
mark('name adcs-run')
mark('runner imports done')
code = runner.main(sys.argv[1:])
mark('main done')
sys.exit(code)
'''

# (label, process, event): the rows of the timeline, in the order of a run.
ROWS = [
    ('adcs-run: process start (exec)', 'adcs-run', 'exec'),
    ('adcs-run: python ready (site imported)', 'adcs-run', 'python ready'),
    ('adcs-run: imports done', 'adcs-run', 'runner imports done'),
    ('adcs-run: scenario validated', 'adcs-run', 'validated'),
    ('adcs-run: domain leased', 'adcs-run', 'leased'),
    ('adcs-run: spawn recorder', 'adcs-run', 'spawn recorder'),
    ('adcs-run: spawn dynamics (last)', 'adcs-run', 'spawn dynamics'),
    ('recorder: exec', 'recorder', 'exec'),
    ('recorder: imports done', 'recorder', 'imports done'),
    ('recorder: rclpy.init done', 'recorder', 'rclpy.init done'),
    ('recorder: node built (endpoints)', 'recorder', 'node built'),
    ('pd_controller: exec', 'pd_controller', 'exec'),
    ('pd_controller: imports done', 'pd_controller', 'imports done'),
    ('pd_controller: rclpy.init done', 'pd_controller', 'rclpy.init done'),
    ('pd_controller: node built', 'pd_controller', 'node built'),
    ('pd_controller: matched', 'pd_controller', 'matched'),
    ('dynamics: exec', 'dynamics', 'exec'),
    ('dynamics: imports done', 'dynamics', 'imports done'),
    ('dynamics: rclpy.init done', 'dynamics', 'rclpy.init done'),
    ('dynamics: node built', 'dynamics', 'node built'),
    ('dynamics: kernel loaded', 'dynamics', 'kernel loaded'),
    ('dynamics: matched (discovery)', 'dynamics', 'matched'),
    ('dynamics: state 0 out', 'dynamics', 'state 0'),
    ('adcs-run: recorder ready seen', 'adcs-run', 'recorder ready seen'),
    ('dynamics: step 1 done', 'dynamics', 'step 1 done'),
    ('dynamics: last step done', 'dynamics', 'last step done'),
    ('dynamics: run done (final acks)', 'dynamics', 'run done'),
    ('dynamics: main returned (node shut down)', 'dynamics', 'main returned'),
    ('dynamics: interpreter exit (atexit)', 'dynamics', 'exit'),
    ('adcs-run: dynamics exit seen', 'adcs-run', 'dynamics exit seen'),
    ('pd_controller: main returned', 'pd_controller', 'main returned'),
    ('pd_controller: interpreter exit (atexit)', 'pd_controller', 'exit'),
    ('adcs-run: controller stopped', 'adcs-run', 'stopped pd_controller'),
    ('recorder: run done (drained)', 'recorder', 'run done'),
    ('recorder: bag closed', 'recorder', 'close done'),
    ('recorder: main returned', 'recorder', 'main returned'),
    ('recorder: interpreter exit (atexit)', 'recorder', 'exit'),
    ('adcs-run: recorder stopped', 'adcs-run', 'stopped recorder'),
    ('adcs-run: metrics done (bag read)', 'adcs-run', 'metrics done'),
    ('adcs-run: printing', 'adcs-run', 'print'),
    ('adcs-run: exit', 'adcs-run', 'exit'),
]


def write_hooks(folder: Path) -> None:
    (folder / 'sitecustomize.py').write_text(HOOKS)
    (folder / 'timeline_driver.py').write_text(DRIVER)


def parse_events(path: Path, launch: float) -> dict[tuple[str, str], float]:
    """``(process, event) -> seconds since launch`` (first occurrence)."""
    names: dict[str, str] = {}
    rows = []
    for line in path.read_text().splitlines():
        t, pid, event = line.split(' ', 2)
        if event.startswith('name '):
            names[pid] = event[5:]
        rows.append((float(t), pid, event))
    out: dict[tuple[str, str], float] = {}
    for t, pid, event in rows:
        out.setdefault((names.get(pid, pid), event), t - launch)
    return out


def timed_run(tree: Path, hooks: Path, out: Path) -> tuple[dict, float, str]:
    """One ``adcs-run`` of the PD slew with ``tree``'s code; its events, wall time and stdout."""
    events = out.parent / f'{out.name}.events'
    env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}   # adcs-run leases its own
    env.update({'PYTHONPATH': f'{hooks}{os.pathsep}{tree}', EVENTS_ENV: str(events)})
    cmd = [sys.executable, str(hooks / 'timeline_driver.py'), str(tree / SCENARIO), '--out', str(out),
           '--no-progress']
    launch, t0 = time.time(), time.monotonic()
    proc = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, timeout=600)
    wall = time.monotonic() - t0
    if proc.returncode != 0:
        raise RuntimeError(f'adcs-run failed ({proc.returncode}):\n{proc.stdout[-1500:]}\n{proc.stderr[-1500:]}')
    return parse_events(events, launch), wall, proc.stdout


def import_times(tree: Path) -> list[str]:
    """``python -X importtime`` of the runner and each node module: total, and the largest
    top-level packages (cumulative, as the interpreter reports them)."""
    lines = []
    for module in ('adcs_sim.app.graph.runner', 'adcs_sim.nodes.recorder', 'adcs_sim.nodes.dynamics',
                   'adcs_controllers.nodes.pd_controller'):
        env = {**os.environ, 'PYTHONPATH': str(tree)}
        err = subprocess.run([sys.executable, '-X', 'importtime', '-c', f'import {module}'], env=env,
                             cwd=tree, capture_output=True, text=True).stderr
        total, top = 0.0, []
        for m in re.finditer(r'import time:\s+\d+ \|\s+(\d+) \| ( *)(\S+)', err):
            if m[3] == module and not m[2]:
                total = int(m[1]) / 1e6            # the module, all it imports included
            elif len(m[2]) == 2:
                top.append((int(m[1]) / 1e6, m[3]))   # what the module imports directly
        largest = ', '.join(f'{name} {t:.2f}' for t, name in sorted(top, reverse=True)[:6])
        lines.append(f'  {module:<28} {total:5.2f} s  ({largest})')
    return lines


def _median(runs: list[dict], key) -> float | None:
    values = [r[key] for r in runs if key in r]
    return statistics.median(values) if values else None


def _fmt(v: float | None) -> str:
    return '     -' if v is None else f'{v:6.2f}'


def print_timeline(columns: dict[str, list[dict]], walls: dict[str, list[float]]) -> None:
    labels = list(columns)
    print(f'\n{"phase (s since the command; medians)":<44}' + ''.join(f'{lab:>12}' for lab in labels))
    for label, proc, event in ROWS:
        print(f'{label:<44}' + ''.join(f'{_fmt(_median(columns[lab], (proc, event))):>12}' for lab in labels))
    print(f'{"end to end (command launch to its exit)":<44}'
          + ''.join(f'{_fmt(statistics.median(walls[lab])):>12}' for lab in labels))
    for lab in labels:
        print(f'  {lab}: end to end per repeat ' + ', '.join(f'{w:.2f}' for w in walls[lab]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--compare', type=Path, metavar='TREE',
                    help="also time another checkout's code (e.g. /tmp/s9_base), alternated with this one")
    ap.add_argument('--no-imports', action='store_true', help='skip the -X importtime figures')
    args = ap.parse_args()
    trees = {'this': ROOT}
    if args.compare:
        trees['compared'] = args.compare.resolve()
    print(f'{os.cpu_count()} CPUs, load average {" ".join(f"{x:.2f}" for x in os.getloadavg())}', flush=True)
    columns: dict[str, list[dict]] = defaultdict(list)
    walls: dict[str, list[float]] = defaultdict(list)
    metrics: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix='startup_timeline_') as tmp:
        hooks = Path(tmp) / 'hooks'
        hooks.mkdir()
        write_hooks(hooks)
        for i in range(args.repeat):
            for label, tree in trees.items():
                events, wall, stdout = timed_run(tree, hooks, Path(tmp) / f'{label}{i}')
                columns[label].append(events)
                walls[label].append(wall)
                metrics.setdefault(label, stdout.split('metrics:', 1)[-1])
                print(f'[{i + 1}/{args.repeat}] {label:<9}: adcs-run {wall:.2f} s end to end', flush=True)
    print_timeline(columns, walls)
    if 'compared' in metrics:
        print('metrics    : ' + ('identical in both trees' if metrics['this'] == metrics['compared']
                                 else 'DIFFER between the trees'))
    if 'compared' in walls:
        ratio = statistics.median(walls['this']) / statistics.median(walls['compared'])
        print(f'ratio      : this / compared end to end = {ratio:.2f}')
    if not args.no_imports:
        for label, tree in trees.items():
            print(f'\nimport times ({label}: {tree}; -X importtime, warm cache):')
            print('\n'.join(import_times(tree)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
