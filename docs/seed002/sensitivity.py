#!/usr/bin/env python3
"""Sensitivity of the ESEO slew (seed 002) to the choices the paper does not give: gains K1, K2,
lever arms, thrust mapping and deadzone. Batch engine (adcs_sim.app.batch.engine: the graph's own plant, law
and allocation with a leading batch axis) on config/eseo_backstepping_slew.yaml; writes
docs/seed002/sensitivity.md.

    .venv/bin/python docs/seed002/sensitivity.py [--duration 120]

Gains, lever arms and deadzone levels vary along the batch axis (one batch of 48 runs for the
gain x geometry grid); each thrust mapping is its own batch (not a batch parameter). Metrics per run: settling time (the eigenaxis error stays below 1 deg
from then on; adcs_sim.app.analysis.metrics.settling_time), total thruster impulse (N s), firings
(thruster-periods), and the largest error over the last 60 s.
"""
from __future__ import annotations

import argparse
import copy
import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))

from adcs_controllers.laws.backstepping import eseo_thruster_layout  # noqa: E402
from adcs_sim.app.analysis.metrics import attitude_errors_deg, settling_time  # noqa: E402
from adcs_sim.app.batch.engine import BatchSimulation  # noqa: E402
from adcs_sim.app.scenario.files import validate_scenario  # noqa: E402

SCENARIO = ROOT / 'config' / 'eseo_backstepping_slew.yaml'
CTRL = 'backstepping_controller'
K1S = (0.05, 0.1, 0.2, 0.4)
K2S = (2.0, 4.0, 8.0)
# (r_x, r_y, r_z) of eq. (21): kept, shorter yaw arm, shorter roll/pitch arm, in-face diagonal thrust
GEOMETRIES = ((0.3, -0.3, 0.4), (0.25, -0.25, 0.4), (0.3, -0.3, 0.3), (0.3, 0.1, 0.4))
LEVELS = (0.0013, 0.013, 0.026, 0.065)


def runs(base: dict, **vary) -> list[dict]:
    """One validated scenario per combination of ``vary`` ({section.key: values})."""
    keys = list(vary)
    out = []
    for combo in itertools.product(*vary.values()):
        r = copy.deepcopy(base)
        for key, value in zip(keys, combo):
            section, name = key.split(':')
            r[section][name] = value
        out.append(r)
    return out


def with_geometry(base: dict, rx: float, ry: float, rz: float) -> dict:
    p, d = eseo_thruster_layout(rx, ry, rz)
    r = copy.deepcopy(base)
    for section in ('dynamics', CTRL):
        r[section]['thrusters.positions'] = p.ravel().tolist()
        r[section]['thrusters.directions'] = d.ravel().tolist()
    return r


def metrics(batch_runs: list[dict]) -> list[dict]:
    result = BatchSimulation.from_runs(batch_runs).run()
    out = []
    for i in range(result.n_runs):
        run = result.run_data(i)
        eigen, _ = attitude_errors_deg(run)
        tail = run.t >= run.t_end - 60.0
        out.append({'settling': settling_time(run.t, eigen, 1.0),
                    'impulse': float(np.nansum(result.thruster_impulse[i, int(result.n_steps[i])])),
                    'firings': int(np.count_nonzero(result.thruster_on_time[i] > 0)),
                    'tail_max': float(eigen[tail].max())})
    return out


def fmt(m: dict) -> str:
    s = 'not settled' if not math.isfinite(m['settling']) else f"{m['settling']:.1f} s"
    return f"{s}, {m['impulse']:.2f} N s"


