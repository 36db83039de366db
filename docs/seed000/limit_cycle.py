#!/usr/bin/env python3
"""Seed 000, the showcase (config/uosat12_gsmn.yaml): where do the late oscillations come from?

At 10 000 s the recorded GSMN run still has x / y rates of about ±1.3 mrad/s, full ±20 mN m pulses and a
3.1° error. Each variant below is the showcase's two-wheel phase (started at rest at the attitude of t0,
as docs/seed000/sensitivity.py does: the same figures as the full run) with ONE thing changed, on the
batch engine (the graph's plant and law code); none is tuned towards a result:

* the recorded law (1 s sampling), and run to 30 000 s (is it a cycle, or a slow convergence?);
* the sampling: 0.25 s;
* epsilon of eq. 30: 1 N m (the high-gain law is always allowed);
* the zero-torque region: min-norm of u_lg alone (eq. 25 with the low gains: eq. 33's constraint
  V̇ ≤ V̇_ulg solved exactly, where eq. 30 turns the torque off on the sign of LgV u_hg);
* the singular term unsaturated (eq. 7: a1 = a2 = inf);
* the IV.B.2 denominator constant (q1² + q2² + 1e-3), the paper's way to make the origin an equilibrium;
* the snlc benchmark (eq. 24/31, low gains) and the zero-momentum law, for comparison.

Printed per variant: eigenaxis error at 2 000 / 5 000 / 9 500 s after t0, the unactuated q3 at the end,
the largest |w_x|, |w_y| (mrad/s) and |u_x|, |u_y| (mN m) over the last 2 000 s, and the fraction of those
steps in zero-torque mode.

    .venv/bin/python docs/seed000/limit_cycle.py [variant ...]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.analysis.metrics import attitude_errors, attitude_errors_deg
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES

ROOT = Path(__file__).resolve().parents[2]
PRINTED = np.array([0.2, 0.2, 0.2, 0.8246])
Q_T0 = PRINTED / np.linalg.norm(PRINTED)      # the attitude at t0 (readings R1(a))
DURATION = 9500.0                             # t0 = 500 s to 10 000 s
TAIL = 2000.0                                 # s, the window of the tail figures
GSMN = 'snlc_gsmn_controller'


def _given(controller: str = GSMN) -> dict:
    """The showcase's parameters started in the two-wheel phase at Q_T0, for ``controller``."""
    given = load_params_file(str(ROOT / 'config' / 'uosat12_gsmn.yaml'))
    given.pop('recorder', None)
    given['dynamics'].update({'initial.attitude': [float(v) for v in Q_T0], 'duration': DURATION})
    given['fault_injector']['schedule.time'] = [0.0]
    ctrl = given.pop(GSMN)
    ctrl['three_wheel.enabled'] = False
    if controller != GSMN:  # the low-gain (benchmark) gains of eq. 31 under the other laws' names
        low = {'k': ctrl['k1'], 'g': ctrl['g1'], 'K': ctrl['K1']}
        for key in ('k1', 'g1', 'K1', 'k2', 'g2', 'K2', 'epsilon'):
            ctrl.pop(key)
        if controller != 'snlc_minnorm_controller':
            ctrl.pop('gamma'), ctrl.pop('sigma')
        if controller == 'zero_momentum_controller':
            low.pop('K')
            ctrl['wheels.spin_inertia'] = given['dynamics']['wheels.spin_inertia']
        ctrl.update(low)
    given[controller] = ctrl
    return given


VARIANTS = {
    'recorded': ({}, {}, GSMN, DURATION),
    'recorded_30000s': ({}, {}, GSMN, 29500.0),
    'sampling_0.25s': ({'control_period': 0.25, 'integrator.max_step': 0.25}, {}, GSMN,
                       DURATION),
    'epsilon_1Nm': ({}, {'epsilon': 1.0}, GSMN, DURATION),
    'min_norm_of_u_lg': ({}, {}, 'snlc_minnorm_controller', DURATION),
    'unsaturated_eq7': ({}, {'a1': float('inf'), 'a2': float('inf')}, GSMN, DURATION),
    'eps_den_1e-3': ({}, {'eps_den': 1e-3}, GSMN, DURATION),
    'snlc_benchmark': ({}, {}, 'snlc_controller', DURATION),
    'zero_momentum': ({}, {}, 'zero_momentum_controller', DURATION),
}


def run(name: str) -> str:
    dyn, ctl, controller, duration = VARIANTS[name]
    given = _given(controller)
    given['dynamics'].update({**dyn, 'duration': duration})
    given[controller].update(ctl)
    sections = {n: NODES[n].schema.validate(v) for n, v in given.items()}
    modes: list[float] = []

    def observe(k, t, st):
        modes.append(float(np.asarray(st.get('mode', -1)).ravel()[0]))
    rd = BatchSimulation.from_runs([sections]).run(observe=observe).run_data(0)
    eig, _ = attitude_errors_deg(rd)
    qe, _, _ = attitude_errors(rd)
    at = [float(eig[np.searchsorted(rd.t, t) - 1]) for t in (2000.0, 5000.0, DURATION, duration)]
    tail, tail_u = rd.t >= rd.t[-1] - TAIL, rd.t_u >= rd.t[-1] - TAIL
    w = np.abs(rd.w[tail]).max(axis=0) * 1e3
    u = np.abs(rd.u[tail_u]).max(axis=0) * 1e3
    period = sections['dynamics']['control_period']
    zero = float(np.mean(np.array(modes[-int(TAIL / period):]) == 1.0)) if controller != 'zero_momentum_controller' \
        else float('nan')
    return (f'| {name} | ' + ' / '.join(f'{v:.3g}' for v in at) + f' | {qe[-1, 2]:.4f} | {w[0]:.3g} / {w[1]:.3g} '
            f'| {u[0]:.3g} / {u[1]:.3g} | {zero:.2f} |')


def main(names: list[str]) -> None:
    print('| variant | error (deg) at 2000 / 5000 / 9500 s / end after t0 | q3 end | tail max |w_x| / |w_y| '
          '(mrad/s) | tail max |u_x| / |u_y| (mN m) | zero-torque fraction (tail) |')
    print('|---|---|---|---|---|---|')
    for name in names or list(VARIANTS):
        print(run(name), flush=True)


if __name__ == '__main__':
    main(sys.argv[1:])
