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
from support.paths import ROOT

from adcs_sim.app.analysis.metrics import RunData, attitude_errors, attitude_errors_deg
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES

_spec = importlib.util.spec_from_file_location('limit_cycle', ROOT / 'docs' / 'seed000' / 'limit_cycle.py')
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)

K1, G1, A = 10.0, 0.08, 0.025      # N m s/rad, rad/s, - (config/uosat12_gsmn.yaml, the paper's VI.A gains)
U_MAX = 0.02                       # N m
PAPER_ACCURACY_DEG = 0.5           # deg, VI.A: its bands are "attitude errors of approximately 0.5 degree"


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


@pytest.mark.slow
def test_the_slow_tail_is_eq8s_saturation_and_the_low_gain_mode_not_a_bug():
    """The same two-wheel start (the showcase at t0), 5 000 s on the batch engine, one thing changed per run:
    as recorded 8.37° at the end; eq. 7 (a1 = a2 = inf) 1.6e-6°; the high gains allowed (epsilon = 1 N m) 1.96°
    (docs/seed000.md's table prints the sample one step before: 8.38 / 2e-6 / 1.92°).
    Asserted as what the paper says, no threshold of ours: section III, the saturated law ends "at a
    neighborhood of the origin, of which the amplitude depends on the saturation limit" (so without eq. 8's
    saturation the run comes closer: eq. 7 < printed); section V.B, the high gains "favor rapidity" (high gains
    < printed); and the accuracy VI.A names, "approximately 0.5 degree" (its bands are in fact 23° and 16°:
    docs/seed000.md), as the pointing the paper aims at: eq. 7 is inside it, the printed law is not
    (margins of 5 decades and 16 times: fresh batch runs through eq. 30's mode switches, which an ulp on
    another CPU may move, cannot cross them). (Was: > 5°, < 1e-3° and "under half", margins with no reason.)
    The law as printed (eq. 8 with the paper's a = 0.025 and eq. 30 with epsilon = the torque limit, where
    the high-gain mode is never entered: tests/test_seed000_reproduction.py::
    test_finding_the_printed_epsilon_never_admits_the_high_gain_mode) is what is slow."""
    given = study._given()
    given['dynamics']['duration'] = 5000.0
    runs = []
    for change in ({}, {'a1': float('inf'), 'a2': float('inf')}, {'epsilon': 1.0}):
        g = {n: dict(v) for n, v in given.items()}
        g[study.GSMN].update(change)
        runs.append({n: NODES[n].schema.validate(v) for n, v in g.items()})
    result = BatchSimulation.from_runs(runs).run()
    printed, eq7, high_gains = (attitude_errors_deg(result.run_data(i))[0][-1] for i in range(3))
    print(f'error at 5000 s after t0 (deg): printed {printed:.3g}, eq. 7 {eq7:.3g}, high gains {high_gains:.3g}')
    assert eq7 < printed                     # III: the saturation limit sets the residual
    assert high_gains < printed              # V.B: the high gains favour rapidity
    assert eq7 < PAPER_ACCURACY_DEG < printed  # VI.A's "approximately 0.5 degree"
