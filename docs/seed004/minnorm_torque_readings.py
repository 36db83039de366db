"""Seed 004, III.F.2: is the standard min-norm law's integrated torque "the same" as the PD benchmark's?

The paper: min-norm's gains kp = 0.02, kd = 0.15 "were tuned to consume the same overall integrated torque as
the PD benchmark controller u1 ... by increasing the gains of the standard min-norm controller until the
overall torque reaches the same level as the PD law". Ours, as run (bags/microsat_minnorm_slew): 0.197 N m s
against PD's 0.268. This script keeps the paper's printed gains (kp, kd, and γ = 0.02, the only γ III.F.2
prints) and changes, one at a time, what the text leaves open, to see whether any reading gives the equality:

* the metric: ∫‖u‖dt (the size of the paper's 0.214 / 0.245), ∫uᵀu dt (III.D's definition, "∫ uᵀ(τ)u(τ)dτ")
  or ∫‖u‖₁dt (the three wheels' torques added);
* the torque limit: the wheels' 0.01 N m (III.F), or none (the law's demand applied: figure 3 shows the
  law's "higher initial torque value, potentially causing torque saturation", i.e. maybe an unsaturated run);
* how the demand is limited: per wheel (clip) or the whole vector scaled;
* the projection direction LgV: inertia_weighted (our default) or printed (I⁻¹);
* the control period: 0.1 s (the III.F reading) or 1 s (PD's bag).

Batch engine, the scenarios' own parameters otherwise. Also, for the record only (NOT a reading: it would
be tuning a gain the paper prints for the GSMN comparison), the γ that would make the two equal.

    .venv/bin/python docs/seed004/minnorm_torque_readings.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from adcs_sim.app.analysis.metrics import run_metrics, zoh_durations
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

ROOT = Path(__file__).resolve().parents[2]
MN, PD = 'minnorm_controller', 'pd_controller'
UNLIMITED = 1.0   # N m per wheel: above the law's 0.078 N m demand, so never binding


def scenario(name: str, period: float = 0.1, unlimited: bool = False, **controller) -> dict:
    """``config/<name>.yaml`` validated, at ``period`` (s), wheels unlimited if asked, controller keys set."""
    v = validate_scenario(ROOT / 'config' / f'{name}.yaml')
    v.pop('recorder', None)
    v['dynamics'].update({'control_period': period, 'integrator.max_step': period})
    law = MN if MN in v else PD
    if unlimited:
        v['dynamics']['wheels.max_torque'] = [UNLIMITED] * 3
        v[law]['wheels.max_torque'] = [UNLIMITED] * 3
    v[law].update(controller)
    return v


def figures(runs: list[dict]) -> list[tuple[float, float, float, float, float]]:
    """(∫‖u‖dt N m s, ∫uᵀu dt N² m² s, peak |u| N m, settling 0.5° s, ∫‖u‖₁dt N m s) of each run (one batch each: the
    runs differ in laws, periods and wheel limits, which one batch cannot hold)."""
    out = []
    for run in runs:
        data = BatchSimulation.from_runs([run]).run().run_data(0)
        m = run_metrics(data)
        l1 = float(np.sum(np.abs(data.u).sum(axis=-1) * zoh_durations(data.t_u, data.t_end)))
        out.append((m['integrated_torque_Nms'], m['control_energy_N2m2s'], max(m['peak_torque_Nm']),
                    m['settling_euler213_0.5deg_s'], l1))
    return out


READINGS = {  # label: (min-norm scenario kwargs, PD scenario kwargs)
    'as run (0.1 s, 0.01 N m, clip, inertia_weighted)': ({}, {}),
    'wheels unlimited (the law\'s demand applied)': ({'unlimited': True}, {'unlimited': True}),
    'demand scaled as a vector': ({'saturation': 'scale'}, {'saturation': 'scale'}),
    'LgV printed (I⁻¹)': ({'lgv': 'printed'}, {}),
    '1 s control period': ({'period': 1.0}, {'period': 1.0}),
    'unlimited, LgV printed': ({'unlimited': True, 'lgv': 'printed'}, {'unlimited': True}),
    'unlimited, 1 s': ({'unlimited': True, 'period': 1.0}, {'unlimited': True, 'period': 1.0}),
}


def readings_table() -> list[tuple[str, tuple, tuple]]:
    """Each reading's (label, min-norm figures, PD figures)."""
    runs = []
    for mn, pd in READINGS.values():
        runs += [scenario('microsat_minnorm_slew', **mn), scenario('microsat_pd_slew', **pd)]
    f = figures(runs)
    return [(label, f[2 * i], f[2 * i + 1]) for i, label in enumerate(READINGS)]


def gamma_for_equal_torque() -> list[tuple[float, float, float]]:
    """For the record (not adopted): min-norm's ∫‖u‖dt and settling over γ, as run otherwise."""
    gammas = (0.005, 0.01, 0.02, 0.04, 0.08, 0.16)
    f = figures([scenario('microsat_minnorm_slew', gamma=g) for g in gammas])
    return [(g, x[0], x[3]) for g, x in zip(gammas, f)]


def main() -> None:
    print('| reading | min-norm ∫‖u‖dt | PD ∫‖u‖dt | ratio | min-norm ∫uᵀu dt | PD ∫uᵀu dt | ratio '
          '| ∫‖u‖₁dt ratio | min-norm peak (N·m) | min-norm settling (s) |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    for label, mn, pd in readings_table():
        print(f'| {label} | {mn[0]:.3f} | {pd[0]:.3f} | {mn[0] / pd[0]:.2f} | {mn[1]:.2e} | {pd[1]:.2e} | '
              f'{mn[1] / pd[1]:.2f} | {mn[4] / pd[4]:.2f} | {mn[2]:.4f} | {mn[3]:.1f} |')
    print('\nγ (not a reading: tuning) | min-norm ∫‖u‖dt | settling (s)')
    for g, torque, ts in gamma_for_equal_torque():
        print(f'{g:g} | {torque:.3f} | {ts:.1f}')


if __name__ == '__main__':
    main()
