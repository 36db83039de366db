"""Seed 004, eq. (17): the two readings of the min-norm projection direction LgV, tested on the paper's
own GSMN figures with the batch engine (docs/seed004/lgv_readings.py prints the same table) and, for
the inertia-weighted reading, its Lyapunov function V_I (dV/dt <= 0 in every mode).

    'printed'           LgV = (w + γq)ᵀ I⁻¹   V of eq. (15)                  (the pure functions' default)
    'inertia_weighted'  LgV = (w + γq)ᵀ       V_I = c(1 - q4) + ½wᵀIw + γqᵀIw, c = 2(kp + γkd) tr(I)/3
                                                                    (the schemas' default: Table I's numbers)

Each test states the paper's figure, ours under each reading and the tolerance with its reason; a test
that pins a disagreement says so in its name. No ROS.
"""
from __future__ import annotations

import importlib.util
import itertools
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from support.inverse_optimal import (
    GAINS_3F,
    GAINS_T1,
    I_3F,
    I_FULL,
    I_T1,
    coasting_states,
    random_states,
    state_derivative,
)
from support.scenarios import batch_run_data

from adcs_controllers.families import GSMN_SCHEMA, MINNORM_SCHEMA
from adcs_controllers.laws import inverse_optimal as io
from adcs_msgs_py.params import ParameterError

pytestmark = pytest.mark.paper

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location('lgv_readings', ROOT / 'docs' / 'seed004' / 'lgv_readings.py')
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)


# The Table I tests share these two batch runs (~17 s on the 2-core machine, paid by whichever runs first):
# all four are marked slow.
@lru_cache(maxsize=None)
def table1(lgv: str) -> dict:
    return study.table1_figures(batch_run_data(study.scenario_with('table1_gsmn', lgv)))


@lru_cache(maxsize=None)
def iii_f(lgv: str, period: float | None = None) -> dict:
    return study.iii_f_figures(batch_run_data(study.scenario_with('microsat_gsmn_slew', lgv, period)))


PAPER_T1 = study.table1_paper()
PAPER_3F = study.PAPER['microsat_gsmn_slew']


# --- V_I, the function whose exact LgV is (w + γq)ᵀ ---------------------------------------------

@pytest.mark.parametrize('inertia', [I_T1, I_FULL])
def test_inertia_weighted_lie_derivatives_match_finite_difference_of_V_I(inertia):
    """dV_I/dt along eq. 3-4 (central difference of V_I, wheel momentum h != 0) = LfV + LgV u."""
    rng = np.random.default_rng(11)
    kp, kd, g = 5.0, 5.0, 0.8
    for _ in range(20):
        q, w = random_states(rng, 1, 0.5)
        q, w = q[0], w[0]
        u, h = rng.normal(size=3), rng.normal(size=3)
        LfV, LgV = io.lie_derivatives(q, w, inertia, kp, kd, g, h=h, lgv='inertia_weighted')
        assert_array_equal(LgV, w + g * q[:3])
        dq, dw = state_derivative(q, w, inertia, u, h)
        d = 1e-5
        fd = (io.lyapunov_inertia_weighted(q + d * dq, w + d * dw, inertia, kp, kd, g)
              - io.lyapunov_inertia_weighted(q - d * dq, w - d * dw, inertia, kp, kd, g)) / (2 * d)
        # round-off of the central difference: |V_I| (up to ~300 here) x 2e-16 / d ~ 6e-9
        assert_allclose(LfV + LgV @ u, fd, rtol=1e-6, atol=3e-8)


def test_V_I_is_iota_times_eq15_for_a_scalar_inertia_and_positive_definite():
    rng = np.random.default_rng(12)
    q, w = random_states(rng, 500, 1.0)
    iota = 7.0
    assert_allclose(io.lyapunov_inertia_weighted(q, w, iota * np.eye(3), 5.0, 5.0, 0.8),
                    iota * io.lyapunov(q, w, 5.0, 5.0, 0.8), rtol=1e-12)
    assert np.all(io.lyapunov_inertia_weighted(q, w, I_T1, 5.0, 5.0, 0.8) > 0)


