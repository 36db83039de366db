"""Seed 004 section IV (adcs_sim.app.campaign.tuning): single-axis switching model, settling-time limit
(eq. 31) and the highest high gains under a peak-torque limit, checked against simulation."""
from __future__ import annotations

import math
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

from adcs_sim.app.campaign import tuning as tn

ROOT = pathlib.Path(__file__).resolve().parents[1]

# The paper's example (IV.G): J = 10, 30°, kp1 = 0.02, kd1 = 0.5 (γ is not printed: 0.01 here).
J, THETA0, KP1, KD1, GAMMA = 10.0, math.radians(30.0), 0.02, 0.5, 0.01


def test_switch_point_closed_form_matches_simulation():
    sp = tn.switch_point(J, KP1, KD1, GAMMA, THETA0)
    zeta = tn.damping_ratio(J, KP1, KD1)
    assert_allclose(zeta, 0.5 / (2 * 10 * math.sqrt(0.02 / 20)), rtol=1e-15)  # 0.7906
    kp2 = 4 * KP1
    run = tn.simulate_single_axis(J, KP1, KD1, kp2, tn.same_damping_kd(J, kp2, zeta), GAMMA, THETA0, 200.0)
    assert_allclose(run.t_off, sp.t_s, rtol=1e-8)
    i = np.flatnonzero(run.t == run.t_off)[0]
    assert_allclose(run.theta[i], sp.theta_s, rtol=1e-8)
    assert_allclose(run.theta_dot[i], sp.theta_dot_s, rtol=1e-7)
    assert_allclose(sp.theta_dot_s, -GAMMA * sp.theta_s, rtol=1e-15)
    # the coast: constant rate, zero torque, until θ' + kp2/(2 kd2) θ = 0
    coast = run.phase == tn.PHASE_ZERO_TORQUE
    assert np.all(run.u[coast] == 0.0)
    assert_allclose(run.theta_dot[coast], sp.theta_dot_s, rtol=1e-8)
    c2 = kp2 / (2 * tn.same_damping_kd(J, kp2, zeta))
    assert_allclose(run.t_on, sp.t_s + (sp.theta_s - (-sp.theta_dot_s / c2)) / -sp.theta_dot_s, rtol=1e-8)


def test_settling_time_converges_to_the_limit_as_high_gains_grow():
    """Eq. (31): t_sl = t_s + |θ_s/θ'_s|. As kp2 (same ζ) grows, the reactivation time tends to
    t_sl from below and the settling time (2% band) decreases to the infinite-gain value
    t_s + (|θ_s| - tol)/|θ'_s| (band entered while coasting; t_sl is its tol -> 0 limit)."""
    r = tn.tune_single_axis(J, KP1, KD1, GAMMA, THETA0)
    assert_allclose(r.t_sl, tn.settling_time_limit(J, KP1, KD1, GAMMA, THETA0), rtol=1e-15)
    assert_allclose(r.t_sl, r.t_s + 1 / GAMMA, rtol=1e-14)
    tol = 0.02 * THETA0
    infinite_gain = r.t_s + (abs(r.theta_s) - tol) / abs(r.theta_dot_s)
    t_on, settle = [], []
    for m in (1, 4, 16, 64, 256, 1024):
        kp2 = m * KP1
        run = tn.simulate_single_axis(J, KP1, KD1, kp2, tn.same_damping_kd(J, kp2, r.zeta), GAMMA,
                                      THETA0, 2 * r.t_sl, dt=0.1)
        t_on.append(run.t_on)
        settle.append(tn.single_axis_settling_time(run, tol))
    assert np.all(np.diff(t_on) > 0) and t_on[-1] < r.t_sl
    assert r.t_sl - t_on[-1] < 0.03 * r.t_sl
    assert np.all(np.diff(settle) <= 1e-9)
    assert settle[0] > infinite_gain + 20.0          # low high-gains: far from the limit
    assert_allclose(settle[-1], infinite_gain, rtol=1e-6)
    assert min(settle) >= infinite_gain - 1e-6


@pytest.mark.parametrize('max_torque', [None, 0.01, 0.002])
def test_highest_gains_put_the_peak_torque_on_the_limit(max_torque):
    r = tn.tune_single_axis(J, KP1, KD1, GAMMA, THETA0, max_torque)
    limit = KP1 * THETA0 / 2 if max_torque is None else max_torque
    assert_allclose(r.initial_torque, KP1 * THETA0 / 2, rtol=1e-15)
    assert r.max_torque == limit and r.feasible
    assert_allclose(r.peak_torque, limit, rtol=1e-12)
    assert_allclose(tn.damping_ratio(J, r.kp2, r.kd2), r.zeta, rtol=1e-12)

    def peak(kp2):
        run = tn.simulate_single_axis(J, KP1, KD1, kp2, tn.same_damping_kd(J, kp2, r.zeta), GAMMA,
                                      THETA0, r.t_sl + 60.0, dt=0.002)
        return np.abs(run.u[run.phase == tn.PHASE_HIGH_GAIN]).max()

    assert_allclose(peak(r.kp2), limit, rtol=1e-5)
    assert peak(1.05 * r.kp2) > limit * 1.02
    assert peak(0.95 * r.kp2) < limit


def test_peak_torque_scales_with_the_square_root_of_kp2():
    sp = tn.switch_point(J, KP1, KD1, GAMMA, THETA0)
    zeta = tn.damping_ratio(J, KP1, KD1)
    p1 = tn.high_gain_peak_torque(J, 0.1, zeta, sp.theta_dot_s)
    assert_allclose(tn.high_gain_peak_torque(J, 0.4, zeta, sp.theta_dot_s), 2 * p1, rtol=1e-14)


def test_rejects_overdamped_and_nonpositive_parameters():
    with pytest.raises(ValueError, match='underdamped'):
        tn.switch_point(J, KP1, 2.0, GAMMA, THETA0)
    with pytest.raises(ValueError):
        tn.switch_point(J, KP1, KD1, 0.0, THETA0)
    with pytest.raises(ValueError):
        tn.tune_single_axis(J, KP1, KD1, GAMMA, THETA0, max_torque=0.0)


def test_infeasible_when_the_limit_is_below_the_low_gain_needs():
    r = tn.tune_single_axis(J, KP1, KD1, GAMMA, THETA0, max_torque=1e-5)
    assert r.kp2 < KP1 and not r.feasible


def test_cli_prints_the_tuning(capsys):
    assert tn.main(['--inertia', '10', '--angle-deg', '30', '--kp1', '0.02', '--kd1', '0.5',
                    '--gamma', '0.01', '--max-torque', '0.005', '--simulate']) == 0
    out = capsys.readouterr().out
    r = tn.tune_single_axis(J, KP1, KD1, GAMMA, THETA0, 0.005)
    assert f'{r.t_sl:.3f} s' in out and f'{r.kp2:.6g}' in out and 'simulated' in out


def test_module_runs_as_a_script_without_rclpy():
    """``python -m adcs_sim.app.campaign.tuning ...`` (run as __main__ through runpy) pulls in no rclpy."""
    code = ('import runpy, sys\n'
            'sys.argv = ["tuning", "--inertia", "10", "--angle-deg", "30", "--kp1", "0.02", '
            '"--kd1", "0.5", "--gamma", "0.02"]\n'
            'try:\n    runpy.run_module("adcs_sim.app.campaign.tuning", run_name="__main__")\n'
            'except SystemExit as e:\n    assert e.code == 0\n'
            'print("rclpy" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert 'settling-time limit t_sl   84.034 s' in out.stdout
    assert out.stdout.strip().endswith('False')
