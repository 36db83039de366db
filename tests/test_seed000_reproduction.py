"""Seed 000 (Horri & Palmer) reproduced through the ROS graph: the recorded bags in bags/.

Each bag is an ``adcs-run`` of its config/ scenario (separate processes, lockstep; made by
bags/regenerate.py). The tests read the bags and check what holds of the paper's claims under our
readings (docs/seed000_readings.md), state the paper's figures beside ours (docs/seed000.md), and
check that the showcase bag is what the current code computes (the batch engine, bit for bit).

Paper, section VI.A (q4 settling from t0 = 500 s within 1 ± 0.02 / 1 ± 0.01; ∫‖u‖dt from t0):
GSMN 521.5 / 1748.4 s, 9.84 N m s; zero momentum 2452.1 / 2956.5 s, 19.2; snlc 2918.8 / 7072.9 s,
19.62. These numbers are NOT reproduced (the attitude at t0, the three-wheel phase, the wheels'
spin inertia and speed loop are not given): ours are pinned below as regression values to half a unit of
the digit docs/seed000.md prints, next to the paper's, and the qualitative claims are tested.
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.comparison import reference_comparison
from support.papers import SEED000_LAWS, SEED000_PAPER
from support.paths import ROOT

from adcs_sim.app.analysis.metrics import RunData, attitude_errors, fault_metrics

pytestmark = pytest.mark.paper

BAGS = ROOT / 'bags'
LAWS = SEED000_LAWS
# (q4 within 1 ± 0.02, within 1 ± 0.01 (s after t0), ∫‖u‖dt after t0 (N m s)): the paper's Table, from
# its one home, docs/seed000/paper.yaml (what the reports show beside ours)
PAPER = SEED000_PAPER
OURS = {'zero_momentum': (190.8, 1083.0, 29.78), 'snlc': (192.4, 1110.2, 24.02),
        'gsmn': (308.5, 944.1, 22.87)}
T0 = 500.0
U_MAX = 0.02


def load(name: str) -> RunData:
    return RunData.from_bag(BAGS / name / 'bag')


@pytest.fixture(scope='module')
def runs() -> dict[str, RunData]:
    return {law: load(name) for law, name in LAWS.items()}


def figures(run: RunData) -> tuple[float, float, float]:
    m = fault_metrics(run)
    return (m['settling_q4_0.02_after_fault_s'], m['settling_q4_0.01_after_fault_s'],
            m['integrated_torque_after_fault_Nms'])


@pytest.mark.parametrize('law', list(LAWS))
def test_three_axis_stabilisation_with_two_wheels(runs, law):
    """VI.A: "the attitude is stabilized on all three axes with admissible torque": from t0 the
    run enters and stays in both of the paper's q4 bands (all three axes: 1 - q4 bounds the whole
    rotation), no z torque, no wheel above its limit, the unactuated q3 smaller at the end than at t0
    (ours: 1e-7 of it for zero momentum and snlc, 0.105 for GSMN, still converging:
    tests/test_seed000_showcase_tail.py). The end inside the paper's fine band 1 - q4 < 0.01 (ours 4.6e-9,
    1.7e-9, 3.6e-4). Both were thresholds with no reason (q3 < 0.15 x, 1 - q4 < 0.001): now the claim's
    ordering and the paper's own band."""
    run = runs[law]
    m = fault_metrics(run)
    assert m['first_fault_time_s'] == T0
    assert math.isfinite(m['settling_q4_0.02_after_fault_s'])
    assert math.isfinite(m['settling_q4_0.01_after_fault_s'])
    after = run.t_u >= T0
    assert np.all(run.u[after, 2] == 0.0)
    assert np.abs(run.u).max() <= U_MAX + 1e-12
    qe, _, _ = attitude_errors(run)
    k0 = int(np.flatnonzero(run.t == T0)[0])
    assert abs(qe[-1, 2]) < abs(qe[k0, 2])
    assert 1.0 - abs(qe[-1, 3]) < 0.01  # the paper's 1 ± 0.01 band on q4


