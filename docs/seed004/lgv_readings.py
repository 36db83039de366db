"""Seed 004, eq. (17): the two readings of the min-norm projection direction LgV on the paper's own GSMN figures.

    (a) 'printed'           LgV = (w + γq)ᵀ I⁻¹   (V of eq. 15; the paper's text)
    (b) 'inertia_weighted'  LgV = (w + γq)ᵀ       (V_I = c(1 - q4) + ½wᵀIw + γqᵀIw; the default: Table I)

Runs Table I's GSMN case (config/table1_gsmn.yaml) and section III.F's GSMN slew
(config/microsat_gsmn_slew.yaml) under each reading with the batch engine, the scenarios' own parameters
(nothing tuned; only the ``lgv`` key of the controller section differs), and prints per-axis signed peak
torques, ∫‖u‖dt and the settling times beside the paper's values (docs/seed004/paper.yaml). III.F is
also run at a 1 s control period (the paper gives none; the scenario reads 0.1 s, docs/seed004.md).

    .venv/bin/python docs/seed004/lgv_readings.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from adcs_controllers.laws.inverse_optimal import LGV_READINGS
from adcs_sim.app.analysis.metrics import RunData, run_metrics, settling_times
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

ROOT = Path(__file__).resolve().parents[2]
PAPER = yaml.safe_load((ROOT / 'docs' / 'seed004' / 'paper.yaml').read_text())['runs']
AXES = ('x', 'y', 'z')


def scenario_with(scenario: str, lgv: str, period: float | None = None) -> dict:
    """The validated ``config/<scenario>.yaml`` with the GSMN section's ``lgv`` set; ``period`` (s)
    overrides the control period and the integrator step (None: the scenario's)."""
    validated = validate_scenario(ROOT / 'config' / f'{scenario}.yaml')
    validated['gsmn_controller']['lgv'] = lgv
    if period is not None:
        validated['dynamics'].update({'control_period': period, 'integrator.max_step': period})
    return validated


def simulate(scenario: str, lgv: str, period: float | None = None) -> RunData:
    """The batch engine's run of :func:`scenario_with`."""
    return BatchSimulation.from_runs([scenario_with(scenario, lgv, period)]).run().run_data(0)


def peaks_signed(run: RunData) -> np.ndarray:
    """Per axis, the applied torque of largest magnitude with its sign (Table I prints signed peaks)."""
    u = run.u
    return u[np.abs(u).argmax(axis=0), [0, 1, 2]]


def per_axis_settling(run: RunData, tol: float) -> np.ndarray:
    """Settling time per body axis X, Y, Z (2-1-3 Euler angles; the library orders them y, x, z)."""
    y, x, z = settling_times(run, (tol,))[tol]['euler213_per_axis']
    return np.array([x, y, z])


def table1_figures(run: RunData) -> dict[str, np.ndarray | float]:
    """Table I's GSMN quantities of one run: signed peaks, ∫‖u‖dt, per-axis 1° / 0.5° settling."""
    return {'peak (N m)': peaks_signed(run), 'int |u| dt (N m s)': run_metrics(run)['integrated_torque_Nms'],
            'settling 1 deg (s)': per_axis_settling(run, 1.0), 'settling 0.5 deg (s)': per_axis_settling(run, 0.5)}


def table1_paper() -> dict[str, np.ndarray | float]:
    """The same quantities as printed in Table I (GSMN column; peaks are printed negative)."""
    p = PAPER['table1_gsmn']
    theta = {'x': 'theta1_x', 'y': 'theta2_y', 'z': 'theta3_z'}
    return {'peak (N m)': -np.array([p[f'peak_torque_{a}_Nm'] for a in AXES]),
            'int |u| dt (N m s)': p['integrated_torque_Nms'],
            'settling 1 deg (s)': np.array([p[f'settling_euler213_{theta[a]}_1deg_s'] for a in AXES]),
            'settling 0.5 deg (s)': np.array([p[f'settling_euler213_{theta[a]}_0.5deg_s'] for a in AXES])}


def iii_f_figures(run: RunData) -> dict[str, float]:
    """Section III.F's GSMN quantities: 0.5° settling on all three axes, ∫‖u‖dt, peak |u| (N m)."""
    m = run_metrics(run)
    return {'settling 0.5 deg all axes (s)': m['settling_euler213_0.5deg_s'],
            'int |u| dt (N m s)': m['integrated_torque_Nms'], 'peak |u|_inf (N m)': float(np.abs(run.u).max())}


def fmt(v) -> str:
    return ' / '.join(f'{x:.4g}' for x in np.atleast_1d(v))


def print_table(title: str, paper: dict, ours: dict[str, dict]) -> None:
    """A markdown table: one row per quantity, the paper's value then each reading's."""
    print(f'\n{title}\n')
    print('| quantity | paper | ' + ' | '.join(ours) + ' |')
    print('|---' * (2 + len(ours)) + '|')
    for key in next(iter(ours.values())):
        print(f'| {key} | {fmt(paper[key]) if key in paper else "-"} | '
              + ' | '.join(fmt(v[key]) for v in ours.values()) + ' |')


def main() -> None:
    t1 = {lgv: table1_figures(simulate('table1_gsmn', lgv)) for lgv in LGV_READINGS}
    print_table('Table I, GSMN (config/table1_gsmn.yaml, 1 ms period)', table1_paper(), t1)
    paper3 = {'settling 0.5 deg all axes (s)': PAPER['microsat_gsmn_slew']['settling_euler213_all_0.5deg_s'],
              'int |u| dt (N m s)': PAPER['microsat_gsmn_slew']['integrated_torque_Nms']}
    for period in (None, 1.0):
        f3 = {lgv: iii_f_figures(simulate('microsat_gsmn_slew', lgv, period)) for lgv in LGV_READINGS}
        label = "the scenario's 0.1 s period" if period is None else f'{period:g} s period (sensitivity)'
        print_table(f'III.F, GSMN (config/microsat_gsmn_slew.yaml, {label})', paper3, f3)


if __name__ == '__main__':
    main()
