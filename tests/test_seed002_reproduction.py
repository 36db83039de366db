"""Seed 002 (Kristiansen & Nicklasson, ESEO) reproduced through the ROS graph: bags/eseo_backstepping_slew.

The bag is an ``adcs-run`` of config/eseo_backstepping_slew.yaml (separate processes, lockstep;
bags/regenerate.py): the first 300 s of the two-orbit mission config/eseo_backstepping.yaml.
The tests read it and state the paper's figures beside ours (docs/seed002.md):

* paper: the 135.68° slew "settles within approximately 38 seconds" (Fig. 1); ours 38.126 s
  (1° eigenaxis band), asserted within half a second of the paper's (its precision);
* paper: the attitude is then held "constant over the entire orbit" (Fig. 2, two orbits); ours:
  below 1° after settling over the recorded 300 s (graph) and over 1000 s (batch engine, the
  same code; what a test of < 60 s allows here: ~2 ms per step); the whole two orbits through
  the graph (one run, 0.98° max after settling) are in docs/seed002.md;
* thruster impulse and firings: not given by the paper; ours pinned (the doc's digits; the count exactly);
* what the 38 s agreement means: the gains are ours (the paper gives none, ours chosen for fuel); the grid's
  settling times (30.0-63.8 s) bracket the paper's 38 s and 2 of its 12 pairs are within the paper's
  precision (the slew is thrust-saturated); the paper's own
  "q_i = [±1 0 0 0]" start: either sign gives the same run.

Also: the bag is what the current code computes (the batch engine, bit for bit), and a start
5° from q̃ = [-1, 0, 0, 0] goes there directly (no unwinding).
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from support.comparison import assert_recorded_run_equal, reference_comparison
from support.papers import SEED002_PAPER_SETTLING
from support.paths import ROOT

from adcs_sim.app.analysis.metrics import RunData, attitude_errors_deg, settling_time, thruster_metrics

pytestmark = pytest.mark.paper

BAG = ROOT / 'bags' / 'eseo_backstepping_slew'
# s, section 4.2 / Fig. 1 ("approximately 38 seconds"), from its one home, docs/seed002/paper.yaml
PAPER_SETTLING = SEED002_PAPER_SETTLING
OURS_SETTLING = 38.126         # s, 1° band (the committed bag's)
PAPER_PRECISION = 0.5          # s, "approximately 38 seconds": whole seconds
OURS_IMPULSE = 7.904           # N s over the recorded 300 s (all of it in the slew: none after 60 s)
OURS_FIRINGS = 608             # thruster-periods over the recorded 300 s
HOLD_HORIZON = 1000.0          # s, the batch hold test (a fifth of an orbit)


@pytest.fixture(scope='module')
def run() -> RunData:
    return RunData.from_bag(BAG / 'bag')


def test_slew_settles_like_the_paper(run):
    """Paper (section 4.2, Fig. 1): the 135.68° slew "settles within approximately 38 seconds". Ours:
    38.126 s (1° eigenaxis band against q_d(t), interpolated last exit). Tolerances: the initial
    error to 0.01° (the paper prints none: it follows from q_d, readings R1); ours to 1 ms, a
    regression value (the bag is deterministic: any change of law, plant or analysis moves it);
    the paper's to half a second, its precision ("approximately 38", whole seconds)."""
    eigen, _ = attitude_errors_deg(run)
    assert eigen[0] == pytest.approx(135.68, abs=0.01)   # the short way to q̃ = -1 (readings R1)
    ts = settling_time(run.t, eigen, 1.0)
    assert ts == pytest.approx(OURS_SETTLING, abs=1e-3)
    assert abs(ts - PAPER_SETTLING) <= PAPER_PRECISION


def test_paper_comparison_table_is_generated_by_adcs_analyze(tmp_path):
    """docs/seed002.md's settling row (paper / ours / difference) is ``adcs-analyze --compare --reference
    docs/seed002/paper.yaml`` on the committed bag (one bag is enough with a reference): the tracking error's
    1° settling against q_d(t), the metric a tracking report leads with, as the doc prints it."""
    paper = ROOT / 'docs' / 'seed002' / 'paper.yaml'
    text = reference_comparison([BAG / 'bag'], paper, tmp_path)
    assert '| eseo_backstepping_slew | `settling_eigenaxis_1deg_s` | 38 | 38.1257 | +0.3 % |' in text
    with open(tmp_path / 'reference_comparison.csv', newline='', encoding='utf-8') as f:
        (row,) = csv.DictReader(f)
    doc = (ROOT / 'docs' / 'seed002.md').read_text(encoding='utf-8')
    line = next(t for t in doc.splitlines() if t.startswith('| slew settling, 1° eigenaxis band against q_d(t) (s) |'))
    assert f'| {float(row["ours"]):.2f} (' in line and f'| {100 * float(row["relative_difference"]):+.1f} % |' in line


