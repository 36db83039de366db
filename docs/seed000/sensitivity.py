#!/usr/bin/env python3
"""Seed 000 VI.A: how the six settling times and ∫‖u‖dt depend on what the paper leaves open.

Runs the batch engine (the graph's own plant and law code, :mod:`adcs_sim.app.batch.engine`) on the three
VI.A scenarios started directly in the two-wheel phase: the Z wheel fails at t = 0 with the body
at rest at the attitude it had at t0 (the three-wheel PD phase of the scenarios ends at rest at
the off-pointing attitude to ~1e-9 rad/s, so this is the same run shifted by t0). Then varies one
thing at a time: the reading of the printed q(0), the attitude at t0 (random axes at the same
angle), the sampling time, eq. (7) vs (8), the wheels' spin inertia. Writes
``docs/seed000/sensitivity.md``.

    .venv/bin/python docs/seed000/sensitivity.py            # ~10 min on 2 cores
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from adcs_msgs_py.params_file import load_params_file  # noqa: E402
from adcs_sim.app.analysis.metrics import fault_metrics  # noqa: E402
from adcs_sim.app.batch.engine import BatchSimulation  # noqa: E402
from adcs_sim.app.scenario.registry import NODES  # noqa: E402

LAWS = {'zero momentum (eq. 13)': ('uosat12_zero_momentum', 'zero_momentum_controller'),
        'snlc (eq. 14/24)': ('uosat12_snlc', 'snlc_controller'),
        'GSMN (eq. 30-32)': ('uosat12_gsmn', 'snlc_gsmn_controller')}
PAPER = {'zero momentum (eq. 13)': (2452.1, 2956.5, 19.2), 'snlc (eq. 14/24)': (2918.8, 7072.9, 19.62),
         'GSMN (eq. 30-32)': (521.5, 1748.4, 9.84)}
PRINTED = np.array([0.2, 0.2, 0.2, 0.8246])
READINGS = {
    'R1(a) printed q(0) normalised (kept)': PRINTED / np.linalg.norm(PRINTED),
    'R1(b) vector part kept, q4 = sqrt(1 - 0.12)': np.array([0.2, 0.2, 0.2, np.sqrt(1 - 0.12)]),
    '"20 deg on all three axes", 2-1-3 Euler': Rotation.from_euler('YXZ', [20, 20, 20], degrees=True).as_quat(),
}
DURATION = 9500.0  # t0 = 500 s to 10 000 s


def sections(scenario: str, controller: str, q_t0, dynamics=None, control=None) -> dict:
    """Validated sections of ``scenario`` started in the two-wheel phase at attitude ``q_t0``
    (``dynamics`` / ``control``: more ``{dotted.name: value}`` for those sections)."""
    given = load_params_file(str(ROOT / 'config' / f'{scenario}.yaml'))
    given.pop('recorder', None)
    given['dynamics'].update({'initial.attitude': [float(v) for v in q_t0], 'duration': DURATION,
                              **(dynamics or {})})
    given['fault_injector']['schedule.time'] = [0.0]
    given[controller].update({'three_wheel.enabled': False, **(control or {})})
    return {name: NODES[name].schema.validate(values) for name, values in given.items()}


def figures(runs: list[dict]) -> np.ndarray:
    """(n, 3): q4 settling 0.02, 0.01 (s after the fault) and ∫‖u‖dt after it (N m s) per run."""
    result = BatchSimulation.from_runs(runs).run()
    out = []
    for i in range(len(runs)):
        m = fault_metrics(result.run_data(i))
        out.append([m['settling_q4_0.02_after_fault_s'], m['settling_q4_0.01_after_fault_s'],
                    m['integrated_torque_after_fault_Nms']])
    return np.array(out)


def fmt(row) -> str:
    return ' | '.join(f'{v:.1f}' if np.isfinite(v) else str(v) for v in row)


def random_axes(n: int, angle: float, seed: int = 0) -> np.ndarray:
    axes = np.random.default_rng(seed).normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return Rotation.from_rotvec(axes * angle).as_quat()


def main() -> int:
    q_kept = READINGS['R1(a) printed q(0) normalised (kept)']
    angle = 2 * np.arccos(q_kept[3])
    lines = ['# Seed 000 VI.A: sensitivity of the settling times and the integrated torque', '',
             'Made by `docs/seed000/sensitivity.py` (batch engine, the graph\'s code). Each row: q4 '
             'within 1 ± 0.02 / 1 ± 0.01 (s after t0) | ∫‖u‖dt from t0 to 10 000 s (N m s). '
             'Every run starts the two-wheel phase at rest at its attitude, 9500 s.', '']
    lines += ['## Paper', '', '| law | 0.02 | 0.01 | ∫‖u‖dt |', '|---|---|---|---|']
    lines += [f'| {law} | {fmt(PAPER[law])} |' for law in LAWS] + ['']

    lines += ['## Reading of the printed q(0)', '', '| law | reading | 0.02 | 0.01 | ∫‖u‖dt |',
              '|---|---|---|---|---|']
    for law, (scn, ctrl) in LAWS.items():
        rows = figures([sections(scn, ctrl, q) for q in READINGS.values()])
        lines += [f'| {law} | {name} | {fmt(r)} |' for name, r in zip(READINGS, rows)]
        print(law, 'readings done', flush=True)
    lines.append('')

    n = 100
    lines += [f'## Attitude at t0: {n} random axes at the same angle ({np.degrees(angle):.1f}°)', '',
              '| law | figure | mean | std | min | max |', '|---|---|---|---|---|---|']
    for law, (scn, ctrl) in LAWS.items():
        rows = figures([sections(scn, ctrl, q) for q in random_axes(n, angle)])
        for j, name in enumerate(('0.02 (s)', '0.01 (s)', '∫‖u‖dt (N m s)')):
            col = rows[:, j]
            lines.append(f'| {law} | {name} | {np.mean(col):.1f} | {np.std(col):.1f} | '
                         f'{np.min(col):.1f} | {np.max(col):.1f} |')
        print(law, 'random axes done', flush=True)
    lines.append('')

    lines += ['## Sampling time (zero-order hold, control period)', '', '| law | period (s) | 0.02 | 0.01 | ∫‖u‖dt |',
              '|---|---|---|---|---|']
    for law, (scn, ctrl) in LAWS.items():
        for period in (1.0, 2.0, 5.0, 10.0):
            step = min(0.25, period)
            r = figures([sections(scn, ctrl, q_kept, {'control_period': period, 'integrator.max_step': step})])[0]
            lines.append(f'| {law} | {period:g} | {fmt(r)} |')
        print(law, 'sampling done', flush=True)
    lines.append('')

    lines += ['## Other choices', '', '| law | variant | 0.02 | 0.01 | ∫‖u‖dt |', '|---|---|---|---|---|']
    for law, (scn, ctrl) in LAWS.items():
        variants = {'a1 = a2 = 0.025 (scenario)': {}, 'a1 = a2 = inf (eq. 7)': {'a1': float('inf'), 'a2': float('inf')},
                    'eps_den = 1e-3 (IV.B.2)': {'eps_den': 1e-3}}
        rows = figures([sections(scn, ctrl, q_kept, control=c) for c in variants.values()])
        lines += [f'| {law} | {name} | {fmt(r)} |' for name, r in zip(variants, rows)]
        if ctrl == 'zero_momentum_controller':
            for js in (0.005, 0.02):
                r = figures([sections(scn, ctrl, q_kept, {'wheels.spin_inertia': [js] * 3},
                                      {'wheels.spin_inertia': [js] * 3})])[0]
                lines.append(f'| {law} | wheel spin inertia {js} kg m² (scenario 0.01) | {fmt(r)} |')
        print(law, 'variants done', flush=True)
    lines.append('')
    out = ROOT / 'docs' / 'seed000' / 'sensitivity.md'
    out.write_text('\n'.join(lines) + '\n')
    print(f'wrote {out.relative_to(ROOT)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
