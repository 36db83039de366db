#!/usr/bin/env python3
"""Per-step cost of every control law on one run, against the plant's step measured in the same run.

Issue 18, item 2 ("laws fast enough for a 1 kHz loop"): for each scenario of ``config/`` with a
controller section (one per law family and configuration), the law object its node builds
(:data:`adcs_sim.app.scenario.registry.NODES` ``[section].family.build``) is called as the controller node
calls it, ``control(t, q, w)`` (plus the wheel momentum for the laws that need it), on one run at the
scenario's initial state; and the same scenario's plant is stepped over one control period
(``Plant.step``, the compiled kernel) as the dynamics node does. Prints µs per call of each and the
ratio law / plant, and whether the law fits a 1 kHz loop (< 1000 µs) on this machine now.

The two-wheel laws (seed 000 after a wheel failure, UK-DMC) are timed in their two-wheel mode:
``--after-fault`` (default on) fails the wheels the scenario's fault injector fails before timing.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adcs_sim.app.scenario.registry import NODES  # noqa: E402
from adcs_sim.app.scenario.files import validate_scenario  # noqa: E402
from adcs_sim.truth.fault_schedule import fault_schedule  # noqa: E402
from adcs_sim.truth.schema import build_plant, initial_state  # noqa: E402


def per_call_us(fn, repeats: int) -> float:
    """Median over 5 rounds of the mean time of ``repeats`` calls, in µs."""
    rounds = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeats):
            fn()
        rounds.append((time.perf_counter() - t0) / repeats * 1e6)
    return float(np.median(rounds))


def law_timer(sections: dict, controller: str, after_fault: bool):
    """A zero-argument call of the section's law as its node makes it, and a label."""
    law, act = NODES[controller].family.build(sections[controller])
    label = type(law).__name__
    act.inform(law)
    faults = next((s for s in sections if NODES[s].role == 'faults'), None)
    if after_fault and faults is not None:
        for _, snapshot in fault_schedule(sections[faults]):
            if act.follow_faults(snapshot):
                act.inform(law)
                label += ' (after the faults)'
    d = sections['dynamics']
    plant = build_plant(d)
    x = initial_state(plant, d)
    q, w = x[:4] / np.linalg.norm(x[:4]), x[4:7]
    if getattr(law, 'needs_wheel_momentum', False):
        h = act.wheel_momentum(np.zeros(len(act.wheel_names)))
        return (lambda: law.control(0.0, q, w, h)), label
    return (lambda: law.control(0.0, q, w)), label


def plant_timer(sections: dict):
    d = sections['dynamics']
    plant = build_plant(d)
    x = initial_state(plant, d)
    commands = plant.zero_commands()
    period, max_step = float(d['control_period']), float(d['integrator.max_step'])
    return lambda: plant.step(0.0, x, commands, period, max_step)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=300, help='calls per timing round')
    parser.add_argument('--before-fault', action='store_true', help='time the laws in their initial mode only')
    args = parser.parse_args()
    print(f'{"scenario":<36} {"law":<44} {"law us":>8} {"plant us":>9} {"law/plant":>9}  1 kHz')
    for path in sorted((ROOT / 'config').glob('*.yaml')):
        sections = validate_scenario(path)
        controller = next((s for s in sections if NODES[s].role == 'controller'), None)
        if controller is None:
            continue
        with np.errstate(all='ignore'):
            law, label = law_timer(sections, controller, not args.before_fault)
            law_us = per_call_us(law, args.repeats)
            plant_us = per_call_us(plant_timer(sections), args.repeats)
        print(f'{path.stem:<36} {label:<44} {law_us:8.0f} {plant_us:9.1f} {law_us / plant_us:9.1f}  '
              f'{"yes" if law_us < 1000 else "NO"}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
