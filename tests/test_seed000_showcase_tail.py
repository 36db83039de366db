"""Seed 000, the showcase (bags/uosat12_gsmn): what its last 2 000 s show, and where that comes from.

At 10 000 s the x / y rates still swing by about ±1.3 mrad/s with full ±20 mN m pulses and the error is 3.1°.
The tests show (docs/seed000.md, "The showcase's tail"; docs/seed000/limit_cycle.py for every variant):
the run is still converging on the unactuated axis, at the pace of eq. 8's saturated singular term (the
pulses are that saturated rate demand), and it is the law's: with eq. 7 (no saturation) or with the high
gains allowed the same start is at rest. No ROS (the bag, and the batch engine).
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from conftest import ROOT

from adcs_sim.app.analysis import RunData, attitude_errors, attitude_errors_deg
from adcs_sim.app.batch import BatchSimulation
from adcs_sim.app.registry import NODES

_spec = importlib.util.spec_from_file_location('limit_cycle', ROOT / 'docs' / 'seed000' / 'limit_cycle.py')
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)

K1, G1, A = 10.0, 0.08, 0.025      # N m s/rad, rad/s, - (config/uosat12_gsmn.yaml, the paper's VI.A gains)
U_MAX = 0.02                       # N m


def test_showcase_tail_is_the_saturated_singular_demand_and_still_converging():
    """The recorded run, 2 000 s windows from 4 000 s: the unactuated |q3| falls in every window (0.09 -> 0.06 ->
    0.04 -> 0.02) and so does the error (10.9 -> 7.8 -> 5.2 -> 3.1°, the last pinned to half a unit of the 3.1 the
    docs print, a regression value of the committed bag; was "> 1°", no reason), so at 10 000 s it is not a
    steady cycle. The x / y rates stay below the
    saturated singular term of eq. 8, g1 a = 2 mrad/s, plus k1 |q| (the desired rate's cap), and the pulses at
    the wheel limit are K1 times that demand (10 x 2 mrad/s = 20 mN m)."""
    run = RunData.from_bag(ROOT / 'bags' / 'uosat12_gsmn' / 'bag')
    qe, _, _ = attitude_errors(run)
    eig, _ = attitude_errors_deg(run)
    q3 = [np.abs(qe[(run.t >= t) & (run.t < t + 2000.0), 2]).max() for t in (4000.0, 6000.0, 8000.0)]
    assert q3[0] > q3[1] > q3[2] > np.abs(qe[-1, 2])
    e = [eig[(run.t >= t) & (run.t < t + 2000.0)].max() for t in (4000.0, 6000.0, 8000.0)]
    assert e[0] > e[1] > e[2] > eig[-1]
    assert abs(eig[-1] - 3.1) <= 0.05, eig[-1]
    tail = run.t >= 8000.0
    cap = G1 * A + 0.02 * np.abs(qe[tail, :2]).max()
    assert np.abs(run.w[tail, :2]).max() < cap
    assert np.abs(run.u[run.t_u >= 8000.0, :2]).max() == U_MAX
    assert K1 * G1 * A == pytest.approx(U_MAX, rel=1e-12)


def test_the_slow_tail_is_eq8s_saturation_and_the_low_gain_mode_not_a_bug():
    """The same two-wheel start (the showcase at t0), 5 000 s on the batch engine, one thing changed per run:
    as recorded 8.37° at the end; eq. 7 (a1 = a2 = inf) 1.6e-6°; the high gains allowed (epsilon = 1 N m) 1.96°
    (docs/seed000.md's table prints the sample one step before: 8.38 / 2e-6 / 1.92°). Fresh batch runs through
    eq. 30's mode switches, so no regression pin (an ulp across CPUs may move a switch): the thresholds are
    the claims' words with wide margins (degrees off: > 5°; at rest: < 1e-3°; much faster: under half).
    The law as printed (eq. 8 with the paper's a = 0.025 and eq. 30 with epsilon = the torque limit, where
    the high-gain mode is never entered) is what is slow; the paper itself says the saturated law ends in a
    limit cycle near the origin whose amplitude depends on the saturation limit (section III)."""
    given = study._given()
    given['dynamics']['duration'] = 5000.0
    runs = []
    for change in ({}, {'a1': float('inf'), 'a2': float('inf')}, {'epsilon': 1.0}):
        g = {n: dict(v) for n, v in given.items()}
        g[study.GSMN].update(change)
        runs.append({n: NODES[n].schema.validate(v) for n, v in g.items()})
    result = BatchSimulation.from_runs(runs).run()
    final = [attitude_errors_deg(result.run_data(i))[0][-1] for i in range(3)]
    assert final[0] > 5.0                    # printed law: still degrees off
    assert final[1] < 1e-3                   # eq. 7: at rest
    assert final[2] < 0.5 * final[0]         # high gains: much faster