def test_attitude_held_after_settling(run):
    """Below 1° (the settling band) from the settling time to the end of the recording (0.98° at most). The law's
    own error on controller/status agrees with the analysis of the state to round-off (1e-12 deg, ~35 ulps of
    135°; observed 2.8e-14; was 1e-9, no reason). V2 (eq. 31) falls, 1.263 -> 7.3e-6 over the 300 s, pinned to
    half a unit of the digits docs/seed002.md prints (regression values of the deterministic bag; was "by 1e3",
    no reason; V2 is not monotone step by step: the thrusters are on / off)."""
    eigen, _ = attitude_errors_deg(run)
    ts = settling_time(run.t, eigen, 1.0)
    assert eigen[run.t >= ts].max() <= 1.0
    assert run.t_end == pytest.approx(300.0)
    status = run.controller_status
    angle = np.array([float(v['angle_deg']) for _, _, v in status])
    assert_allclose(angle, eigen[:len(angle)], atol=1e-12)
    V2 = np.array([float(v['V2']) for _, _, v in status])
    assert V2[-1] < V2[0] and abs(V2[0] - 1.263) <= 5e-4 and abs(V2[-1] - 7.3e-6) <= 5e-8, (V2[0], V2[-1])
    assert run.missed_steps == 0


def test_thruster_impulse_and_firings(run):
    """Paper: neither figure. Ours, regression values of the deterministic bag (was 1 % each, with no reason):
    the impulse 7.904 N s to half a unit of the digit docs/seed002.md prints (0.0005 N s; observed 7.904000),
    the firings, a count, exactly (608)."""
    m = thruster_metrics(run)
    assert abs(m['thruster_impulse_Ns'] - OURS_IMPULSE) <= 0.0005, m['thruster_impulse_Ns']
    assert m['thruster_firings'] == OURS_FIRINGS
    # each thruster's impulse = 0.13 N x its total on-time; every firing lasts a whole period
    assert_allclose(run.thruster_impulse[-1], 0.13 * run.thruster_on_time.sum(axis=0), rtol=1e-12)
    assert set(np.unique(run.thruster_on_time).tolist()) <= {0.0, 0.1}
    # the controller's firing count is the recorded one
    count = np.array([float(v['firing_count']) for _, _, v in run.controller_status])
    assert count[len(run.t_thrusters) - 1] == m['thruster_firings']


@pytest.mark.slow
def test_bag_is_the_batch_run(run):
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    sections = validate_scenario(BAG / 'scenario.yaml')
    batch = BatchSimulation.from_runs([sections]).run()
    b = batch.run_data(0)
    assert_recorded_run_equal(b.q, run.q)
    assert_recorded_run_equal(b.u, run.u)
    assert_recorded_run_equal(batch.thruster_impulse[0, 1:], run.thruster_impulse)


def _batch(duration: float, initial_attitude=None, initial_rate=None):
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    sections = validate_scenario(ROOT / 'config' / 'eseo_backstepping.yaml')
    sections.pop('recorder', None)
    d = sections['dynamics']
    d['duration'] = duration
    if initial_attitude is not None:
        d['initial.attitude'], d['initial.rate'] = list(initial_attitude), list(initial_rate)
    return BatchSimulation.from_runs([sections]).run()


@pytest.mark.slow
def test_attitude_held_after_settling_batch():
    """The hold of Fig. 2 by the batch engine (the graph's code; the whole two orbits through
    the graph: docs/seed002.md): settled within 60 s, then below 1° to 1000 s (a fifth of an
    orbit: the gravity gradient on the inertially held body has turned by 67°)."""
    result = _batch(HOLD_HORIZON)
    run = result.run_data(0)
    eigen, _ = attitude_errors_deg(run)
    ts = settling_time(run.t, eigen, 1.0)
    assert ts < 60.0
    assert eigen[run.t >= ts].max() <= 1.0
    assert run.t_end == pytest.approx(HOLD_HORIZON)


