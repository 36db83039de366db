"""Seed 001, figure 3: the best δ of the k0 metric (eq. 27-29) under two readings of eq. 27-28.

    printed   α = δ u_max, β = (1 − δ) u_max    (eq. 27-28 as printed: α weights the attitude term Kp S)
    swapped   α = (1 − δ) u_max, β = δ u_max    (α and β exchanged: δ weights the rate term Kv ω)

Everything else is ``config/m2r_umax1.yaml`` (J of eq. 26, ω(0) = [1, −1, 0.5] rad/s, R_d = diag(1, −1, −1),
A = diag(1, 2, 3), f of eq. 25 with ω̄ = 0.2 rad/s, u_max = 1 N m, 0.1 s step), on the batch engine (the
graph's own plant and law code). k0 of eq. 29 in seconds (k0 steps × the step). Nothing is tuned: only α and
β differ between runs. The paper's figure 3 (best δ = 0.4) is the only number at stake: its curve is lost
in the extraction.

    .venv/bin/python docs/seed001/delta_readings.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from adcs_sim.app.analysis.metrics import k0_metric
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / 'config' / 'm2r_umax1.yaml'
READINGS = ('printed', 'swapped')
U_MAX = 1.0          # N m, the scenario's (figure 3's) saturation limit
DURATION = 300.0     # s simulated per δ: every k0 of the sweep is below it but δ = 0.1 (printed)


def alpha_beta(delta: float, reading: str) -> tuple[float, float]:
    """(α, β) of eq. 27-28 for ``delta`` under ``reading`` (α + β = u_max either way: Proposition 1's bound)."""
    a, b = delta * U_MAX, round(1.0 - delta, 12) * U_MAX
    if reading == 'printed':
        return a, b
    if reading == 'swapped':
        return b, a
    raise ValueError(f'reading must be one of {READINGS}, got {reading!r}')


def k0_sweep(deltas, reading: str, f: str = 'eq25', step: float | None = None,
             reduce: str = 'max') -> np.ndarray:
    """k0 (s) of eq. 29 for each δ (one batch); ``step`` overrides the control period and the integrator step
    (None: the scenario's 0.1 s); -1 where the error never meets eq. 29 within DURATION."""
    sections = validate_scenario(SCENARIO, duration=DURATION)
    if step is not None:
        sections['dynamics'].update({'control_period': step, 'integrator.max_step': step})
    dt = sections['dynamics']['control_period']
    schema = NODES['m2r_controller'].schema
    runs = []
    for d in deltas:
        alpha, beta = alpha_beta(float(d), reading)
        runs.append({'dynamics': sections['dynamics'],
                     'm2r_controller': schema.validate({**sections['m2r_controller'], 'alpha': alpha,
                                                        'beta': beta, 'f': f})})
    theta: list[np.ndarray] = []
    BatchSimulation.from_runs(runs).run(observe=lambda k, t, st: theta.append(np.array(st['theta'], dtype=float)))
    k0 = k0_metric(np.stack(theta).T, 200, 0.03, reduce)
    return np.where(k0 > 0, k0 * dt, -1.0)


def best_delta(deltas, k0: np.ndarray) -> float:
    return float(np.asarray(deltas)[int(np.argmin(np.where(k0 > 0, k0, np.inf)))])


def main() -> None:
    deltas = np.round(np.arange(0.1, 0.95, 0.1), 2)
    fine = np.round(np.arange(0.3, 0.71, 0.05), 2)
    print('| δ | k0 (s), printed | k0 (s), swapped |\n|---|---|---|')
    table = {r: k0_sweep(deltas, r) for r in READINGS}
    for i, d in enumerate(deltas):
        print(f'| {d:.1f} | ' + ' | '.join(f'{table[r][i]:.1f}' if table[r][i] > 0 else f'> {DURATION:g}'
                                          for r in READINGS) + ' |')
    for r in READINGS:
        print(f'best δ, {r}: {best_delta(deltas, table[r]):.2f} (0.1 grid)', end='; ')
        k = k0_sweep(fine, r)
        print(f'{best_delta(fine, k):.2f} (0.05 grid: ' + ', '.join(f'{d:.2f}: {v:.1f}' for d, v in zip(fine, k)) + ')')
    for step in (0.05, 0.01):
        k = {r: k0_sweep(deltas, r, step=step) for r in READINGS}
        print(f'step {step:g} s: best δ printed {best_delta(deltas, k["printed"]):.1f}, '
              f'swapped {best_delta(deltas, k["swapped"]):.1f}')
    k = {r: k0_sweep(deltas, r, reduce='mean') for r in READINGS}
    print(f'eq. 29 "mean" reading: best δ printed {best_delta(deltas, k["printed"]):.1f}, '
          f'swapped {best_delta(deltas, k["swapped"]):.1f}')
    k = {r: k0_sweep(deltas, r, f='eq24') for r in READINGS}
    print(f'f of eq. 24: best δ printed {best_delta(deltas, k["printed"]):.1f}, '
          f'swapped {best_delta(deltas, k["swapped"]):.1f}')


if __name__ == '__main__':
    main()