@pytest.mark.parametrize('law', list(LAWS))
def test_settling_and_torque_beside_the_paper(runs, law):
    """Our figures beside the paper's (printed for the record), pinned as regression values to half a
    unit of the last digit docs/seed000.md prints (0.05 s, 0.005 N m s): the bags are deterministic,
    so any change of law, plant or analysis that moves a figure of the doc fails here."""
    ours = figures(runs[law])
    print(f'{law}: paper {PAPER[law]}, ours {tuple(round(v, 1) for v in ours)}')
    for value, pinned, half_digit in zip(ours, OURS[law], (0.05, 0.05, 0.005)):
        assert abs(value - pinned) <= half_digit, (value, pinned)


def test_gsmn_settles_first_in_the_fine_band(runs):
    """VI.A: in the 1 ± 0.01 band the GSMN law settles first (paper: 1748.4 s against 2956.5 and
    7072.9 s). Holds here (944 against 1083 and 1110 s), by a smaller margin."""
    fine = {law: figures(run)[1] for law, run in runs.items()}
    assert fine['gsmn'] < fine['zero_momentum'] and fine['gsmn'] < fine['snlc']


def test_disagreement_gsmn_is_not_first_in_the_coarse_band(runs):
    """DISAGREEMENT with VI.A, pinned: the paper has GSMN first in the 1 ± 0.02 band too (521.5 s
    against 2452.1 and 2918.8 s); here it is last (308.5 s against 190.8 and 192.4 s:
    docs/seed000.md, "What does not hold here")."""
    coarse = {law: figures(run)[0] for law, run in runs.items()}
    assert coarse['gsmn'] > coarse['zero_momentum'] and coarse['gsmn'] > coarse['snlc']


def test_gsmn_needs_the_least_integrated_torque(runs):
    """VI.A: "a lower level of the integrated torque of 9.84 N m s, compared to 19.62 N m s" (snlc)
    and 19.2 (zero momentum): GSMN uses the least torque here too (22.9 against 24.0 and 29.8)."""
    torque = {law: figures(run)[2] for law, run in runs.items()}
    assert torque['gsmn'] < torque['snlc'] and torque['gsmn'] < torque['zero_momentum']


def test_disagreement_snlc_needs_less_torque_than_zero_momentum(runs):
    """DISAGREEMENT with VI.A, pinned: the paper's snlc uses slightly MORE torque than zero momentum
    (19.62 against 19.2 N m s); ours uses less (24.0 against 29.8)."""
    torque = {law: figures(run)[2] for law, run in runs.items()}
    assert PAPER['snlc'][2] > PAPER['zero_momentum'][2]
    assert torque['snlc'] < torque['zero_momentum']


def test_gsmn_has_zero_torque_phases(runs):
    """VI.A: the min-norm law "remains stable despite several horizontal zero torque phases": the
    status switches between the projected low-gain torque and zero torque many times, the torque
    is exactly zero then. "Several" asserted as at least two zero-torque phases; ours, 455 switches (a count
    of the deterministic bag, docs/seed000.md), exactly (was: > 50, with no reason)."""
    run = runs['gsmn']
    status = [(t, v) for t, _, v in run.controller_status if t >= T0]
    modes = [v['mode'] for _, v in status]
    switches = sum(a != b for a, b in zip(modes, modes[1:]))
    assert {'low_gain', 'zero_torque'} <= set(modes) and switches == 455
    assert sum(a != 'zero_torque' and b == 'zero_torque' for a, b in zip(modes, modes[1:])) >= 2
    zero_t = {t for t, v in status if v['mode'] == 'zero_torque'}
    k = np.isin(run.t_u, sorted(zero_t))
    assert np.all(run.u[k] == 0.0)
    assert {v['phase'] for _, v in status} == {'two_wheel'}


