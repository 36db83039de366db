"""Seed 000's two-wheel laws (adcs_controllers.laws.underactuated): desired rates (eq. 7/8), the
zero-momentum wheel speed law (eq. 12-13), the snlc tracking law (eq. 14/24/31), the min-norm law
(eq. 25-27) and the gain-scheduled min-norm law (eq. 30-32). No ROS; a few seconds in total."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from adcs_controllers.laws import underactuated as ua
from adcs_core.attitude import quat_kinematics
from adcs_sim.truth.plant import Plant, ReactionWheels, WheelCommand

# Section VI.A: UoSAT-12 inertia and gains.
I_UOSAT = np.diag([40.45, 42.09, 42.36])
I_FULL = np.array([[40.45, 0.5, 0.2], [0.5, 42.09, -0.3], [0.2, -0.3, 42.36]])
SNLC = dict(k=0.02, g=0.08, K=10.0)
GSMN = dict(k1=0.02, g1=0.08, K1=10.0, k2=0.2, g2=1.2, K2=10.0, gamma=0.01, sigma=0.04, epsilon=0.02)
SAT = dict(a1=0.025, a2=0.025, eps_den=1e-3)
EPS = dict(eps_den=1e-3)  # IV.B.2 denominator only (unsaturated: the paper's stability argument)
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
# Printed q(0) = [0.2 0.2 0.2 0.8246] has norm 0.8944: normalised (docs/seed000_readings.md).
Q0_PRINTED = np.array([0.2, 0.2, 0.2, 0.8246])
Q0 = Q0_PRINTED / np.linalg.norm(Q0_PRINTED)


def random_states(rng, n, w_max=0.02, zero_w3=True):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 3] < 0] *= -1
    w = rng.uniform(-w_max, w_max, size=(n, 3))
    if zero_w3:
        w[:, 2] = 0.0  # zero total momentum implies w3 = 0 (section II)
    return q, w


def all_laws(q, w, inertia, **sat):
    """(name, u, status) of every torque law for states q, w."""
    out = [('snlc',) + ua.snlc_torque(q, w, inertia, **SNLC, **sat),
           ('snlc_eq14',) + ua.snlc_torque(q, w, inertia, **SNLC, **sat, scale_by_inertia=True),
           ('min_norm',) + ua.min_norm_torque(q, w, inertia, **SNLC, gamma=0.01, sigma=0.04, **sat),
           ('gsmn',) + ua.gsmn_torque(q, w, inertia, **GSMN, **sat)]
    return out


# --- eq. 7/8: desired rates --------------------------------------------------------------------

def test_desired_rates_closed_loop_kinematics_eq9_eq10():
    """With w = wd (w3 = 0): dq3/dt = -g/2 q3 (eq. 9) and dq4/dt = k/2 (q1² + q2²) (eq. 10);
    with the IV.B.2 ε, dq4/dt is unchanged and q3 still decays. With the saturation (eq. 8)
    dq4/dt = k/2|q12|² - g/2 (q1 sat(r1) - q2 sat(r2)) can be negative (the paper's argument
    is for the unsaturated law), while q3 still decays."""
    q, _ = random_states(np.random.default_rng(1), 500)
    k, g = 0.02, 0.08
    wd, _ = ua.desired_rates(q, np.zeros((500, 3)), k, g)
    dq = quat_kinematics(q, wd)
    assert_allclose(dq[:, 2], -g / 2 * q[:, 2], rtol=1e-9, atol=1e-15)
    assert_allclose(dq[:, 3], k / 2 * (q[:, 0] ** 2 + q[:, 1] ** 2), rtol=1e-9, atol=1e-15)
    wd, _ = ua.desired_rates(q, np.zeros((500, 3)), k, g, **EPS)
    dq = quat_kinematics(q, wd)
    assert_allclose(dq[:, 3], k / 2 * (q[:, 0] ** 2 + q[:, 1] ** 2), rtol=1e-9, atol=1e-15)
    assert np.all(dq[:, 2] * q[:, 2] <= 0)
    wd, _ = ua.desired_rates(q, np.zeros((500, 3)), k, g, **SAT)
    dq = quat_kinematics(q, wd)
    assert np.all(dq[:, 2] * q[:, 2] <= 0)
    assert dq[:, 3].min() < 0


def test_desired_rate_derivative_matches_finite_difference():
    """wd_dot (the ω̇d of eq. 14) is dωd/dt along the kinematics with the measured w."""
    rng = np.random.default_rng(2)
    q, w = random_states(rng, 200, zero_w3=False)
    for sat in ({}, dict(a1=0.5, a2=0.5, eps_den=1e-3)):
        wd, wd_dot = ua.desired_rates(q, w, 0.02, 0.08, **sat)
        h = 1e-6
        qp = q + h * quat_kinematics(q, w)
        qm = q - h * quat_kinematics(q, w)
        fd = (ua.desired_rates(qp, w, 0.02, 0.08, **sat)[0] - ua.desired_rates(qm, w, 0.02, 0.08, **sat)[0]) / (2 * h)
        assert_allclose(wd_dot, fd, rtol=1e-5, atol=1e-8)
        assert_array_equal(wd[:, 2], 0.0)


def test_saturation_eq8():
    q = np.array([0.3, 0.01, 0.5, np.sqrt(1 - 0.09 - 0.0001 - 0.25)])
    wd7, _ = ua.desired_rates(q, np.zeros(3), 0.02, 0.08)
    wd8, _ = ua.desired_rates(q, np.zeros(3), 0.02, 0.08, a1=0.025, a2=0.025)
    r1, r2 = q[1] * q[2] / (q[0] ** 2 + q[1] ** 2), q[0] * q[2] / (q[0] ** 2 + q[1] ** 2)
    assert_allclose(wd7[:2], [-0.02 * q[0] + 0.08 * r1, -0.02 * q[1] - 0.08 * r2], rtol=1e-12)
    assert_allclose(wd8[:2], [-0.02 * q[0] + 0.08 * 0.025, -0.02 * q[1] - 0.08 * 0.025], rtol=1e-12)


# --- generic properties ------------------------------------------------------------------------

@pytest.mark.parametrize('inertia', [I_UOSAT, I_FULL], ids=['diag', 'full'])
def test_batch_equals_loop_bit_for_bit(inertia):
    q, w = random_states(np.random.default_rng(3), 64, zero_w3=False)
    batch = all_laws(q, w, inertia, **SAT)
    for i in range(len(q)):
        for (name, u, st), (_, ui, sti) in zip(batch, all_laws(q[i], w[i], inertia, **SAT)):
            assert_array_equal(u[i], ui, err_msg=name)
            for key in st:
                assert_array_equal(st[key][i], sti[key], err_msg=f'{name}.{key}')
    s, st = ua.zero_momentum_wheel_speeds(q, inertia, 0.01, 0.02, 0.08, **SAT)
    for i in range(len(q)):
        si, sti = ua.zero_momentum_wheel_speeds(q[i], inertia, 0.01, 0.02, 0.08, **SAT)
        assert_array_equal(s[i], si)
        assert_array_equal(st['wd'][i], sti['wd'])


def test_z_torque_exactly_zero():
    q, w = random_states(np.random.default_rng(4), 300, zero_w3=False)
    for inertia in (I_UOSAT, I_FULL):
        for sat in ({}, SAT):
            for name, u, _ in all_laws(q, w, inertia, **sat):
                assert_array_equal(u[:, 2], 0.0, err_msg=name)
                assert np.all(np.isfinite(u)), name


def test_zero_error_gives_zero_output():
    w0 = np.zeros(3)
    for sat in ({}, SAT):
        wd, wd_dot = ua.desired_rates(IDENTITY, w0, 0.02, 0.08, **sat)
        assert_array_equal(wd, 0.0)
        assert_array_equal(wd_dot, 0.0)
        for name, u, st in all_laws(IDENTITY, w0, I_UOSAT, **sat):
            assert_array_equal(u, 0.0, err_msg=name)
            if 'V' in st:
                assert st['V'] == 0.0
        s, _ = ua.zero_momentum_wheel_speeds(IDENTITY, I_UOSAT, 0.01, 0.02, 0.08, **sat)
        assert_array_equal(s, 0.0)


def test_reference_attitude_is_the_new_origin():
    rng = np.random.default_rng(5)
    q_ref = rng.normal(size=4)
    q_ref /= np.linalg.norm(q_ref)
    u, _ = ua.gsmn_torque(q_ref, np.zeros(3), I_UOSAT, **GSMN, **SAT, q_ref=q_ref)
    assert_allclose(u, 0.0, atol=1e-15)


def test_zero_momentum_speeds_eq13():
    q = Q0
    s, st = ua.zero_momentum_wheel_speeds(q, I_UOSAT, [0.01, 0.02], 0.02, 0.08)
    wd, _ = ua.desired_rates(q, np.zeros(3), 0.02, 0.08)
    assert_allclose(s, [-40.45 / 0.01 * wd[0], -42.09 / 0.02 * wd[1]], rtol=1e-14)
    assert_allclose(st['h_cmd'], [-40.45 * wd[0], -42.09 * wd[1]], rtol=1e-14)


# --- Lyapunov arguments --------------------------------------------------------------------------

def _vdot_snlc(q, w, K, scale_by_inertia=False, **sat):
    u, _ = ua.snlc_torque(q, w, I_UOSAT, 0.02, 0.08, K, scale_by_inertia=scale_by_inertia, **sat)
    LfV, LgV = ua.lie_derivatives(q, w, I_UOSAT, 0.02, 0.02, 0.08, **sat)
    return LfV + np.sum(LgV * u, axis=-1)


def test_snlc_vdot_nonpositive_under_zero_momentum():
    """Eq. (16)-(19), zero momentum (h = -I w, w3 = 0): exact dV/dt = -k²|q12|² + k q12ᵀe12 -
    eᵀ I⁻¹ K e (the printed eq. 19 drops the cross term), <= 0 iff K_i >= I_i / 4. Holds for
    K = 11 (eq. 31 form) and for the printed eq. 14 (I_i K_i), with or without the IV.B.2 ε
    (unsaturated, as the paper's argument); FAILS on some states for the paper's K = 10 < 42.09 / 4 (readings doc)."""
    q, w = random_states(np.random.default_rng(6), 20000)
    for sat in ({}, EPS):
        assert _vdot_snlc(q, w, 11.0, **sat).max() <= 1e-15
        assert _vdot_snlc(q, w, 10.0, scale_by_inertia=True, **sat).max() <= 1e-15
    assert _vdot_snlc(q, w, 10.0).max() > 0.0  # the paper's K with the eq. 31 form


def test_min_norm_and_gsmn_never_slower_than_their_reference_law():
    """Eq. (22)/(33): LgV u <= LgV k(x) (min-norm) and LgV u <= LgV u_hg in the high-gain mode;
    the printed leading minus of eq. (25) would give LgV u = -LgV k > 0 wherever the law is on."""
    q0, w0 = random_states(np.random.default_rng(7), 5000, zero_w3=False)
    for sat in ({}, SAT):
        q, w = q0, w0
        u, st = ua.min_norm_torque(q, w, I_FULL, **SNLC, gamma=0.01, sigma=0.04, **sat)
        ub, _ = ua.snlc_torque(q, w, I_FULL, **SNLC, **sat)
        _, LgV = ua.lie_derivatives(q, w, I_FULL, 0.02, 0.01, 0.04, **sat)
        lgu, lgb = np.sum(LgV * u, -1), np.sum(LgV * ub, -1)
        assert np.all(lgu <= lgb + 1e-12 * np.abs(lgb))
        assert np.all(lgu <= 0.0)
        on = st['mode'] == ua.MODE_MIN_NORM
        assert on.any() and (~on).any()
        assert_allclose(lgu[on], lgb[on], rtol=1e-12)
        assert np.all(-lgu[on] > 0)  # printed-minus reading: dV/dt increased
        # add states near the high-gain trajectory (‖u_hg‖∞ < ε needs |ω - ωd_hg| < 2 mrad/s)
        qs = q * np.array([1e-3, 1e-3, 1e-3, 1.0])
        qs /= np.linalg.norm(qs, axis=1, keepdims=True)
        wd_hg, _ = ua.desired_rates(qs, w, GSMN['k2'], GSMN['g2'], **sat)
        q = np.concatenate([q, qs])
        w = np.concatenate([w, wd_hg + np.random.default_rng(9).uniform(-1e-4, 1e-4, w.shape)])
        _, LgV = ua.lie_derivatives(q, w, I_FULL, 0.02, 0.01, 0.04, **sat)
        u, st = ua.gsmn_torque(q, w, I_FULL, **GSMN, **sat)
        modes = {ua.MODE_LOW_GAIN, ua.MODE_ZERO_TORQUE, ua.MODE_HIGH_GAIN}
        assert set(np.unique(st['mode'])) <= modes
        if sat:  # saturated: the three modes occur (unsaturated, I ω̇d_hg is large near q12 = 0)
            assert set(np.unique(st['mode'])) == modes
        uh, _ = ua.snlc_torque(q, w, I_FULL, GSMN['k2'], GSMN['g2'], GSMN['K2'], **sat)
        hi = st['mode'] == ua.MODE_HIGH_GAIN
        assert_allclose(np.sum(LgV * u, -1)[hi], np.sum(LgV * uh, -1)[hi], rtol=1e-12)
        assert_array_equal(u[st['mode'] == ua.MODE_ZERO_TORQUE], 0.0)


def test_min_norm_vdot_nonpositive_where_benchmark_is():
    """γ = k, σ = g, zero momentum, K = 11: dV/dt(min-norm) <= dV/dt(snlc) <= 0."""
    q, w = random_states(np.random.default_rng(8), 20000)
    u, st = ua.min_norm_torque(q, w, I_UOSAT, 0.02, 0.08, 11.0, 0.02, 0.08, **EPS)
    assert st['Vdot'].max() <= 1e-15
    assert np.all(st['Vdot'] <= _vdot_snlc(q, w, 11.0, **EPS) + 1e-15)


# --- closed loop with the plant (section VI.A) ----------------------------------------------------

def test_closed_loop_zero_momentum_and_snlc_converge_on_three_axes():
    """UoSAT-12 inertia, wheels on x and y (0.02 N m, 5000 rpm, spin inertia 0.01 kg m² — not
    given by the paper), 1 s ZOH, from the normalised printed q(0) at rest. Run 0: zero-momentum
    law (speed mode), run 1: snlc (torque mode, motor torque = -u), in one batch. 3000 s (the paper's
    slowest 0.02-band settling time is 2918.8 s)."""
    wheels = ReactionWheels(names=['rw_x', 'rw_y'], axes=[[1, 0, 0], [0, 1, 0]],
                            spin_inertia=[0.01, 0.01], max_torque=[0.02, 0.02],
                            max_speed=[5000 * 2 * np.pi / 60] * 2)
    plant = Plant(I_UOSAT, [wheels])
    x = plant.initial_state(np.stack([Q0, Q0]), np.zeros(3))
    speed_mode = np.array([[True, True], [False, False]])
    cmds = plant.zero_commands()
    q4_err, q3 = [], []
    for k in range(3000):
        q, w = x[:, :4], x[:, 4:7]
        s, _ = ua.zero_momentum_wheel_speeds(q[0], I_UOSAT, 0.01, 0.02, 0.08, **SAT)
        u, _ = ua.snlc_torque(q[1], w[1], I_UOSAT, **SNLC, **SAT)
        cmds['wheels'] = WheelCommand(np.stack([s, -u[:2]]), speed_mode)
        x = plant.step(float(k), x, cmds, 1.0, 1.0)
        q4_err.append(np.abs(1 - np.abs(x[:, 3])))
        q3.append(np.abs(x[:, 2]))
    q4_err, q3 = np.array(q4_err), np.array(q3)
    assert np.all(np.isfinite(x))
    # q4 within 1 ± 0.01 (the paper's fine band) for the last 1500 s, on both runs
    assert np.all(q4_err[1500:] < 0.01)
    # actuated axes small; the unactuated axis Z converges (slowly: with a = 0.025 the singular
    # term is saturated, |q3| 0.224 -> ~0.06 at 3000 s, ~0.001-0.004 at 10 000 s)
    assert np.all(np.abs(x[:, :2]) < 0.05), x[:, :4]
    assert np.all(q3[-1] < 0.3 * Q0[2])
    assert np.all(q3[-1] < 0.8 * q3[1999])
    # zero total momentum is kept: w3 stays ~0
    assert np.all(np.abs(x[:, 6]) < 1e-6)
