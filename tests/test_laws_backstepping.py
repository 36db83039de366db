"""Seed 002's laws (adcs_controllers.laws.backstepping): the actuator matrix of eq. (21) and its
Moore-Penrose allocation (eq. 20), thrust mapping and bang-bang firing, the integrator
backstepping law (eq. 22-35) and the ESEO slew with four thrusters and one pitch wheel on the pure
plant. Choices (lever arms, gains, deadzone) and their evidence: docs/seed002_readings.md.
No ROS; ~6 s in total."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from adcs_controllers.laws import backstepping as bs
from adcs_core.attitude import quat_kinematics, quat_multiply, rotate_to_body
from adcs_core.orbit import CircularOrbit, orbit_frame_attitude, orbit_rate
from adcs_sim.truth.plant import Plant, ReactionWheels, Torquers
from adcs_sim.truth.thrusters import Thrusters, step_pulsed

# Section 4.1: ESEO.
J_ESEO = np.diag([4.350, 4.3370, 3.6640])
ALTITUDE = 250e3
F_MAX = 0.13                       # N
WHEEL_TORQUE = 0.4                 # N m (a torque: R6 of the readings)
WHEEL_INERTIA = 4e-5               # kg m²
WHEEL_SPEED = 5035 * 2 * math.pi / 60   # rad/s
# Section 4.2, scalar first in the paper: q_d = [-0.3772, -0.4329, 0.6645, 0.4783].
QD_PAPER = np.array([-0.3772, -0.4329, 0.6645, 0.4783])
Q_REL = np.r_[QD_PAPER[1:], QD_PAPER[0]] / np.linalg.norm(QD_PAPER)
# Our choices (docs/seed002_readings.md): corner/tangential thrusters on the +z face, i.e.
# eq. (21) with (r_x, r_y, r_z) = (0.3, -0.3, 0.4) m; K1 = 0.1 rad/s, K2 = 4 N m s; deadzone
# 0.013 N (10 % of F_max); control period 0.1 s; minimum on-time 20 ms.
RX, RY, RZ = 0.3, -0.3, 0.4
K1, K2 = 0.1, 4.0
ON_LEVEL = 0.013
PERIOD = 0.1
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def scalar_first_error(q, qd):
    """Eq. (12) printed, on scalar-last inputs: [η̃, ε̃]."""
    eta, eps = q[..., 3], q[..., :3]
    etad, epsd = qd[..., 3], qd[..., :3]
    et = etad * eta + np.sum(epsd * eps, axis=-1)
    ev = etad[..., None] * eps - eta[..., None] * epsd - np.cross(epsd, eps)
    return et, ev


def random_states(seed, n, w_max=0.1):
    rng = np.random.default_rng(seed)
    q = Rotation.random(n, random_state=seed).as_quat()
    qd = Rotation.random(n, random_state=seed + 100).as_quat()
    w = rng.uniform(-w_max, w_max, (n, 3))
    wd = rng.uniform(-w_max, w_max, (n, 3))
    wdd = rng.uniform(-0.01, 0.01, (n, 3))
    return q, w, qd, wd, wdd


# --- eq. (11-14): error quaternion ------------------------------------------------------------------

def test_error_quaternion_is_eq12_and_obeys_eq13_14():
    q, w, qd, wd, wdd = random_states(1, 100)
    _, st = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, K1, K2)
    et, ev = scalar_first_error(q, qd)
    assert_allclose(st['q_err'][:, 3], et, atol=1e-15)
    assert_allclose(st['q_err'][:, :3], ev, atol=1e-15)
    # eq. (13-14) with ω̃ = ω - R(q̃)ᵀ ω_d: finite difference along q̇ and q̇_d
    h = 1e-6
    dq = quat_kinematics(q, w)
    dqd = quat_kinematics(qd, wd)
    qe_p = bs.backstepping_torque(q + h * dq, w, qd + h * dqd, wd, wdd, J_ESEO, K1, K2)[1]['q_err']
    qe_m = bs.backstepping_torque(q - h * dq, w, qd - h * dqd, wd, wdd, J_ESEO, K1, K2)[1]['q_err']
    assert_allclose((qe_p - qe_m) / (2 * h), quat_kinematics(st['q_err'], st['w_err']), atol=1e-8)


def test_g_matrix_identities():
    """G z1 = sgn(η̃) ε̃ (so α1 = -K1 sgn(η̃) ε̃), G Gᵀ = I, V1 = z1ᵀz1 = 2(1 - |η̃|), and
    G z1 = 0 ⇔ ε̃ = 0 (eq. 26)."""
    q, w, qd, wd, wdd = random_states(2, 200)
    _, st = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, K1, K2)
    qe = st['q_err']
    eta, eps = qe[:, 3], qe[:, :3]
    G = bs.g_matrix(eta, eps)
    z1 = st['z1']
    s = np.where(eta >= 0, 1.0, -1.0)
    assert_allclose(np.einsum('nij,nj->ni', G, z1), s[:, None] * eps, atol=1e-15)
    assert_allclose(G @ np.swapaxes(G, 1, 2), np.broadcast_to(np.eye(3), (200, 3, 3)), atol=1e-14)
    assert_allclose(st['V1'], 2 * (1 - np.abs(eta)), atol=1e-14)
    assert_allclose(st['alpha1'], -K1 * s[:, None] * eps, atol=1e-16)
    assert bs.sgn(0.0) == 1.0 and bs.sgn(-0.0) == 1.0 and bs.sgn(-1e-300) == -1.0


def test_alpha1_dot_analytic_matches_finite_difference():
    """Section 3.3: α̇1 = -K1 (Ġ z1 + G ż1) equals dα1/dt along the motion (away from η̃ = 0),
    and equals the short form -K1 sgn(η̃) ε̃̇; K1 as a matrix too."""
    q, w, qd, wd, wdd = random_states(3, 100)
    K1m = np.array([[0.2, 0.05, 0.0], [0.05, 0.1, 0.01], [0.0, 0.01, 0.3]])
    h = 1e-6
    dq, dqd = quat_kinematics(q, w), quat_kinematics(qd, wd)
    for gain in (K1, K1m):
        _, st = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, gain, K2)
        a_p = bs.backstepping_torque(q + h * dq, w, qd + h * dqd, wd, wdd, J_ESEO, gain, K2)[1]['alpha1']
        a_m = bs.backstepping_torque(q - h * dq, w, qd - h * dqd, wd, wdd, J_ESEO, gain, K2)[1]['alpha1']
        away = np.abs(st['q_err'][:, 3]) > 1e-3
        assert_allclose(((a_p - a_m) / (2 * h))[away], st['alpha1_dot'][away], atol=1e-8)
    _, st = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, K1, K2)
    qe, we = st['q_err'], st['w_err']
    eps_dot = quat_kinematics(qe, we)[:, :3]
    s = np.where(qe[:, 3] >= 0, 1.0, -1.0)
    assert_allclose(st['alpha1_dot'], -K1 * s[:, None] * eps_dot, atol=1e-16)


def test_torque_invariant_under_sign_of_q_d():
    """|η̃| and sgn(η̃): q_d and -q_d (the same attitude) give the same torque, bit for bit."""
    q, w, qd, wd, wdd = random_states(4, 100)
    t1, s1 = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, K1, K2)
    t2, s2 = bs.backstepping_torque(q, w, -qd, wd, wdd, J_ESEO, K1, K2)
    assert_array_equal(t1, t2)
    assert_array_equal(s1['V2'], s2['V2'])


def test_v2_derivative_is_minus_w_in_closed_loop():
    """Eq. (33): under the unsaturated torque of eq. (32) applied to the plant (same J, gravity
    gradient on and compensated, q_d turning with the orbit frame), dV2/dt = -W at random
    states: ∂V2/∂t + ∇V2 · ẋ by central differences (h = 1e-6 s), relative 1e-6."""
    orbit = CircularOrbit(ALTITUDE, inclination=0.5)
    ref = bs.OrbitReference(orbit, Q_REL, hold_time=None)
    plant = Plant(J_ESEO, [Torquers()], orbit=orbit, gravity_gradient=True)

    def law(t, x):
        qd, wd, wdd = ref(t)
        return bs.backstepping_torque(x[:4], x[4:7], qd, wd, wdd, J_ESEO, K1, K2,
                                      orbit.gravity_gradient(t, x[:4], J_ESEO))

    q, w, *_ = random_states(5, 20)
    h = 1e-6
    for i in range(20):
        t = 100.0 * i
        x = plant.initial_state(q[i], w[i])
        tau, st = law(t, x)
        xdot = plant.derivative(t, x, {'torquers': tau})
        dV = (law(t + h, x + h * xdot)[1]['V2'] - law(t - h, x - h * xdot)[1]['V2']) / (2 * h)
        assert dV == pytest.approx(-st['W'], rel=1e-6, abs=1e-12)
        assert st['W'] > 0


# --- eq. (20-21): actuator matrix and allocation -------------------------------------------------------

def test_actuator_matrix_from_geometry_is_eq21():
    for rx, ry, rz in ((RX, RY, RZ), (0.3, 0.1, 0.4), (0.12, 0.27, -0.35)):
        p, d = bs.eseo_thruster_layout(rx, ry, rz)
        assert_allclose(bs.actuator_matrix(p, d, (0, 1, 0)), bs.eseo_actuator_matrix(rx, ry, rz), atol=1e-15)
        thr = Thrusters(['a', 'b', 'c', 'd'], p, d, F_MAX)
        assert_allclose(thr.torque_matrix, bs.eseo_actuator_matrix(rx, ry, rz)[:, :4], atol=1e-15)


def test_pseudo_inverse_identity_and_minimum_norm():
    """B_a B_a† = I (section 2.5.1), B_a† = B_aᵀ(B_a B_aᵀ)⁻¹, and u = B_a† τ has the least norm
    of all u with B_a u = τ (adding null-space vectors only lengthens it)."""
    B = bs.eseo_actuator_matrix(RX, RY, RZ)
    P = bs.pseudo_inverse(B)
    assert_allclose(B @ P, np.eye(3), atol=1e-14)
    assert_allclose(P, B.T @ np.linalg.inv(B @ B.T), atol=1e-13)
    rng = np.random.default_rng(6)
    N = np.linalg.svd(B)[2][3:].T          # (5, 2) null space
    tau = rng.normal(size=(50, 3))
    u = np.einsum('ij,nj->ni', P, tau)
    assert_allclose(u @ B.T, tau, atol=1e-13)
    for _ in range(20):
        v = u + rng.normal(size=(50, 2)) @ N.T
        assert_allclose(v @ B.T, tau, atol=1e-12)
        assert np.all(np.linalg.norm(v, axis=1) >= np.linalg.norm(u, axis=1) - 1e-12)


def test_square_face_corner_thrusters_pointing_inward_are_singular():
    """Eq. (21) with r_x = r_y (thrust lines through the z axis): no yaw torque, B_a has rank 2
    and B_a B_aᵀ is singular (why r_x ≠ r_y, readings R3)."""
    B = bs.eseo_actuator_matrix(0.3, 0.3, 0.4)
    assert np.linalg.matrix_rank(B) == 2
    with pytest.raises(ValueError, match='rank 2'):
        bs.pseudo_inverse(B)


def test_wheel_gyro_matrix_is_printed_da():
    h = 0.7
    assert_allclose(bs.wheel_gyro_matrix(h), [[0, 0, -h], [0, 0, 0], [h, 0, 0]], atol=0)
    w = np.array([0.3, -0.2, 0.5])
    assert_allclose(bs.wheel_gyro_matrix(h) @ w, np.cross(w, [0, h, 0]), atol=1e-16)


def test_allocation_gives_the_plant_the_requested_torque():
    """Eq. (20) signs against the plant: signed thruster forces (as ideal torquers T F) and the
    wheel motor torque τ_m = -ḣ_wy with the paper's h_wy = -(wheel momentum) make
    J_s ω̇ + ω × (J_s ω) equal to the requested τ_a (the wheel's gyroscopic torque included)."""
    rng = np.random.default_rng(8)
    p, d = bs.eseo_thruster_layout(RX, RY, RZ)
    alloc = bs.ThrusterWheelAllocation(p, d, F_MAX, wheel_inertia=WHEEL_INERTIA)
    wheels = ReactionWheels(['rw'], [[0, 1, 0]], [WHEEL_INERTIA], [np.inf], [np.inf])
    plant = Plant(J_ESEO, [Torquers(), wheels])
    for _ in range(10):
        tau = rng.normal(size=3) * 0.05
        w = rng.normal(size=3) * 0.1
        speed = rng.uniform(-500, 500)
        _, tau_m, info = alloc.command(tau, w, speed)
        u = info['u']
        x = np.concatenate([IDENTITY, w, [speed, 0.0]])
        cmds = {'torquers': alloc.B[:, :4] @ u[:4], 'wheels': wheels.zero_command()._replace(value=np.array([tau_m]))}
        wdot = plant.derivative(0.0, x, cmds)[4:7]
        Js = plant.inertia_struct
        assert_allclose(Js @ wdot + np.cross(w, Js @ w), tau, atol=1e-12)


def test_nullspace_mapping_keeps_torque_and_pairs_do_not():
    """'nullspace': all demands >= 0, one of them 0 (the least shift), same torque, zero extra
    force; 'pairs': non-negative, exact in x/y but reverses the yaw of the moved part (the
    opposed thruster's yaw torque has the same sign in eq. 21)."""
    p, d = bs.eseo_thruster_layout(RX, RY, RZ)
    T = bs.actuator_matrix(p, d, None)
    n = bs.positive_null_vector(T)
    assert_allclose(n, [1, 1, 1, 1], atol=1e-12)
    pairs = bs.opposed_pairs(d)
    assert_array_equal(pairs, [3, 2, 1, 0])
    rng = np.random.default_rng(9)
    Fs = rng.normal(size=(100, 3)) @ bs.pseudo_inverse(T).T     # minimum norm: sum F = 0
    D = bs.thrust_demand(Fs, 'nullspace', null_vector=n)
    assert np.all(D >= 0)
    assert_allclose(D.min(axis=1), 0.0, atol=1e-15)
    assert_allclose(D @ T.T, Fs @ T.T, atol=1e-14)
    P = bs.thrust_demand(Fs, 'pairs', pairs=pairs)
    assert np.all(P >= 0)
    assert_allclose((P @ T.T)[:, :2], (Fs @ T.T)[:, :2], atol=1e-14)
    assert np.abs((P @ T.T)[:, 2] - (Fs @ T.T)[:, 2]).max() > 0.1 * np.abs((Fs @ T.T)[:, 2]).max()
    with pytest.raises(ValueError):
        bs.thrust_demand(Fs, 'scale')


def test_bang_bang_deadzone_and_hysteresis():
    demand = np.array([0.0, 0.012, 0.013, 0.014, 0.5])
    assert_array_equal(bs.bang_bang(demand, 0.013), [False, False, False, True, True])
    seq = [0.02, 0.01, 0.006, 0.01, 0.014, 0.0]
    on, out_plain, out_hyst = None, [], []
    for dmd in seq:
        out_plain.append(bool(bs.bang_bang(dmd, 0.013)))
        on = bs.bang_bang(dmd, 0.013, 0.0065, on)
        out_hyst.append(bool(on))
    assert out_plain == [True, False, False, False, True, False]
    assert out_hyst == [True, True, False, False, True, False]
    with pytest.raises(ValueError):
        bs.bang_bang(demand, 0.01, 0.02)
    # batch state: each run keeps its own trigger
    st = bs.bang_bang(np.array([[0.02], [0.0]]), 0.013, 0.0065, None)
    st = bs.bang_bang(np.array([[0.01], [0.01]]), 0.013, 0.0065, st)
    assert_array_equal(st, [[True], [False]])


def test_allocation_respects_wheel_limits():
    """The wheel is never commanded past its torque limit nor past its speed limit within the
    period; the rest of the torque goes to the thrusters (R5)."""
    p, d = bs.eseo_thruster_layout(RX, RY, RZ)
    alloc = bs.ThrusterWheelAllocation(p, d, F_MAX, wheel_inertia=WHEEL_INERTIA, wheel_max_torque=WHEEL_TORQUE,
                                       wheel_max_speed=WHEEL_SPEED, period=PERIOD)
    rng = np.random.default_rng(10)
    tau = rng.normal(size=(500, 3))
    speed = rng.uniform(-WHEEL_SPEED, WHEEL_SPEED, 500)
    _, tau_m, info = alloc.command(tau, np.zeros((500, 3)), speed)
    assert np.all(np.abs(tau_m) <= WHEEL_TORQUE)
    assert np.all(np.abs(speed + tau_m / WHEEL_INERTIA * PERIOD) <= WHEEL_SPEED * (1 + 1e-12))
    assert_allclose(info['u'] @ alloc.B.T, tau, atol=1e-12)   # thrusters take up the difference


# --- batch == loop ---------------------------------------------------------------------------------------

def test_batch_equals_loop_bit_identical():
    q, w, qd, wd, wdd = random_states(11, 30)
    K1s = np.linspace(0.05, 0.3, 30)
    tau_b, st_b = bs.backstepping_torque(q, w, qd, wd, wdd, J_ESEO, K1s, K2, tau_g=w * 1e-4)
    p, d = bs.eseo_thruster_layout(RX, RY, RZ)
    alloc_b = bs.ThrusterWheelAllocation(p, d, F_MAX, wheel_inertia=WHEEL_INERTIA, wheel_max_torque=WHEEL_TORQUE,
                                         wheel_max_speed=WHEEL_SPEED, on_level=ON_LEVEL, off_level=ON_LEVEL / 2)
    speed = np.linspace(-WHEEL_SPEED, WHEEL_SPEED, 30)
    on_b, tm_b, _ = alloc_b.command(tau_b * 0.02, w, speed)
    on_b2, _, _ = alloc_b.command(tau_b * 0.01, w, speed)
    for i in range(30):
        tau_i, st_i = bs.backstepping_torque(q[i], w[i], qd[i], wd[i], wdd[i], J_ESEO, K1s[i], K2, tau_g=w[i] * 1e-4)
        assert_array_equal(tau_b[i], tau_i)
        for k in ('V1', 'V2', 'W', 'z2', 'alpha1_dot'):
            assert_array_equal(st_b[k][i], st_i[k])
        alloc = bs.ThrusterWheelAllocation(p, d, F_MAX, wheel_inertia=WHEEL_INERTIA, wheel_max_torque=WHEEL_TORQUE,
                                           wheel_max_speed=WHEEL_SPEED, on_level=ON_LEVEL, off_level=ON_LEVEL / 2)
        on_i, tm_i, _ = alloc.command(tau_i * 0.02, w[i], speed[i])
        on_i2, _, _ = alloc.command(tau_i * 0.01, w[i], speed[i])
        assert_array_equal(on_b[i], on_i)
        assert_array_equal(tm_b[i], tm_i)
        assert_array_equal(on_b2[i], on_i2)


def test_actuation_takes_one_off_level_per_run_with_a_shared_on_level():
    """firing.off_level dispersed, on_level shared (as a campaign's batch stacks them): each run keeps
    its own Schmitt trigger, fires as it does alone, and the off levels give different firings."""
    from adcs_controllers.families import BACKSTEPPING
    from adcs_sim.app.scenario.files import validate_scenario
    section = validate_scenario(Path(__file__).parents[1] / 'config' / 'eseo_backstepping_slew.yaml')
    p = section[BACKSTEPPING.schema.node]
    offs = [0.002, 0.006, 0.012]
    batch = bs.ThrusterActuation({**p, 'firing.off_level': np.array(offs)})
    alone = [bs.ThrusterActuation({**p, 'firing.off_level': off}) for off in offs]
    tau = np.array([0.0, 0.0, 0.017])   # demands of 0.020 N on two thrusters at scale 1 (on_level 0.013)
    w, speed = np.zeros((3, 3)), np.zeros((3, 1))
    fired = []
    for scale in (1.0, 0.8, 0.5, 0.25, 0.05, 1.0):   # demands 0.020, 0.016, 0.010, 0.005, 0.001, 0.020
        on_b, tm_b, _ = batch.command(np.tile(scale * tau, (3, 1)), w, speed)
        for i, act in enumerate(alone):
            on_i, tm_i, _ = act.command(scale * tau, w[i], speed[i])
            assert_array_equal(on_b[i], on_i)
            assert_array_equal(tm_b[i], tm_i)
        fired.append(on_b.sum(axis=-1) > 0)
    assert [list(f) for f in zip(*fired)] == [[True, True, True, True, False, True],
                                              [True, True, True, False, False, True],
                                              [True, True, False, False, False, True]]


# --- reference trajectory ----------------------------------------------------------------------------------

def test_orbit_reference_rates():
    """Orbit-fixed target: q_d = q_io ⊗ q_rel turns with ω^d_id = R(q_rel)ᵀ[0, -ω_o, 0]
    (finite difference); held target: constant q_d, zero rate, from hold_time on."""
    orbit = CircularOrbit(ALTITUDE, inclination=0.9)
    ref = bs.OrbitReference(orbit, Q_REL, hold_time=None)
    t, h = 700.0, 1e-2
    qd, wd, wdd = ref(t)
    dq = (ref(t + h)[0] - ref(t - h)[0]) / (2 * h)
    assert_allclose(dq, quat_kinematics(qd, wd), atol=1e-11)
    assert_allclose(np.linalg.norm(wd), orbit.mean_motion, rtol=1e-14)
    assert_array_equal(wdd, 0.0)
    held = bs.OrbitReference(orbit, Q_REL, hold_time=300.0)
    assert_allclose(held(100.0)[0], bs.OrbitReference(orbit, Q_REL, None)(100.0)[0], atol=0)
    assert_allclose(held(300.0)[0], quat_multiply(orbit_frame_attitude(orbit, 300.0), Q_REL), atol=0)
    assert_array_equal(held(5000.0)[0], held(300.0)[0])
    assert_array_equal(held(5000.0)[1], 0.0)


# --- the ESEO slew (section 4) --------------------------------------------------------------------------------

def eseo_run(duration, q_rel0=IDENTITY, mapping='nullspace', hold=0.0):
    """Section 4.2 on the pure plant: the body starts aligned with the orbit frame at perigee
    (at rest in it) and is commanded to q_d = q_io(0) ⊗ q_rel, then held inertially."""
    orbit = CircularOrbit(ALTITUDE)
    p, d = bs.eseo_thruster_layout(RX, RY, RZ)
    thr = Thrusters([f't{i}' for i in range(4)], p, d, F_MAX, min_on_time=0.02)
    rw = ReactionWheels(['rw'], [[0, 1, 0]], [WHEEL_INERTIA], [WHEEL_TORQUE], [WHEEL_SPEED])
    plant = Plant(J_ESEO, [thr, rw], orbit=orbit, gravity_gradient=True)
    alloc = bs.ThrusterWheelAllocation(p, d, F_MAX, wheel_inertia=WHEEL_INERTIA, wheel_max_torque=WHEEL_TORQUE,
                                       wheel_max_speed=WHEEL_SPEED, mapping=mapping, on_level=ON_LEVEL,
                                       period=PERIOD)
    law = bs.BacksteppingLaw({'inertia': [4.350, 4.3370, 3.6640], 'target.attitude': Q_REL,
                              'target.rate': [0.0, 0.0, 0.0], 'K1': K1, 'K2': K2,
                              'orbit.altitude': ALTITUDE, 'reference.hold_time': hold})
    qo = orbit_frame_attitude(orbit, 0.0)
    q0 = quat_multiply(qo, q_rel0)
    w0 = rotate_to_body(q_rel0, orbit_rate(orbit)[1])
    x = plant.initial_state(q0, w0)
    n = int(round(duration / PERIOD))
    angle, V2, on_total = np.empty(n), np.empty(n), 0.0
    for k in range(n):
        t = k * PERIOD
        tau, st = law.control(t, x[:4], x[4:7])
        on_time, tau_m, _ = alloc.command(tau, x[4:7], x[plant.slices['wheels']][0])
        cmds = {'thrusters': thr.command(t, on_time, PERIOD),
                'wheels': rw.zero_command()._replace(value=np.array([tau_m]))}
        on_total += on_time.sum()
        angle[k], V2[k] = st['angle'], st['V2']
        x = step_pulsed(plant, t, x, cmds, PERIOD, PERIOD)
    return np.degrees(angle), V2, x[plant.slices['thrusters']], on_total, x


def settling_time(deg, tol=1.0):
    above = np.nonzero(deg > tol)[0]
    return 0.0 if above.size == 0 else (above[-1] + 1) * PERIOD


@pytest.mark.paper
@pytest.mark.slow
def test_eseo_slew_settles_and_holds():
    """Paper: settles in ~38 s (Fig. 1), then holds the inertial attitude (Fig. 2). Ours
    (documented choices): the 135.68° slew (q̃(0) has η̃ = -0.3772: the short way is to
    q̃ = -1) settles below 1° at 38.2 s; asserted < 60 s and within 3 s of ours. The error then
    stays below 1° from 60 s to the end of a 300 s run (ours: 0.31° max; 0.98° max over two
    orbits, docs/seed002_readings.md). Total impulse = F × total on-time exactly (ours 7.90 N s,
    608 firings; asserted < 12 N s)."""
    deg, V2, impulse, on_total, _ = eseo_run(300.0)
    assert deg[0] == pytest.approx(135.68, abs=0.01)
    ts = settling_time(deg)
    assert ts < 60.0, ts
    assert ts == pytest.approx(38.2, abs=3.0)
    assert deg[int(round(60.0 / PERIOD)):].max() < 1.0
    assert impulse.sum() == pytest.approx(F_MAX * on_total, rel=1e-12)
    assert impulse.sum() < 12.0
    assert V2[-1] < 1e-3 * V2[0]


def test_start_near_minus_one_does_not_unwind():
    """q̃(0) = [-cos 2.5°, sin 2.5° e] (5° from the target, on the η̃ < 0 side): the law goes
    to q̃ = [-1, 0, 0, 0] directly; the error never exceeds the initial 5° (+0.5°), whereas a
    law driving η̃ to +1 would turn 355°."""
    e = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
    half = math.radians(2.5)
    qe0 = np.r_[math.sin(half) * e, math.cos(half)] * -1.0          # η̃ < 0
    # body relative to the orbit frame: q_rel ⊗ q̃ (so that q̄_d ⊗ q = q̃)
    q_rel0 = quat_multiply(Q_REL, qe0)
    deg, V2, impulse, _, _ = eseo_run(60.0, q_rel0=q_rel0)
    assert deg[0] == pytest.approx(5.0, abs=1e-6)
    assert deg.max() < 5.5
    assert deg[-1] < 1.0
    assert impulse.sum() < 1.0