# VI.A's GSMN gains (config/uosat12_gsmn.yaml, the paper's list): high-gain K2 (N m s/rad), g2, k2 (rad/s), eq. 8's a
K2, G2, K2_ATT, A_SAT, EPSILON = 10.0, 1.2, 0.2, 0.025, 0.02
INERTIA = np.diag([40.45, 42.09, 42.36])   # kg m^2, VI.A
MIN_U_HG = 0.265                           # N m, ours: min ||u_hg||inf after t0, as docs/seed000.md prints it


def test_finding_the_printed_epsilon_never_admits_the_high_gain_mode(runs):
    """FINDING about the printed parameters (not a disagreement with a printed figure): eq. 30 enters the high-gain
    mode only where ||u_hg||inf < epsilon, and with VI.A's epsilon = 0.02 (read as N m, the wheel limit; readings
    R6) that never happens. Section V.B says the high gains are used "whenever there are no torque saturation
    issues"; VI.A never says the mode is entered in its run (its text and figures 5, 6 and 9 speak of the torque
    and the "horizontal zero torque phases"), so nothing printed is contradicted: the mode is unreachable.
    Closed form: near the x-y origin eq. 8's singular ratio sits at its limit a and omega, q1, q2 -> 0, so
    u_hg,i = -K2 (omega_i + k2 q_i -/+ g2 a) + I_i wd_dot_i -> +/-K2 g2 a = 10 x 1.2 x 0.025 = 0.3 N m = 15 epsilon.
    Checked three ways: the closed form; the law (eq. 32 through adcs_controllers' snlc) at a state 1e-9 from
    the origin gives +/-0.3 N m to K2 k2 1e-9; on every recorded step after t0 (ratio saturated on 98.5 % of them)
    ||u_hg||inf >= 0.265 N m (ours, pinned to half a unit of the digit docs/seed000.md prints: 0.0005 N m),
    above epsilon, and the status never reports `high_gain`. With epsilon = 1 N m the mode is entered and the
    run comes to rest (tests/test_seed000_showcase_tail.py)."""
    from adcs_controllers.laws.underactuated import snlc_torque
    assert K2 * G2 * A_SAT == pytest.approx(0.3, rel=1e-12) and K2 * G2 * A_SAT > EPSILON
    u0, _ = snlc_torque(np.array([1e-9, 1e-9, 1e-3, 1.0]), np.zeros(3), INERTIA, K2_ATT, G2, K2, A_SAT, A_SAT)
    assert np.abs(u0[:2]) == pytest.approx([K2 * G2 * A_SAT] * 2, abs=2 * K2 * K2_ATT * 1e-9)
    run = runs['gsmn']
    after = run.t >= T0
    u_hg, _ = snlc_torque(run.q[after], run.w[after], INERTIA, K2_ATT, G2, K2, A_SAT, A_SAT)
    floor = np.abs(u_hg).max(axis=-1).min()
    print(f'min ||u_hg||inf after t0: {floor:.4f} N m (epsilon {EPSILON} N m; K2 g2 a = {K2 * G2 * A_SAT:.3f})')
    assert floor > EPSILON
    assert abs(floor - MIN_U_HG) <= 0.0005, floor
    assert 'high_gain' not in {v['mode'] for t, _, v in run.controller_status if t >= T0}


