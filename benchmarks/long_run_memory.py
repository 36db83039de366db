"""A long lockstep run through ``adcs-run`` with the peak memory of every node (issue #10 item 5).

Default: seed 004's PD scenario (config/microsat_pd_slew.yaml) at 10 Hz for 24 simulated hours
(864 000 steps, every message recorded). The script samples each process of the run once a
second from /proc (VmRSS now, VmHWM = peak resident set so far) and prints, per node, the peak
RSS and the RSS at a quarter, half and the end of the run: bounded memory means the later
samples do not keep growing with the number of steps. Then adcs-run's largest sampled RSS while
the nodes ran and after they stopped (its end-of-run analysis, issue #18 item 5: streamed, so it
no longer grows with the run). Not a test (it takes tens of minutes).

    .venv/bin/python benchmarks/long_run_memory.py [--hours 24] [--rate-hz 10] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def proc_mem(pid: int) -> tuple[float, float] | None:
    """(VmRSS, VmHWM) in MiB, or None if the process is gone."""
    try:
        fields = dict(line.split(':', 1) for line in Path(f'/proc/{pid}/status').read_text().splitlines())
        return int(fields['VmRSS'].split()[0]) / 1024, int(fields['VmHWM'].split()[0]) / 1024
    except (OSError, KeyError, ValueError):
        return None


def children(pid: int) -> dict[int, str]:
    out = subprocess.run(['ps', '-o', 'pid=,args=', '--ppid', str(pid)], capture_output=True, text=True).stdout
    kids = {}
    for line in out.strip().splitlines():
        child, args = line.strip().split(None, 1)
        module = next((a for a in args.split() if a.startswith(('adcs_sim.nodes.', 'adcs_controllers.nodes.'))), None)
        if module:
            kids[int(child)] = module.rsplit('.', 1)[-1]
    return kids


def phase_peaks(samples: dict) -> str | None:
    """adcs-run's largest sampled RSS while the nodes ran and after the last of them was gone (its
    end-of-run analysis: metrics, metrics.json), from the once-a-second samples."""
    nodes_end = max((rows[-1][0] for name, rows in samples.items() if name != 'adcs-run'), default=None)
    runner = samples.get('adcs-run', [])
    during = [r[1] for r in runner if nodes_end is None or r[0] <= nodes_end]
    after = [r[1] for r in runner if nodes_end is not None and r[0] > nodes_end]
    if not during or not after:
        return None
    return (f'adcs-run RSS: max {max(during):.1f} MiB while the nodes ran, max {max(after):.1f} MiB '
            f'after them ({len(after)} samples of its end-of-run analysis)')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--hours', type=float, default=24.0, help='simulated hours (default 24)')
    parser.add_argument('--rate-hz', type=float, default=10.0, help='control rate (default 10 Hz)')
    parser.add_argument('--scenario', type=Path, default=ROOT / 'config' / 'microsat_pd_slew.yaml')
    parser.add_argument('--out', type=Path, default=None, help='run folder (default: a temp folder)')
    args = parser.parse_args(argv)
    tree = yaml.safe_load(args.scenario.read_text())
    period = 1.0 / args.rate_hz
    dyn = tree['dynamics']['ros__parameters']
    dyn.update({'duration': args.hours * 3600.0, 'control_period': period,
                'integrator': {**dyn.get('integrator', {}), 'max_step': period}})
    work = Path(tempfile.mkdtemp(prefix='adcs_long_run_'))
    scenario = work / 'scenario.yaml'
    scenario.write_text(yaml.safe_dump(tree, sort_keys=False))
    out = args.out or work / 'run'
    steps = int(round(args.hours * 3600.0 / period))
    print(f'{args.scenario.name}: {args.hours:g} h at {args.rate_hz:g} Hz = {steps} steps -> {out}', flush=True)
    wall0 = time.monotonic()
    runner = subprocess.Popen([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                               '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    samples: dict[str, list[tuple[float, float, float]]] = {}   # node -> [(wall s, rss, hwm)]
    names: dict[int, str] = {}
    while runner.poll() is None:
        names.update(children(runner.pid))
        for pid, name in names.items():
            mem = proc_mem(pid)
            if mem is not None:
                samples.setdefault(name, []).append((time.monotonic() - wall0, *mem))
        mem = proc_mem(runner.pid)
        if mem is not None:
            samples.setdefault('adcs-run', []).append((time.monotonic() - wall0, *mem))
        try:
            runner.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            pass
    stdout, stderr = runner.communicate()
    wall = time.monotonic() - wall0
    print(f'adcs-run exit status {runner.returncode} after {wall:.0f} s wall '
          f'({steps / wall:.0f} steps/s, real-time factor {args.hours * 3600 / wall:.0f}x)')
    if runner.returncode != 0:
        print(stderr[-3000:], file=sys.stderr)
    print(f'{"node":<16} {"peak RSS MiB":>12} {"RSS @25%":>9} {"@50%":>7} {"@end":>7}')
    report = {}
    for name, rows in sorted(samples.items()):
        t_end = rows[-1][0]
        at = lambda f: min(rows, key=lambda r: abs(r[0] - f * t_end))[1]  # noqa: E731
        peak = max(r[2] for r in rows)
        report[name] = {'peak_rss_mib': peak, 'rss_25': at(0.25), 'rss_50': at(0.5), 'rss_end': rows[-1][1]}
        print(f'{name:<16} {peak:12.1f} {at(0.25):9.1f} {at(0.5):7.1f} {rows[-1][1]:7.1f}')
    phases = phase_peaks(samples)
    if phases:
        print(phases)
    metrics = out / 'metrics.json'
    if metrics.exists():
        m = json.loads(metrics.read_text())
        print(f'missed steps {m.get("missed_steps")}, bag {sum(f.stat().st_size for f in (out / "bag").iterdir()) / 2**20:.0f} MiB')
    (work / 'memory.json').write_text(json.dumps(report, indent=2))
    return runner.returncode


if __name__ == '__main__':
    raise SystemExit(main())
