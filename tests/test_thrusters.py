"""Seed 002 plant parts (adcs_sim.truth.thrusters): on/off thrusters as a plant actuator (torque
Σ rᵢ × Fᵢ, pulses within a control period, minimum on-time, impulse states), the orbit frame
(z nadir, x along track) and the gravity-gradient torque of eq. (19). No ROS; a few seconds."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from adcs_core.attitude import quat_kinematics, quat_multiply, rotate_to_body
from adcs_core.orbit import (
    CircularOrbit,
    body_in_orbit,
    directional_cosines,
    gravity_gradient_principal,
    orbit_frame_attitude,
    orbit_frame_matrix,
    orbit_rate,
)
from adcs_sim.truth.plant import Plant
from adcs_sim.truth.thrusters import Thrusters, step_pulsed

J_ESEO = np.diag([4.350, 4.3370, 3.6640])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
F = 0.13


def make(positions, directions, force=F, **kw) -> Thrusters:
    n = len(positions)
    return Thrusters([f't{i}' for i in range(n)], positions, directions, force, **kw)


def corner_layout():
    """ESEO choice (docs/seed002_readings.md): corners of the +z face, tangential thrust."""
    p = np.array([[-0.3, 0.3, 0.4], [-0.3, -0.3, 0.4], [0.3, 0.3, 0.4], [0.3, -0.3, 0.4]])
    d = np.array([[1, 1, 0], [1, -1, 0], [-1, 1, 0], [-1, -1, 0]]) / math.sqrt(2)
    return p, d


# --- torque = Σ r × F --------------------------------------------------------------------------

def test_single_thruster_torque_and_force():
    """A thruster at (0, 0, 0.4) pushing +x gives torque r × F = (0, 0.4 F, 0) and force (F, 0, 0);
    one pushing through the centre of mass gives no torque."""
    thr = make([[0, 0, 0.4], [0.3, 0, 0]], [[2, 0, 0], [-1, 0, 0]])   # direction normalised
    cmd = thr.command(0.0, [1.0, 1.0], 1.0)
    tau, f = thr.torque(0.5, np.zeros(2), np.zeros(3), cmd)
    assert_allclose(f, [F, F], rtol=0, atol=0)
    assert_allclose(tau, [0.0, 0.4 * F, 0.0], rtol=0, atol=1e-17)
    assert_allclose(thr.force(0.5, cmd), [0.0, 0.0, 0.0], atol=1e-17)
    cmd = thr.command(0.0, [1.0, 0.0], 1.0)
    assert_allclose(thr.force(0.5, cmd), [F, 0.0, 0.0], atol=1e-17)


def test_torque_is_sum_of_r_cross_F_for_random_layouts():
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = rng.integers(1, 9)
        r = rng.uniform(-0.5, 0.5, (n, 3))
        d = rng.normal(size=(n, 3))
        Fmax = rng.uniform(0.01, 1.0, n)
        thr = make(r, d, Fmax)
        on = rng.uniform(0, 1, n) < 0.6
        cmd = thr.command(0.0, np.where(on, 1.0, 0.0), 1.0)
        tau, _ = thr.torque(0.3, np.zeros(n), np.zeros(3), cmd)
        dn = d / np.linalg.norm(d, axis=1, keepdims=True)
        expected = sum(np.cross(r[i], Fmax[i] * dn[i]) for i in range(n) if on[i]) if on.any() else 0.0
        assert_allclose(tau, expected + np.zeros(3), rtol=1e-12, atol=1e-15)


def test_eseo_corner_layout_torques():
    """Corner/tangential layout: x/y torque √2/2 r_z F per thruster, yaw √2/2 (r_x + r_y) F;
    the four torques sum to zero and so do the four forces (the null vector [1, 1, 1, 1])."""
    p, d = corner_layout()
    thr = make(p, d)
    T = thr.torque_matrix
    a, e = 0.4 / math.sqrt(2), 0.6 / math.sqrt(2)
    assert_allclose(T.T, [[-a, a, -e], [a, a, e], [-a, -a, e], [a, -a, -e]], atol=1e-15)
    assert_allclose(T.sum(axis=1), 0.0, atol=1e-15)
    assert_allclose(thr.force_matrix.sum(axis=1), 0.0, atol=1e-15)


def test_pure_axis_torque_spins_body_exactly():
    """Thrusters 2 and 4 together give a pure x torque 2 a F: at rest, ω_x = 2 a F t / J_x
    (no gyroscopic term about a principal axis); RK4 is exact for a constant torque."""
    p, d = corner_layout()
    thr = make(p, d)
    plant = Plant(J_ESEO, [thr])
    x = plant.initial_state(IDENTITY, np.zeros(3))
    period = 0.5
    for k in range(10):
        cmds = {'thrusters': thr.command(k * period, [0.0, period, 0.0, period], period)}
        x = step_pulsed(plant, k * period, x, cmds, period, 0.1)
    tau_x = 2 * 0.4 / math.sqrt(2) * F
    assert_allclose(x[4:7], [tau_x * 5.0 / 4.350, 0, 0], rtol=1e-12, atol=1e-15)
    assert_allclose(x[7:], [0.0, 5 * F, 0.0, 5 * F], rtol=1e-13, atol=0)


# --- pulses, impulse accounting, minimum on-time -------------------------------------------------

def test_impulse_is_force_times_on_time_with_exact_split():
    """Arbitrary on-times inside a period: with step_pulsed every impulse state equals
    F × on-time (to rounding, 1e-14 relative); plain RK4 steps across the edges miss by up to
    F h / 3 (Simpson weights), and do here (> 1e-4 N s)."""
    p, d = corner_layout()
    Fmax = np.array([0.13, 0.10, 0.07, 0.2])
    on = np.array([0.037, 0.1, 0.0, 0.0123])
    period, h = 0.1, 0.025
    thr = make(p, d, Fmax)
    plant = Plant(J_ESEO, [thr])
    x0 = plant.initial_state(IDENTITY, [0.01, -0.02, 0.005])
    cmds = {'thrusters': thr.command(2.0, on, period)}
    x = step_pulsed(plant, 2.0, x0, cmds, period, h)
    assert_allclose(x[7:], Fmax * on, rtol=1e-14, atol=0)
    x_rk = plant.step(2.0, x0, cmds, period, h)
    err = np.abs(x_rk[7:] - Fmax * on)
    assert np.all(err <= Fmax * h / 3 + 1e-15)
    assert err.max() > 1e-4
    # over several periods the totals add up exactly too
    for k in range(1, 6):
        x = step_pulsed(plant, 2.0 + k * period, x, {'thrusters': thr.command(2.0 + k * period, on, period)},
                        period, h)
    assert_allclose(x[7:], 6 * Fmax * on, rtol=1e-13, atol=0)


def test_pulse_timing_within_the_period():
    thr = make([[0, 0, 1]], [[1, 0, 0]])
    cmd = thr.command(10.0, [0.03], 0.1)
    assert thr.is_on(10.0, cmd)[0] == 1.0
    assert thr.is_on(10.0299, cmd)[0] == 1.0
    assert thr.is_on(10.0301, cmd)[0] == 0.0
    assert thr.is_on(9.999, cmd)[0] == 0.0
    full = thr.command(10.0, [0.1], 0.1)     # whole period: on at the closed end (RK4's k4)
    assert thr.is_on(10.1, full)[0] == 1.0
    assert thr.is_on(10.1001, full)[0] == 0.0
    assert thr.is_on(10.1 + 1e-12, full)[0] == 1.0   # rounding of RK4 stage times


def test_whole_period_firings_lose_nothing_to_rounded_stage_times():
    """Periods starting at k * 0.1 (not representable): RK4's last stage at t_k + h may land a
    few ulp past the period's end; the full-period firing must still count there (impulse =
    F × 50 × 0.1 to 1e-13 with plain Plant.step)."""
    thr = make([[0, 0, 0.4]], [[1, 0, 0]])
    plant = Plant(J_ESEO, [thr])
    x = plant.initial_state(IDENTITY, np.zeros(3))
    for k in range(50):
        x = plant.step(k * 0.1, x, {'thrusters': thr.command(k * 0.1, [0.1], 0.1)}, 0.1, 0.1)
    assert x[7] == pytest.approx(F * 5.0, rel=1e-13)


def test_minimum_on_time_and_clipping():
    thr = make([[0, 0, 1]] * 4, [[1, 0, 0]] * 4, min_on_time=0.02)
    cmd = thr.command(0.0, [0.019, 0.02, 0.5, -0.1], 0.1)
    assert_array_equal(cmd.on_time, [0.0, 0.02, 0.1, 0.0])
    ext = make([[0, 0, 1]] * 2, [[1, 0, 0]] * 2, min_on_time=0.02, min_on_rule='extend')
    assert_array_equal(ext.command(0.0, [0.005, 0.0], 0.1).on_time, [0.02, 0.0])
    plant = Plant(J_ESEO, [thr])
    x = step_pulsed(plant, 0.0, plant.initial_state(IDENTITY, np.zeros(3)), {'thrusters': cmd}, 0.1, 0.05)
    assert_allclose(x[7:], F * np.array([0.0, 0.02, 0.1, 0.0]), rtol=1e-14)


@pytest.mark.parametrize('kw', [dict(max_force=-1.0), dict(max_force=np.inf), dict(min_on_time=-0.1),
                                dict(min_on_rule='round'), dict(directions=[[0, 0, 0]])])
def test_bad_parameters_raise(kw):
    args = dict(names=['t0'], positions=[[0, 0, 1]], directions=[[1, 0, 0]], max_force=F)
    args.update(kw)
    with pytest.raises(ValueError):
        Thrusters(**args)


def test_nonfinite_on_time_and_wrong_period_raise():
    thr = make([[0, 0, 1]], [[1, 0, 0]])
    with pytest.raises(ValueError):
        thr.command(0.0, [np.nan], 0.1)
    plant = Plant(J_ESEO, [thr])
    x = plant.initial_state(IDENTITY, np.zeros(3))
    with pytest.raises(ValueError):
        step_pulsed(plant, 0.0, x, {'thrusters': thr.command(0.0, [0.05], 0.1)}, 0.2, 0.1)


def test_batch_equals_loop_bit_identical():
    """Batched on-times and forces step exactly as single runs (whole-period firings, as the
    bang-bang law gives; with inner edges the batch splits at the union of edges)."""
    rng = np.random.default_rng(5)
    p, d = corner_layout()
    n = 6
    Fmax = rng.uniform(0.1, 0.15, (n, 4))
    thr_b = make(p, d, Fmax)
    plant_b = Plant(J_ESEO, [thr_b])
    q0 = Rotation.random(n, random_state=1).as_quat()
    w0 = rng.uniform(-0.05, 0.05, (n, 3))
    x = plant_b.initial_state(q0, w0)
    fires = rng.uniform(size=(20, n, 4)) < 0.5
    for k in range(20):
        x = step_pulsed(plant_b, k * 0.1, x, {'thrusters': thr_b.command(k * 0.1, fires[k] * 0.1, 0.1)}, 0.1, 0.05)
    for i in range(n):
        thr = make(p, d, Fmax[i])
        plant = Plant(J_ESEO, [thr])
        xi = plant.initial_state(q0[i], w0[i])
        for k in range(20):
            xi = step_pulsed(plant, k * 0.1, xi, {'thrusters': thr.command(k * 0.1, fires[k, i] * 0.1, 0.1)}, 0.1, 0.05)
        assert_array_equal(x[i], xi)


# --- orbit frame ------------------------------------------------------------------------------------

ORBITS = [CircularOrbit(250e3), CircularOrbit(700e3, inclination=1.2, raan=0.4, arg_latitude0=2.0)]


@pytest.mark.parametrize('orbit', ORBITS)
def test_orbit_frame_axes(orbit):
    """z_o to nadir, x_o along the velocity, y_o = z_o × x_o (negative orbit normal), orthonormal."""
    for t in (0.0, 123.4, 4000.0):
        R = orbit_frame_matrix(orbit, t)
        assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
        assert_allclose(R[:, 2], -orbit.position_unit(t), atol=1e-15)
        dt = 1e-3
        v = (orbit.position_unit(t + dt) - orbit.position_unit(t - dt)) / (2 * dt)
        assert_allclose(R[:, 0], v / np.linalg.norm(v), atol=1e-9)
        normal = np.cross(orbit.position_unit(t), v)
        assert_allclose(R[:, 1], -normal / np.linalg.norm(normal), atol=1e-9)


@pytest.mark.parametrize('orbit', ORBITS)
def test_orbit_rate_is_the_frame_rotation(orbit):
    """Eq. (1): ω_o = sqrt(μ / r³); the orbit frame turns at [0, -ω_o, 0] in its own axes
    (finite difference of q_io through the quaternion kinematics)."""
    n, w_io = orbit_rate(orbit)
    assert n == pytest.approx(math.sqrt(3.986004418e14 / (6378137.0 + orbit.altitude) ** 3), rel=1e-15)
    assert_allclose(w_io, [0, -n, 0])
    t, dt = 500.0, 1e-2
    q = orbit_frame_attitude(orbit, t)
    dq = (orbit_frame_attitude(orbit, t + dt) - orbit_frame_attitude(orbit, t - dt)) / (2 * dt)
    assert_allclose(dq, quat_kinematics(q, w_io), atol=1e-10)
    # one revolution per orbit
    assert_allclose(orbit_frame_matrix(orbit, 2 * math.pi / n), orbit_frame_matrix(orbit, 0.0), atol=1e-12)
    if orbit.altitude == 250e3:   # ESEO at 250 km: 89.5 min orbit
        assert 2 * math.pi / n / 60 == pytest.approx(89.50, abs=0.01)


def test_body_aligned_with_orbit_frame_has_identity_cosines():
    orbit = ORBITS[1]
    q = orbit_frame_attitude(orbit, 77.0)
    assert_allclose(directional_cosines(orbit, 77.0, q), np.eye(3), atol=1e-15)
    assert_allclose(np.abs(body_in_orbit(orbit, 77.0, q)), IDENTITY, atol=1e-15)


# --- gravity gradient, eq. (19) -----------------------------------------------------------------------

def test_gravity_gradient_matches_eq19_closed_form():
    """CircularOrbit.gravity_gradient = 3 ω_o² c3 × (J c3) with c3 the third column of R^b_o,
    = its principal-axes closed form; |τ| ≤ 3/2 ω_o² (J_max - J_min)."""
    orbit = ORBITS[0]
    n, _ = orbit_rate(orbit)
    q = Rotation.random(200, random_state=7).as_quat()
    t = 321.0
    tau = orbit.gravity_gradient(t, q, J_ESEO)
    c3 = directional_cosines(orbit, t, q)[..., 2]
    assert_allclose(tau, 3 * n ** 2 * np.cross(c3, c3 @ J_ESEO), rtol=1e-12, atol=1e-20)
    assert_allclose(tau, gravity_gradient_principal(n, c3, np.diag(J_ESEO)), rtol=1e-12, atol=1e-20)
    bound = 1.5 * n ** 2 * (4.350 - 3.6640)
    assert np.linalg.norm(tau, axis=1).max() <= bound * (1 + 1e-12)
    assert np.linalg.norm(tau, axis=1).max() > 0.9 * bound


def test_gravity_gradient_equilibria_and_stability():
    """Zero torque at the 24 attitudes with principal axes along the orbit axes; about the
    orbit frame (z = minor axis to nadir) a small pitch θ gives τ_y = -3 ω_o² (J_x - J_z) θ
    (restoring) and a small roll φ τ_x = -3 ω_o² (J_y - J_z) φ (restoring)."""
    orbit = ORBITS[0]
    n, _ = orbit_rate(orbit)
    t = 1000.0
    qo = orbit_frame_attitude(orbit, t)
    for r in Rotation.create_group('O'):
        q = quat_multiply(qo, r.as_quat())
        assert_allclose(orbit.gravity_gradient(t, q, J_ESEO), 0.0, atol=1e-19)
    for axis, k, dJ in ((1, 1, 4.350 - 3.6640), (0, 0, 4.3370 - 3.6640)):
        for ang in (1e-4, -1e-4):
            rv = np.zeros(3)
            rv[axis] = ang
            q = quat_multiply(qo, Rotation.from_rotvec(rv).as_quat())
            tau = orbit.gravity_gradient(t, q, J_ESEO)
            assert tau[k] == pytest.approx(-3 * n ** 2 * dJ * ang, rel=1e-3)
            assert tau[k] * ang < 0
    c3 = rotate_to_body(qo, -orbit.position_unit(t))
    assert_allclose(c3, [0, 0, 1], atol=1e-15)