@pytest.mark.parametrize('inertia, gains, eps, w_max', [
    (I_3F, GAINS_3F, 0.01, 0.02), (I_T1, GAINS_T1, 70.0, 1.0), (I_FULL, GAINS_T1, 70.0, 1.0)])
def test_inertia_weighted_gsmn_and_min_norm_vdot_never_positive_in_any_mode(inertia, gains, eps, w_max):
    """The same random and coasting states as the printed reading's test (tests/test_laws_inverse_optimal.py):
    with V_I of the benchmark gains, dV/dt <= 0 in the low-gain, zero-torque and high-gain modes, and for the
    min-norm law with either gain set; V_I > 0 on every state."""
    rng = np.random.default_rng(5)
    q, w = random_states(rng, 4000, w_max)
    qc, wc = coasting_states(rng, 4000, w_max, gains['gamma'] / 2, 2 * gains['kp2'] / gains['kd2'])
    q, w = np.concatenate([q, qc]), np.concatenate([w, wc])
    u, st = io.gsmn_torque(q, w, inertia, **gains, epsilon=eps, lgv='inertia_weighted')
    LfV, LgV = io.lie_derivatives(q, w, inertia, gains['kp1'], gains['kd1'], gains['gamma'], lgv='inertia_weighted')
    assert_allclose(st['Vdot'], LfV + np.sum(LgV * u, 1), rtol=1e-12, atol=1e-18)
    for m in (io.MODE_LOW_GAIN, io.MODE_ZERO_TORQUE, io.MODE_HIGH_GAIN):
        in_mode = st['mode'] == m
        assert in_mode.sum() >= 50, f'mode {m} barely sampled'
        assert np.all(st['Vdot'][in_mode] <= 0), f'dV_I/dt > 0 in mode {m}'
    assert np.all(st['V'] > 0)
    for kp, kd in ((gains['kp1'], gains['kd1']), (gains['kp2'], gains['kd2'])):
        _, st_mn = io.min_norm_torque(q, w, inertia, kp, kd, gains['gamma'], lgv='inertia_weighted')
        assert np.all(st_mn['Vdot'] <= 0)


def test_inertia_weighted_torque_at_rest_is_kp1_qIq_over_qq_times_q():
    """At w = 0 the projection of u1 = -kp1 I q on LgVᵀ = γq is -kp1 (qᵀIq / qᵀq) q (the issue's closed form)."""
    q = np.array([0.4646, 0.1928, 0.8047, 0.3153])
    u, _ = io.gsmn_torque(q, np.zeros(3), I_T1, **GAINS_T1, epsilon=140.0, lgv='inertia_weighted')
    qv = q[:3]
    assert_allclose(u, -GAINS_T1['kp1'] * (qv @ I_T1 @ qv) / (qv @ qv) * qv, rtol=1e-14)


def test_schemas_default_to_the_inertia_weighted_reading_pure_functions_to_the_printed_and_bad_refused():
    """The nodes and the batch engine (schemas, section laws) default to (b), the reading Table I supports;
    the pure functions keep the paper's printed text (a) as their default."""
    rng = np.random.default_rng(13)
    q, w = random_states(rng, 50, 1.0)
    u0, st0 = io.gsmn_torque(q, w, I_T1, **GAINS_T1, epsilon=70.0)
    u1, st1 = io.gsmn_torque(q, w, I_T1, **GAINS_T1, epsilon=70.0, lgv='printed')
    assert_array_equal(u0, u1)
    assert_array_equal(st0['Vdot'], st1['Vdot'])
    with pytest.raises(ValueError, match='lgv must be one of'):
        io.min_norm_torque(q, w, I_T1, 5.0, 5.0, 0.8, lgv='typo')
    for schema in (GSMN_SCHEMA, MINNORM_SCHEMA):
        assert schema.by_name['lgv'].default == 'inertia_weighted' == io.DEFAULT_LGV
        assert schema.by_name['lgv'].choices == io.LGV_READINGS


def test_schema_refuses_an_unknown_lgv_reading_naming_the_key():
    params = {'inertia': [10.0, 15.0, 20.0], 'kp1': 5.0, 'kd1': 5.0, 'kp2': 30.0, 'kd2': 10.0, 'gamma': 0.8,
              'epsilon': 140.0, 'lgv': 'no_inverse'}
    with pytest.raises(ParameterError) as exc:
        GSMN_SCHEMA.validate(params)
    assert exc.value.key == 'lgv'