def test_start_near_minus_one_does_not_unwind():
    """q̃(0) = 5° from [-1, 0, 0, 0] (η̃ < 0), at rest in the orbit frame: the law goes to
    q̃ = -1 directly: the error never exceeds its start (ours: the max is the start, 5°), is inside the 1°
    settling band at 60 s (0.14°), with less impulse than the 135.68° slew (0.364 against 7.904 N s), where
    a law driving η̃ to +1 would turn 355°. (Was: never above 5.5°, < 1 N s: margins with no reason.)"""
    from adcs_core.attitude import quat_multiply, rotate_to_body
    q_d = np.array([-0.43289710176360546, 0.6644955512171767, 0.47829679781365786, -0.3771974746713605])
    e = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
    half = math.radians(2.5)
    qe0 = -np.r_[math.sin(half) * e, math.cos(half)]      # η̃ < 0
    q0 = quat_multiply(q_d, qe0)                            # q̄_d ⊗ q0 = q̃(0) (eq. 12)
    w0 = rotate_to_body(q0, np.array([0.0, -1.1699887158899546e-3, 0.0]))
    result = _batch(60.0, q0, w0)
    eigen, _ = attitude_errors_deg(result.run_data(0))
    assert eigen[0] == pytest.approx(5.0, abs=1e-6)
    assert eigen.max() <= eigen[0]
    assert eigen[-1] < 1.0
    assert np.nansum(result.thruster_impulse[0, -1]) < OURS_IMPULSE


def test_start_from_either_sign_of_q_is_the_same_run():
    """Paper (4.2): the body starts from "q_i = [±1 0 0 0]ᵀ": either sign is the same attitude and must give the
    same slew. Ours: the run from -q(0) is the run from +q(0) with q negated, the same errors, torques and
    thruster impulses bit for bit (negation is exact in floating point and the law uses sgn(η̃))."""
    from adcs_core.attitude import rotate_to_body
    w0 = rotate_to_body(np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.0, -1.1699887158899546e-3, 0.0]))
    plus = _batch(60.0, [0.0, 0.0, 0.0, 1.0], w0)
    minus = _batch(60.0, [0.0, 0.0, 0.0, -1.0], w0)
    a, b = plus.run_data(0), minus.run_data(0)
    assert_allclose(attitude_errors_deg(a)[0], attitude_errors_deg(b)[0], rtol=0, atol=1e-12)
    assert_allclose(a.u, b.u, rtol=0, atol=0)
    assert_allclose(a.q, -b.q, rtol=0, atol=0)
    assert_allclose(plus.thruster_impulse, minus.thruster_impulse, rtol=0, atol=0)


# The gain grid of docs/seed002_readings.md R9 (the paper gives no gains): K1 (rad/s) x K2 (N m s).
GRID_K1 = (0.05, 0.1, 0.2, 0.4)
GRID_K2 = (2.0, 4.0, 8.0)


def test_the_38s_agreement_to_the_papers_precision_holds_for_2_of_the_12_gain_pairs_of_the_grid():
    """What the 38 s agreement does and does not mean. The paper gives no K1, K2; ours (0.1, 4) were chosen on the
    R9 grid for fuel, not for the settling time. Over that grid (120 s, batch engine) the 1° settling time is
    30.0-63.8 s: the paper's 38 s lies inside the grid's range (an ordering: some gains give it, others do not,
    so the agreement does not identify the paper's gains), and within the paper's own precision, 38 ± 0.5 s
    ("approximately 38", whole seconds; the tolerance of test_slew_settles_like_the_paper), 2 of the 12 pairs
    settle: ours (38.13 s) and (0.1, 2) (37.97 s). The slew is thrust-saturated (~1-2 N m asked, ~0.07 N m
    available), so K1 = 0.1 with either K2 lands there; the other pairs miss it by 0.7-25.8 s. The count is robust
    to a moved thruster switch: the nearest pair to an edge of the band is 0.21 s (two control periods) away
    (38.71 s). (Was: 9 of 12 within ± 5 s and all in 25-70 s, bounds with no reason.)"""
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    runs = []
    for k1 in GRID_K1:
        for k2 in GRID_K2:
            sections = validate_scenario(ROOT / 'config' / 'eseo_backstepping.yaml')
            sections.pop('recorder', None)
            sections['dynamics']['duration'] = 120.0
            sections['backstepping_controller'].update({'K1': k1, 'K2': k2})
            runs.append(sections)
    result = BatchSimulation.from_runs(runs).run()
    ts = np.array([settling_time(result.run_data(i).t, attitude_errors_deg(result.run_data(i))[0], 1.0)
                   for i in range(len(runs))])
    print('1° settling over the grid (s):', np.round(ts, 2).reshape(len(GRID_K1), len(GRID_K2)).tolist())
    assert ts.min() < PAPER_SETTLING < ts.max()
    within = np.abs(ts - PAPER_SETTLING) <= PAPER_PRECISION
    pair = {(k1, k2): w for (k1, k2), w in zip([(a, b) for a in GRID_K1 for b in GRID_K2], within)}
    assert {p for p, w in pair.items() if w} == {(0.1, 4.0), (0.1, 2.0)}, ts