def gains_geometry_section(base: dict, t0: float) -> list[str]:
    """1. gains x geometry: one batch (lever arms, K1, K2 are all batch parameters)."""
    grid = [r for g in GEOMETRIES
            for r in runs(with_geometry(base, *g), **{f'{CTRL}:K1': K1S, f'{CTRL}:K2': K2S})]
    res_all = metrics(grid)
    per = len(K1S) * len(K2S)
    lines = []
    for gi, g in enumerate(GEOMETRIES):
        res = res_all[gi * per:(gi + 1) * per]
        lines += [f'## Gains, lever arms (r_x, r_y, r_z) = {g} m (r_x − r_y = {g[0] - g[1]:.2g} m)', '',
                  '| K1 (rad/s) \\ K2 (N m s) | ' + ' | '.join(f'{k:g}' for k in K2S) + ' |',
                  '| --- |' + ' --- |' * len(K2S)]
        for i, k1 in enumerate(K1S):
            cells = []
            for j, k2 in enumerate(K2S):
                m = res[i * len(K2S) + j]
                cell = f"{fmt(m)}, {m['firings']} firings"
                kept = g == GEOMETRIES[0] and k1 == 0.1 and k2 == 4.0
                cells.append(f'**{cell}**' if kept else cell)
            lines.append(f'| {k1:g} | ' + ' | '.join(cells) + ' |')
        lines.append('')
    print(f'gains x geometries ({len(grid)} runs, one batch): done ({time.monotonic() - t0:.0f} s)', flush=True)
    return lines


def mapping_section(base: dict, t0: float) -> list[str]:
    """2. thrust mapping: null-space shift vs opposed pairs, over the K1 grid (K2 = 4)."""
    lines = ['## Thrust mapping: null-space shift vs opposed pairs (K2 = 4 N m s)', '',
             '| K1 (rad/s) | nullspace | pairs |', '| --- | --- | --- |']
    res = {}
    for mapping in ('nullspace', 'pairs'):
        b = copy.deepcopy(base)
        b[CTRL]['allocation.mapping'] = mapping
        res[mapping] = metrics(runs(b, **{f'{CTRL}:K1': K1S}))
    for i, k1 in enumerate(K1S):
        cells = [f"{fmt(res[m][i])}, {res[m][i]['firings']} firings, tail max {res[m][i]['tail_max']:.2f}°"
                 for m in ('nullspace', 'pairs')]
        lines.append(f'| {k1:g} | ' + ' | '.join(cells) + ' |')
    lines.append('')
    print(f'mappings: done ({time.monotonic() - t0:.0f} s)', flush=True)
    return lines


def deadzone_section(base: dict) -> list[str]:
    """3. deadzone: bang-bang on level, no hysteresis."""
    lines = ['## Deadzone (bang-bang on level, no hysteresis; K1 = 0.1, K2 = 4)', '',
             '| on level (N) | settling, impulse | firings | tail max (°) |', '| --- | --- | --- | --- |']
    grid = []
    for lv in LEVELS:
        r = copy.deepcopy(base)
        r[CTRL]['firing.on_level'] = r[CTRL]['firing.off_level'] = lv
        grid.append(r)
    for lv, m in zip(LEVELS, metrics(grid)):
        row = f"| {lv:g} | {fmt(m)} | {m['firings']} | {m['tail_max']:.2f} |"
        lines.append(row.replace(f'| {lv:g} |', f'| **{lv:g}** |') if lv == 0.013 else row)
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--duration', type=float, default=120.0)
    ap.add_argument('--out', default=str(HERE / 'sensitivity.md'))
    args = ap.parse_args(argv)
    base = validate_scenario(SCENARIO)
    base.pop('recorder', None)
    base['dynamics']['duration'] = args.duration
    t0 = time.monotonic()
    lines = ['# Seed 002: sensitivity of the ESEO slew to our choices', '',
             f'Generated by `docs/seed002/sensitivity.py` (batch engine, `{SCENARIO.relative_to(ROOT)}`, '
             f'{args.duration:g} s runs; settling: eigenaxis error below 1° from then on; impulse: all '
             'four thrusters; "tail max": largest error over the last 60 s). Kept values in bold.', '']
    lines += gains_geometry_section(base, t0) + mapping_section(base, t0) + deadzone_section(base)
    lines += ['', f'Wall time: {time.monotonic() - t0:.0f} s.', '']
    Path(args.out).write_text('\n'.join(lines))
    print(f'wrote {args.out}')
    return 0

if __name__ == '__main__':
    raise SystemExit(main())