# --- Table I (GSMN column): the reading the numbers support -------------------------------------

def _printed_digits_band(axis: int) -> float:
    """Half a unit of the last printed digit of Table I's peak (-40.4: 0.05; -16.77, -69.98: 0.005) plus
    the worst effect on the t = 0 torque -kp1 (qᵀIq/qᵀq) q of the initial quaternion's rounding to 4
    decimals (every ±5e-5 corner; 0.004 / 0.005 / 0.007 N m on X / Y / Z)."""
    paper = PAPER_T1['peak (N m)'][axis]
    decimals = len(f'{abs(paper)}'.split('.')[1])
    q0 = np.array([0.4646, 0.1928, 0.8047])

    def u0(q):
        return -GAINS_T1['kp1'] * (q @ I_T1 @ q) / (q @ q) * q[axis]
    rounding = max(abs(u0(q0 + 5e-5 * np.array(c)) - u0(q0)) for c in itertools.product((-1, 0, 1), repeat=3))
    return 0.5 * 10.0 ** -decimals + rounding


@pytest.mark.slow
def test_table1_gsmn_x_y_peaks_match_the_paper_to_its_printed_digits_inertia_weighted():
    """Paper: X -40.4, Y -16.77 N m. Ours (b): -40.41, -16.77; (a) printed: -53.06, -15.04. Tolerance: the
    printed precision (half a unit of the last digit) plus the initial quaternion's rounding; (a) is asserted
    outside that band (it misses by 12.7 and 1.7 N m; was "> 1 N m", a margin with no reason)."""
    ours, printed = table1('inertia_weighted')['peak (N m)'], table1('printed')['peak (N m)']
    for i in (0, 1):
        band = _printed_digits_band(i)
        assert abs(ours[i] - PAPER_T1['peak (N m)'][i]) < band
        assert abs(printed[i] - PAPER_T1['peak (N m)'][i]) > band  # (a) misses by 12.7 and 1.7 N m


@pytest.mark.slow
def test_disagreement_table1_gsmn_z_peak_inertia_weighted_0p02_Nm_beyond_the_printed_digits():
    """Paper: Z -69.98 N m. Ours (b): -69.996 (1.6 units of the last digit, 0.023 %), outside the printed
    precision; within the issue's 1 % for peaks. (a) printed: -55.50 (21 % low), asserted outside that 1 %
    (was "> 20 %", a margin under the miss with no reason)."""
    ours, paper = table1('inertia_weighted')['peak (N m)'][2], PAPER_T1['peak (N m)'][2]
    assert abs(ours - paper) > _printed_digits_band(2)
    assert abs(ours - paper) < 0.01 * abs(paper)
    assert abs(table1('printed')['peak (N m)'][2] - paper) > 0.01 * abs(paper)


@pytest.mark.slow
def test_table1_gsmn_integrated_torque_within_1pct_inertia_weighted_not_printed():
    """Paper: 26.95 N m s (4 digits). Ours (b): 26.86 (-0.33 %); (a) printed: 27.66 (+2.6 %). Tolerance 1 %,
    the method's, not the paper's digits: the paper gives no control period, and moving ours from 1 ms to
    10 ms moves ∫‖u‖dt by +0.6 % (a) / +1.0 % (b) (27.83 / 27.12 N m s; docs/seed004/lgv_readings.py). (a) is
    asserted outside the same 1 % (was "> 2 %", a margin under its 2.6 % miss with no reason)."""
    paper = PAPER_T1['int |u| dt (N m s)']
    assert abs(table1('inertia_weighted')['int |u| dt (N m s)'] - paper) < 0.01 * paper
    assert abs(table1('printed')['int |u| dt (N m s)'] - paper) > 0.01 * paper


