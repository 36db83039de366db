#!/usr/bin/env python3
"""What the viewer topics cost the lockstep loop: ``adcs-run`` (recorder included) of a scenario
with ``visualization.enabled`` true and false, alternately, ``--repeat`` times each.

The loop time is the dynamics node's own: from its ``lockstep run:`` log line (the graph is up,
step 0 is next) to its ``done at`` line (after the last step and the final acknowledgement
wait), both rcutils wall-clock timestamps in ``logs/dynamics.log``; steps/s = steps / that.
Start-up, the recorder's close and the runner's analysis are outside it.

    .venv/bin/python benchmarks/visualization_cost.py config/eseo_backstepping_slew.yaml --repeat 3
    .venv/bin/python benchmarks/visualization_cost.py config/microsat_pd_slew.yaml --duration 3000

``--baseline`` runs the scenario file unchanged, one column: with ``PYTHONPATH=<a checkout older
than the viewer topics>`` (the nodes inherit it) that is the code before them.

``--micro`` also times, in this process, what the dynamics node adds per step (CPU, not wall):
building and serialising the step's viewer messages (serialisation is what ``publish`` costs
on top of the middleware), beside the same for the step's ``state`` message.
"""
from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

STAMP = re.compile(r'\[INFO\] \[(\d+\.\d+)\] \[dynamics\]: (lockstep run: (\d+) steps|done at)')


def loop_rate(log: str) -> tuple[int, float]:
    """(steps, seconds) of the stepping loop from a dynamics log."""
    start = steps = end = None
    for m in STAMP.finditer(log):
        if m[3]:
            start, steps = float(m[1]), int(m[3])
        else:
            end = float(m[1])
    if start is None or end is None:
        raise RuntimeError(f'no lockstep run / done at lines in the dynamics log:\n{log[-1500:]}')
    return steps, end - start


def run_once(scenario: Path, enabled: bool | None, duration: float | None, work: Path) -> float:
    copy = scenario
    if enabled is not None:
        doc = yaml.safe_load(scenario.read_text())
        doc['dynamics']['ros__parameters'].setdefault('visualization', {})['enabled'] = enabled
        copy = work / f'{scenario.stem}_{"on" if enabled else "off"}.yaml'
        copy.write_text(yaml.safe_dump(doc, sort_keys=False))
    out = Path(tempfile.mkdtemp(dir=work))
    out.rmdir()
    cmd = [sys.executable, '-m', 'adcs_sim.app.graph.runner', str(copy), '--out', str(out), '--no-progress']
    if duration is not None:
        cmd += ['--duration', repr(duration)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f'adcs-run failed ({done.returncode}):\n{done.stderr[-2000:]}')
    steps, seconds = loop_rate((out / 'logs' / 'dynamics.log').read_text())
    bag = sum(f.stat().st_size for f in (out / 'bag').iterdir())
    what = {None: 'unchanged', True: 'visualization on ', False: 'visualization off'}[enabled]
    print(f'{what}: {steps} steps in {seconds:.3f} s -> '
          f'{steps / seconds:.0f} steps/s; bag {bag / 1e6:.2f} MB', flush=True)
    return steps / seconds


def micro(scenario: Path, steps: int = 2000) -> None:
    """Per-step CPU of the viewer messages of ``scenario``'s dynamics section (this process)."""
    from rclpy.serialization import serialize_message

    from adcs_msgs_py.conversions import state_to_msg
    from adcs_msgs_py.params_file import load_params_file
    from adcs_msgs_py.visual import VisualMessages
    from adcs_sim.truth.schema import DYNAMICS_SCHEMA, build_plant
    v = DYNAMICS_SCHEMA.validate(load_params_file(str(scenario))['dynamics'])
    plant = build_plant(v)
    wheels = next((a for a in plant.actuators if hasattr(a, 'spin_inertia')), None)
    thr = next((a for a in plant.actuators if hasattr(a, 'directions')), None)
    vis = VisualMessages([0.0, 0.0, 0.0, 1.0], 1.0, *((wheels.axes, wheels.spin_inertia, wheels.max_speed)
                         if wheels else (None,) * 3), *((thr.positions, thr.directions) if thr else (None,) * 2),
                         orbit=plant.orbit)
    q = np.array([0.1, 0.2, 0.3, 0.9]) / np.linalg.norm([0.1, 0.2, 0.3, 0.9])
    speed = np.ones(wheels.count if wheels else 0)
    on = np.ones(thr.count if thr else 0) * 0.1

    def viewer(k: int) -> None:
        t = k * 100_000_000
        serialize_message(vis.body_frame(t, q))
        if plant.orbit is not None:
            serialize_message(vis.orbit_frame(t))
        for msg in vis.errors(t, q):
            serialize_message(msg)
        if vis.markers.markers:
            serialize_message(vis.marker_array(t, speed, on))

    def state(k: int) -> None:
        serialize_message(state_to_msg(k * 100_000_000, q, np.zeros(3)))

    for name, f in (('viewer messages', viewer), ('state message (reference)', state)):
        t0 = time.process_time()
        for k in range(steps):
            f(k)
        print(f'{name}: {(time.process_time() - t0) / steps * 1e6:.0f} us CPU per step', flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('scenario', type=Path)
    ap.add_argument('--duration', type=float, default=None, help='override the simulated duration (s)')
    ap.add_argument('--repeat', type=int, default=2)
    ap.add_argument('--baseline', action='store_true', help='the scenario unchanged (no visualization key)')
    ap.add_argument('--micro', action='store_true', help="also time the viewer messages' CPU per step here")
    args = ap.parse_args(argv)
    if args.micro:
        micro(args.scenario)
    if args.baseline:
        with tempfile.TemporaryDirectory(prefix='viz_cost_') as tmp:
            rates = [run_once(args.scenario.resolve(), None, args.duration, Path(tmp)) for _ in range(args.repeat)]
        print(f'median of {args.repeat}: {statistics.median(rates):.0f} steps/s')
        return 0
    rates = {True: [], False: []}
    with tempfile.TemporaryDirectory(prefix='viz_cost_') as tmp:
        for _ in range(args.repeat):
            for enabled in (False, True):
                rates[enabled].append(run_once(args.scenario.resolve(), enabled, args.duration, Path(tmp)))
    off, on = statistics.median(rates[False]), statistics.median(rates[True])
    print(f'median of {args.repeat}: off {off:.0f} steps/s, on {on:.0f} steps/s ({100 * (on / off - 1):+.1f} %)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