def test_paper_comparison_table_is_generated_by_adcs_analyze(tmp_path):
    """docs/seed000.md's paper / ours / difference rows are ``adcs-analyze --compare --reference
    docs/seed000/paper.yaml`` on the three committed bags (the q4 settling and ∫‖u‖dt after the fault,
    the metrics the reports lead with): these rows as the doc prints them, so the doc cannot drift from the bags."""
    bags = [str(BAGS / name / 'bag') for name in LAWS.values()]
    paper = ROOT / 'docs' / 'seed000' / 'paper.yaml'
    text = reference_comparison(bags, paper, tmp_path)
    for row in ('| uosat12_zero_momentum | `settling_q4_0.02_after_fault_s` | 2452.1 | 190.766 | -92.2 % |',
                '| uosat12_snlc | `integrated_torque_after_fault_Nms` | 19.62 | 24.0243 | +22.4 % |',
                '| uosat12_gsmn | `settling_q4_0.01_after_fault_s` | 1748.4 | 944.1 | -46.0 % |',
                '| uosat12_gsmn | `integrated_torque_after_fault_Nms` | 9.84 | 22.8656 | +132.4 % |'):
        assert row in text
    # and every one of the nine rows of docs/seed000.md, rounded as it prints them, is the tool's
    doc = (ROOT / 'docs' / 'seed000.md').read_text(encoding='utf-8')
    label = {'uosat12_zero_momentum': 'zero momentum', 'uosat12_snlc': 'snlc', 'uosat12_gsmn': 'GSMN'}
    what = {'settling_q4_0.02_after_fault_s': ('q4 in 1 ± 0.02 after t0 (s)', 1),
            'settling_q4_0.01_after_fault_s': ('q4 in 1 ± 0.01 after t0 (s)', 1),
            'integrated_torque_after_fault_Nms': ('∫‖u‖dt after t0 (N·m·s)', 2)}
    with open(tmp_path / 'reference_comparison.csv', newline='', encoding='utf-8') as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    for r in rows:
        text, digits = what[r['metric']]
        diff = f'{100 * float(r["relative_difference"]):+.1f} %'.replace('-', '\u2212')
        row = f'| {label[r["run"]]}: {text} | {r["published"]} | {float(r["ours"]):.{digits}f} | {diff} |'
        assert row in doc, row


@pytest.mark.slow
def test_showcase_bag_is_what_the_code_computes():
    """bags/uosat12_gsmn is the batch engine's run of its scenario, bit for bit (same plant, law,
    allocation and fault schedule): the recording is current."""
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    bag = load('uosat12_gsmn')
    batch = BatchSimulation.from_runs([validate_scenario(BAGS / 'uosat12_gsmn' / 'scenario.yaml')]).run()
    run = batch.run_data(0)
    assert_array_equal(run.q, bag.q)
    assert_array_equal(run.u, bag.u)


# ours, as docs/seed000.md prints them: eigenaxis error max over the 1st / 2nd orbit (°), wheel speed max (rad/s)
IN_ORBIT = {'uosat12_sun_tracking': (35.0, 9.2, 71.9), 'ukdmc_two_wheels': (39.6, 16.2, 12.1)}


@pytest.mark.parametrize('name', list(IN_ORBIT))
def test_in_orbit_cases_have_bounded_errors(name):
    """VI.B: "controlling the unactuated axis within bounded errors" with measurement noise, the
    gravity-gradient torque and a bias momentum that breaks the zero-momentum assumption. The paper prints no
    bound: the claim is asserted as the second orbit's eigenaxis error no larger than the first's and the
    wheels below their 5000 rpm (523.6 rad/s). Ours (35.0 / 9.2° with wheels 71.9 rad/s; 39.6 / 16.2° with
    12.1 rad/s) pinned to half a unit of the digit docs/seed000.md prints (0.05° and 0.05 rad/s), regression values
    of the deterministic bags. (Was: the 2nd orbit below 15° / 45° and the wheels below 20 % of their limit,
    thresholds with no reason.)"""
    run = load(name)
    _, eigen, _ = attitude_errors(run)
    half = run.t >= run.t_end / 2
    wheels = np.abs(run.wheel_speed).max()
    assert eigen[half].max() <= eigen[~half].max()
    assert wheels < 523.6
    first, second, wheel = IN_ORBIT[name]
    assert abs(eigen[~half].max() - first) <= 0.05 and abs(eigen[half].max() - second) <= 0.05, eigen.max()
    assert abs(wheels - wheel) <= 0.05, wheels