@pytest.mark.slow
def test_disagreement_table1_gsmn_settles_faster_than_the_paper_on_x_y_under_both_readings():
    """DISAGREEMENT with Table I, pinned: paper 1° X / Y: 9.6 / 7.1 s, 0.5°: 10.6 / 10.1 s (printed to 0.1 s).
    Ours 1°: (a) 7.35 / 5.79, (b) 7.04 / 4.89; 0.5°: (a) 7.83 / 7.00, (b) 8.15 / 6.17 s, 1.3-3.9 s early:
    neither reading explains the settling times. Asserted beyond the paper's printed precision (0.05 s), which
    is also more than the 1 ms period moves them (0.009 s, test_table1_control_period_is_converged). (Was:
    "over 1 s" early, a margin under the smallest miss with no reason.)"""
    for lgv in io.LGV_READINGS:
        for key in ('settling 1 deg (s)', 'settling 0.5 deg (s)'):
            assert np.all(table1(lgv)[key][:2] < PAPER_T1[key][:2] - 0.05), (lgv, key)


# --- section III.F: leans weakly to (a); Table I decides ------------------------------------------

@pytest.mark.slow
def test_iii_f_gsmn_settling_within_the_period_sensitivity_under_the_printed_reading_only():
    """Paper: 123.8 s (0.5°, all axes; printed to 0.1 s). Ours at the scenario's 0.1 s period (a reading) and at
    1 s: (a) printed 122.3 / 128.1 s (-1.2 / +3.5 %), (b) 119.8 / 117.7 s (-3.3 / -4.9 %). Tolerance per reading,
    the method's: how far the unknown control period moves that reading's figure from 0.1 s to 1 s, measured here
    ((a) 4.7 %, (b) 1.8 %; no period of 0.01-1 s moves either further: docs/seed004.md). (a) is within its
    sensitivity at both periods, (b) at neither: III.F leans to (a), weakly (a settling time that also depends on
    the wheels, which the paper does not give), against Table I's peaks, printed to 4 digits, which only (b)
    gives (kept: (b)). The paper lies between the two readings at 1 s. (Was: both readings within 5 % at both
    periods, "the method's" from (a)'s 4.5 %, which (b)'s 4.9 % at 1 s sat just under.)"""
    paper = PAPER_3F['settling_euler213_all_0.5deg_s']
    key = 'settling 0.5 deg all axes (s)'
    for lgv, within in (('printed', True), ('inertia_weighted', False)):
        fine, coarse = iii_f(lgv)[key], iii_f(lgv, 1.0)[key]
        sensitivity = abs(coarse - fine) / fine
        for ours in (fine, coarse):
            assert (abs(ours - paper) < sensitivity * paper) == within, (lgv, ours, sensitivity)
    assert iii_f('printed', 1.0)[key] > paper > iii_f('inertia_weighted', 1.0)[key]


def test_disagreement_iii_f_gsmn_integrated_torque_below_the_paper_beyond_the_period_under_both_readings():
    """DISAGREEMENT with III.F, pinned: paper 0.214 N m s. Ours (0.1 s period): (a) 0.183 (-14.5 %), (b) 0.181
    (-15.5 %); at 1 s 0.187 / 0.182. The miss is beyond the method's sensitivity (how far the unknown period
    moves each reading from 0.1 s to 1 s, measured here: (a) 1.9 %, (b) 0.8 %) plus the paper's printed
    precision (0.0005 of 0.214) under both: neither reading explains it. Ours pinned to half a unit of the
    digit docs/seed004_readings.md prints (0.0005 N m s). Both keep the peak inside the 0.01 N m limit (the
    paper's "admissible instantaneous torque"). (Was: a miss between 12 and 16 %, a band around the
    observed with no reason.)"""
    paper = PAPER_3F['integrated_torque_Nms']
    key = 'int |u| dt (N m s)'
    for lgv, ours in (('printed', 0.183), ('inertia_weighted', 0.181)):
        fine, coarse = iii_f(lgv)[key], iii_f(lgv, 1.0)[key]
        assert abs(fine - ours) <= 0.0005, (lgv, fine)
        sensitivity = abs(coarse - fine)
        assert paper - fine > sensitivity + 0.0005 and paper - coarse > 0.0005, (lgv, fine, coarse)
        assert iii_f(lgv)['peak |u|_inf (N m)'] <= 0.01
