"""Physics of the plant core (adcs_sim.truth.plant, adcs_core.attitude): pure numpy, no ROS.

Conventions under test (plant.py docstring): ``J`` is the TOTAL inertia (wheels' spin inertia
included), ``J_s = J - sum_i Js_i a_i a_i^T``, wheel speeds ``Omega`` are relative to the body and
the total angular momentum is ``H = J w + sum_i a_i Js_i Omega_i``.

For a wheel along a principal axis ``k`` of a body at rest (no external torque) the motion stays
one-dimensional (``w x H = 0``) and a wheel torque ``tau`` gives exactly::

    J_s,k dw/dt = -tau,      Js (dw/dt + dOmega/dt) = tau
    =>  dOmega/dt = tau * J_k / (Js * J_s,k),    J_k w + Js Omega = const

which is what the closed forms below use (``k_eff = J_k / (Js * J_s,k)``).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from adcs_core.attitude import euler_213, quat_kinematics, rotate_to_body, rotate_to_inertial
from adcs_core.orbit import CircularOrbit
from adcs_sim.truth.plant import Disturbance, Plant, ReactionWheels, Torquers

INF = np.inf
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def make_wheels(axes, spin_inertia, **kw) -> ReactionWheels:
    axes = np.atleast_2d(np.asarray(axes, dtype=float))
    n = axes.shape[0]
    kw.setdefault('max_torque', [INF] * n)
    kw.setdefault('max_speed', [INF] * n)
    return ReactionWheels(names=[f'rw{i}' for i in range(n)], axes=axes,
                          spin_inertia=np.broadcast_to(spin_inertia, (n,)), **kw)


def torque_cmd(plant: Plant, value, speed_mode=None) -> dict:
    wheels = plant.actuator('wheels')
    value = np.asarray(value, dtype=float)
    mode = np.zeros(wheels.count, dtype=bool) if speed_mode is None else np.asarray(speed_mode, bool)
    cmds = plant.zero_commands()
    cmds['wheels'] = wheels.zero_command()._replace(value=value, speed_mode=mode)
    return cmds


def propagate(plant: Plant, x, commands, duration, period, max_step, t0=0.0):
    """Hold ``commands`` for ``duration`` seconds in steps of ``period``; return (times, states)."""
    n = int(round(duration / period))
    times, states = [t0], [np.array(x, copy=True)]
    for k in range(n):
        x = plant.step(t0 + k * period, x, commands, period, max_step)
        times.append(t0 + (k + 1) * period)
        states.append(x)
    return np.array(times), np.array(states)


def same_rotation(q1, q2, atol):
    """Quaternions equal up to the global sign (q and -q are the same attitude)."""
    q1, q2 = np.asarray(q1), np.asarray(q2)
    sign = np.where(np.sum(q1 * q2, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    assert_allclose(q1, sign * q2, rtol=0, atol=atol)


# --- conservation laws --------------------------------------------------------------------------

SKEWED_AXES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]) / np.array([[1], [1], [1], [math.sqrt(3)]])
SKEWED_JS = np.array([0.01, 0.02, 0.015, 0.01])


def test_torque_free_conserves_inertial_momentum_and_energy():
    """No external torque, no motor torque, no friction: inertial H and kinetic energy constant.

    Non-symmetric total inertia diag(12, 14, 10), 3 orthogonal + 1 skewed wheel at different
    speeds, nonzero body rate, 10 000 s; three initial conditions at once on the batch axis.

    Tolerances. Relative drift of inertial H <= 1e-9 (requirement). Kinetic energy: the exact flow
    conserves T; RK4 is not symplectic, so T drifts secularly by the local truncation error,
    O((omega h)^5) per step, the same order as the momentum drift (T does not depend on q, so the
    quaternion renormalisation does not touch it). The fastest body frequency here is
    omega ~ |H| / J_min ~ 0.02 rad/s (wheel momentum dominates), so omega h ~ 0.025 with
    h = 1.25 s; measured over the 8000 steps: H drift 4.7e-11, energy drift 1.4e-13. We require
    1e-10 relative on T: ~700x the measured truncation drift, and still far below what any
    modelling error in the energy or the equations of motion gives (a wheel-momentum term
    missing the body rate drifts H by ~1e-3 here).
    """
    plant = Plant(np.diag([12.0, 14.0, 10.0]), [make_wheels(SKEWED_AXES, SKEWED_JS)])
    q0 = np.array([0.1, 0.2, -0.3, 0.9]) / np.linalg.norm([0.1, 0.2, -0.3, 0.9])
    x = []
    for s in (1.0, -0.7, 0.4):
        xi = plant.initial_state(q0, s * np.array([1e-3, -2e-3, 3e-3]))
        xi[7:11] = s * np.array([10.0, -5.0, 3.0, 8.0])  # rad/s relative to the body
        x.append(xi)
    x = np.array(x)
    H0 = plant.inertial_momentum(x)
    T0 = plant.kinetic_energy(x)
    _, states = propagate(plant, x, plant.zero_commands(), 10_000.0, period=10.0, max_step=1.25)
    H = plant.inertial_momentum(states)
    T = plant.kinetic_energy(states)
    drift_H = np.linalg.norm(H - H0, axis=-1) / np.linalg.norm(H0, axis=-1)
    assert drift_H.max() <= 1e-9, drift_H.max()
    assert np.abs(T / T0 - 1).max() <= 1e-10
    # The attitude really moved (the test is not trivially satisfied by a body at rest).
    assert np.abs(states[-1, :, :4] - x[:, :4]).max() > 0.1


def test_internal_torques_conserve_inertial_momentum():
    """Motor torques (torque and speed mode) and wheel friction are internal: inertial H constant."""
    wheels = make_wheels(SKEWED_AXES, SKEWED_JS, viscous=[1e-4] * 4, coulomb=[2e-5] * 4,
                         speed_gain=[0.05] * 4, max_torque=[0.005] * 4)
    plant = Plant(np.diag([12.0, 14.0, 10.0]), [wheels])
    x = plant.initial_state(IDENTITY, [2e-3, -1e-3, 4e-3])
    x[7:11] = [5.0, -3.0, 2.0, 4.0]
    H0 = plant.inertial_momentum(x)
    cmds = torque_cmd(plant, [0.002, -0.001, 20.0, -0.003], speed_mode=[False, False, True, False])
    _, states = propagate(plant, x, cmds, 300.0, period=10.0, max_step=0.5)
    assert_allclose(plant.inertial_momentum(states), np.broadcast_to(H0, states[:, :3].shape),
                    rtol=0, atol=1e-9 * np.linalg.norm(H0))
    assert abs(states[-1, 9] - 20.0) < abs(x[9] - 20.0)  # the speed loop did something


def test_axisymmetric_body_nutation_closed_form():
    """I = diag(It, It, Ia), no wheels, no torque: w3 constant and (w1, w2) rotate at
    lambda = (Ia - It)/It * w3, i.e. w1 + i w2 = (w1(0) + i w2(0)) exp(i lambda t).

    Also the nutation angle (between body z and the inertial H) stays at acos(Ia w3 / |H|).
    Tolerance: RK4's phase error on a rotation at lambda with step h is ~ (lambda h)^4 / 120 per
    radian turned; lambda h = 0.01, 16 rad turned -> ~1.3e-9 of the amplitude (0.022 rad/s), i.e.
    ~3e-11 rad/s (measured 2.9e-11). We assert 1e-10 rad/s on every sample, 600 times.
    """
    It, Ia = 10.0, 14.0
    plant = Plant(np.diag([It, It, Ia]))
    w0 = np.array([0.02, -0.01, 0.1])
    x = plant.initial_state(IDENTITY, w0)
    t, states = propagate(plant, x, {}, 400.0, period=1.0, max_step=0.25)
    lam = (Ia - It) / It * w0[2]
    expected = (w0[0] + 1j * w0[1]) * np.exp(1j * lam * t)
    w = states[:, 4:7]
    assert lam * t[-1] > 4 * math.pi  # two full turns of the transverse rate
    assert_allclose(w[:, 0], expected.real, rtol=0, atol=1e-10)
    assert_allclose(w[:, 1], expected.imag, rtol=0, atol=1e-10)
    assert_allclose(w[:, 2], w0[2], rtol=0, atol=1e-15)
    H = plant.inertial_momentum(states)
    z_inertial = rotate_to_inertial(states[:, :4], np.array([0.0, 0.0, 1.0]))
    cos_nut = np.sum(z_inertial * H, axis=-1) / np.linalg.norm(H, axis=-1)
    assert_allclose(cos_nut, Ia * w0[2] / np.linalg.norm(np.diag([It, It, Ia]) @ w0), rtol=0, atol=1e-10)


# --- wheels ----------------------------------------------------------------------------------------

J_DIAG = np.diag([10.0, 12.0, 8.0])


def k_eff(J_k, Js):
    """dOmega/dt per unit motor torque for a wheel on principal axis k of a body at rest."""
    return J_k / (Js * (J_k - Js))


def test_spin_up_principal_axis_uses_total_inertia():
    """Body at rest, wheel on x, constant motor torque: dw = -(Js / J_x) dOmega with J_x the TOTAL
    inertia (incl. the wheel spin inertia), to 1e-12; a large wheel (Js/J = 5 %) makes the other
    convention (-(Js/J_s,x) dOmega) fail by 5 %."""
    Js, tau, T = 0.5, 0.02, 50.0
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js)])
    x0 = plant.initial_state(IDENTITY, np.zeros(3))
    _, states = propagate(plant, x0, torque_cmd(plant, [tau]), T, period=5.0, max_step=0.5)
    w, dOmega = states[-1, 4:7], states[-1, 7] - x0[7]
    assert_allclose(dOmega, tau * T * k_eff(10.0, Js), rtol=1e-12)
    assert_allclose(w, [-(Js / 10.0) * dOmega, 0.0, 0.0], rtol=1e-12, atol=1e-15)
    assert abs(w[0] - (-(Js / (10.0 - Js)) * dOmega)) > 1e-3 * abs(w[0])


def test_spin_up_skewed_wheel():
    """Skewed wheel on a body with a full (non-diagonal) inertia: dw = -J^{-1} a Js dOmega."""
    J = np.array([[10.0, 0.5, 0.2], [0.5, 12.0, -0.3], [0.2, -0.3, 8.0]])
    a = np.array([1.0, 2.0, 2.0]) / 3.0
    Js, tau, T = 0.3, 0.01, 40.0
    plant = Plant(J, [make_wheels(a * 3.0, Js)])  # axis is normalised by ReactionWheels
    x0 = plant.initial_state(IDENTITY, np.zeros(3))
    _, states = propagate(plant, x0, torque_cmd(plant, [tau]), T, period=4.0, max_step=0.5)
    dOmega = states[-1, 7]
    assert dOmega > 1.0
    assert_allclose(states[-1, 4:7], -np.linalg.solve(J, a) * Js * dOmega, rtol=1e-12, atol=1e-16)
    # and the wheel speed itself: Js (a . dw/dt + dOmega/dt) = tau with J_s dw/dt = -a tau
    J_s = J - Js * np.outer(a, a)
    assert_allclose(dOmega, tau * T * (1.0 / Js + a @ np.linalg.solve(J_s, a)), rtol=1e-12)


def test_failed_wheel_produces_no_torque():
    """wheels.available[2] = False with torque commands on all 3 wheels (body at rest, wheels at
    rest, so H = 0 and the motion is exactly linear): wheel 2 gets no motor torque and its speed
    does not change, wheels 0 and 1 spin up exactly as the closed form says, and the run is
    identical to commanding zero on wheel 2."""
    Js = np.array([0.05, 0.04, 0.03])
    tau = np.array([0.01, -0.02, 0.03])
    T = 30.0

    def run(available, cmd, omega2=0.0):
        plant = Plant(J_DIAG, [make_wheels(np.eye(3), Js)])
        plant.actuator('wheels').available[:] = available
        x0 = plant.initial_state(IDENTITY, np.zeros(3))
        x0[9] = omega2
        return plant, propagate(plant, x0, torque_cmd(plant, cmd), T, period=3.0, max_step=0.5)[1]

    plant, failed = run([True, True, False], tau)
    wheels = plant.actuator('wheels')
    assert_array_equal(wheels.motor_torque(failed[-1, 7:10], torque_cmd(plant, tau)['wheels']),
                       [tau[0], tau[1], 0.0])
    # (H = 0 exactly in exact arithmetic; roundoff leaves ~1e-18)
    assert_allclose(failed[:, 9], 0.0, rtol=0, atol=1e-15)
    assert_allclose(failed[:, 6], 0.0, rtol=0, atol=1e-15)
    Jk = np.diag(J_DIAG)
    dOmega = tau[:2] * T * k_eff(Jk[:2], Js[:2])
    assert_allclose(failed[-1, 7:9], dOmega, rtol=1e-12)
    assert_allclose(failed[-1, 4:6], -(Js[:2] / Jk[:2]) * dOmega, rtol=1e-12)
    _, zeroed = run([True, True, True], [tau[0], tau[1], 0.0])
    assert_array_equal(failed, zeroed)


def test_failed_spinning_wheel_keeps_its_absolute_speed():
    """A failed wheel that spins (H != 0, so the body couples the axes): no motor torque means
    Js (a . dw/dt + dOmega/dt) = 0, i.e. its absolute spin Omega + a . w stays constant while its
    speed relative to the body does change; identical to a zero command on a healthy wheel."""
    Js = np.array([0.05, 0.04, 0.03])
    tau = np.array([0.01, -0.02, 0.03])
    plants, runs = [], []
    for available, cmd in (([True, True, False], tau), ([True, True, True], [tau[0], tau[1], 0.0])):
        plant = Plant(J_DIAG, [make_wheels(np.eye(3), Js)])
        plant.actuator('wheels').available[:] = available
        x0 = plant.initial_state(IDENTITY, np.zeros(3))
        x0[9] = 70.0
        runs.append(propagate(plant, x0, torque_cmd(plant, cmd), 30.0, period=3.0, max_step=0.5)[1])
        plants.append(plant)
    failed = runs[0]
    assert_allclose(failed[:, 9] + failed[:, 6], 70.0, rtol=1e-13)
    assert np.abs(failed[:, 9] - 70.0).max() > 1e-6   # the relative speed moved
    assert_array_equal(failed, runs[1])
    # RK4 truncation only: body rates reach ~0.06 rad/s, omega h ~ 0.03 -> ~1e-9 relative drift
    assert_allclose(plants[0].inertial_momentum(failed), np.tile([0.0, 0.0, 0.03 * 70.0], (len(failed), 1)),
                    rtol=0, atol=1e-8 * 0.03 * 70.0)


def test_torque_limit_clips():
    """Commanded +-1 N m with a 0.01 N m limit: the wheel spins up at the limit torque."""
    Js, limit, T = 0.05, 0.01, 20.0
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, max_torque=[limit])])
    x0 = np.stack([plant.initial_state(IDENTITY, np.zeros(3))] * 2)
    cmd = torque_cmd(plant, [[1.0], [-1.0]])
    assert_array_equal(plant.actuator('wheels').motor_torque(x0[:, 7:8], cmd['wheels']), [[limit], [-limit]])
    _, states = propagate(plant, x0, cmd, T, period=2.0, max_step=0.5)
    assert_allclose(states[-1, :, 7], [limit * T * k_eff(10.0, Js), -limit * T * k_eff(10.0, Js)], rtol=1e-12)


def test_speed_limit_cuts_only_torque_that_spins_faster():
    """At |Omega| = max_speed, torque of the same sign as Omega is cut (nothing moves); torque
    that slows the wheel is applied in full."""
    Js, vmax, tau, T = 0.05, 100.0, 0.01, 20.0
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, max_speed=[vmax])])
    x0 = np.stack([plant.initial_state(IDENTITY, np.zeros(3))] * 4)
    x0[:, 7] = [vmax, -vmax, vmax, -vmax]
    cmd = torque_cmd(plant, [[tau], [-tau], [-tau], [tau]])
    _, states = propagate(plant, x0, cmd, T, period=2.0, max_step=0.5)
    end = states[-1]
    assert_array_equal(end[:2, 7], [vmax, -vmax])          # would spin faster: cut
    assert_array_equal(end[:2, 4:7], 0.0)
    dOmega = tau * T * k_eff(10.0, Js)
    assert_allclose(end[2:, 7], [vmax - dOmega, -vmax + dOmega], rtol=1e-12)  # slows: applied


def test_speed_limit_reached_from_below():
    """Spinning up towards the limit, the wheel stops accelerating within one RK4 step of it."""
    Js, vmax, tau, h = 0.05, 100.0, 0.01, 0.5
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, max_speed=[vmax])])
    x0 = plant.initial_state(IDENTITY, np.zeros(3))
    x0[7] = 99.0
    rate = tau * k_eff(10.0, Js)  # rad/s^2, reaches the limit after ~4.75 s
    _, states = propagate(plant, x0, torque_cmd(plant, [tau]), 60.0, period=1.0, max_step=h)
    assert vmax <= states[-1, 7] <= vmax + rate * h
    assert_array_equal(states[-20:, 7], states[-1, 7])  # no longer accelerating


def test_speed_mode_converges_exponentially():
    """Speed mode tau = Js g (Omega_c - Omega): Omega -> Omega_c exponentially. Coupled with the
    body the rate is exactly g J_k / J_s,k (body on a principal axis, at rest); with a huge body
    inertia that is the loop gain g, i.e. time constant 1/speed_gain."""
    g, Js, cmd, T = 0.2, 0.05, 50.0, 25.0
    for J_k, rtol_gain in ((1e6, 1e-7), (10.0, None)):
        plant = Plant(np.diag([J_k, J_k + 1, J_k + 2]), [make_wheels([1, 0, 0], Js, speed_gain=[g])])
        x0 = plant.initial_state(IDENTITY, np.zeros(3))
        t, states = propagate(plant, x0, torque_cmd(plant, [cmd], [True]), T, period=1.0, max_step=0.1)
        rate = g * J_k / (J_k - Js)
        assert_allclose(states[:, 7], cmd * (1 - np.exp(-rate * t)), rtol=0, atol=1e-9 * cmd)
        if rtol_gain is not None:  # huge body: time constant 1/g
            assert_allclose(states[:, 7], cmd * (1 - np.exp(-g * t)), rtol=0, atol=rtol_gain * cmd)
        assert abs(states[-1, 7] - cmd) < 0.01 * cmd


def test_speed_mode_saturates_at_torque_limit():
    """Far from the set-point the speed loop asks more than the limit: a linear ramp at the limit."""
    g, Js, limit = 1.0, 0.05, 0.01
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, speed_gain=[g], max_torque=[limit])])
    x0 = plant.initial_state(IDENTITY, np.zeros(3))
    # loop torque Js g (1000 - Omega) >= 0.05 * 800 >> 0.01 for the whole run
    _, states = propagate(plant, x0, torque_cmd(plant, [1000.0], [True]), 10.0, period=1.0, max_step=0.5)
    assert_allclose(states[-1, 7], limit * 10.0 * k_eff(10.0, Js), rtol=1e-12)


def test_viscous_friction_decays_free_wheel_exponentially():
    """Friction -c Omega between wheel and body (no motor torque): Omega = Omega0 exp(-k t) with
    k = c J_k / (Js J_s,k), and the body picks up what the wheel loses: J_k w + Js Omega = Js Omega0."""
    c, Js, Omega0 = 1e-3, 0.05, 100.0
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, viscous=[c])])
    x0 = plant.initial_state(IDENTITY, np.zeros(3))
    x0[7] = Omega0
    t, states = propagate(plant, x0, plant.zero_commands(), 200.0, period=5.0, max_step=0.5)
    k = c * k_eff(10.0, Js)
    assert k * t[-1] > 4
    assert_allclose(states[:, 7], Omega0 * np.exp(-k * t), rtol=1e-9)
    assert_allclose(10.0 * states[:, 4] + Js * states[:, 7], Js * Omega0, rtol=1e-12)


def test_coulomb_friction_decelerates_linearly_and_stops():
    """Friction -f sign(Omega): constant deceleration f J_k / (Js J_s,k) until the wheel stops, then
    it stays stopped (within one RK4 step's worth of chatter)."""
    f, Js, Omega0, h = 1e-3, 0.05, 10.0, 0.5
    plant = Plant(J_DIAG, [make_wheels([1, 0, 0], Js, coulomb=[f])])
    x0 = np.stack([plant.initial_state(IDENTITY, np.zeros(3))] * 2)
    x0[:, 7] = [Omega0, -Omega0]
    decel = f * k_eff(10.0, Js)   # stops after Omega0 / decel ~ 475 s
    t, states = propagate(plant, x0, plant.zero_commands(), 700.0, period=10.0, max_step=h)
    before = t < 0.95 * Omega0 / decel
    assert_allclose(states[before, 0, 7], Omega0 - decel * t[before], rtol=1e-12, atol=1e-12)
    assert_allclose(states[before, 1, 7], -Omega0 + decel * t[before], rtol=1e-12, atol=1e-12)
    after = t > Omega0 / decel + 2 * h
    assert np.abs(states[after, :, 7]).max() <= decel * h
    assert_allclose(10.0 * states[:, :, 4] + Js * states[:, :, 7], np.broadcast_to(Js * x0[:, 7], (len(t), 2)),
                    rtol=0, atol=1e-13)


# --- attitude conventions ------------------------------------------------------------------------------

def test_rotations_agree_with_scipy():
    """rotate_to_inertial(q, v) = R(q) v and rotate_to_body(q, v) = R(q)^T v with R from scipy's
    Rotation.from_quat (x, y, z, w), for random quaternions, batched."""
    rng = np.random.default_rng(4)
    q = Rotation.random(200, random_state=rng).as_quat()
    v = rng.normal(size=(200, 3))
    R = Rotation.from_quat(q)
    assert_allclose(rotate_to_inertial(q, v), R.apply(v), rtol=0, atol=1e-14)
    assert_allclose(rotate_to_body(q, v), R.inv().apply(v), rtol=0, atol=1e-14)
    assert_allclose(rotate_to_body(q, rotate_to_inertial(q, v)), v, rtol=0, atol=1e-14)


def test_quat_kinematics_matches_scipy():
    """dq/dt of seed 004 eq. 4 is the derivative of q(t) = q0 * exp(w t) (body rate composes on the
    right): central difference of scipy's composition, and a constant-rate integration."""
    rng = np.random.default_rng(7)
    R0 = Rotation.random(20, random_state=rng)
    w = rng.normal(scale=0.1, size=(20, 3))
    q0 = R0.as_quat()
    d = 1e-5
    qp = (R0 * Rotation.from_rotvec(w * d)).as_quat()
    qm = (R0 * Rotation.from_rotvec(-w * d)).as_quat()
    qp *= np.sign(np.sum(qp * q0, axis=-1, keepdims=True))
    qm *= np.sign(np.sum(qm * q0, axis=-1, keepdims=True))
    assert_allclose(quat_kinematics(q0, w), (qp - qm) / (2 * d), rtol=0, atol=1e-9)

    # Spherical body, no torque: w stays constant, so the attitude is q0 * exp(w T) exactly.
    plant = Plant(np.eye(3) * 5.0)
    x0 = np.concatenate([q0, w], axis=-1)
    T = 20.0
    _, states = propagate(plant, x0, {}, T, period=1.0, max_step=0.05)
    same_rotation(states[-1, :, :4], (R0 * Rotation.from_rotvec(w * T)).as_quat(), atol=1e-10)
    assert_allclose(states[-1, :, 4:7], w, rtol=0, atol=1e-15)


def test_euler_213_of_seed_004_initial_attitude():
    """Seed 004 q(0) = [0.3062, 0.1768, 0.1768, 0.9186] is 30 deg on each axis of a 2-1-3 sequence."""
    angles = np.degrees(euler_213(np.array([0.3062, 0.1768, 0.1768, 0.9186])))
    assert_allclose(angles, [30.0, 30.0, 30.0], rtol=0, atol=0.01)
    # and batched
    assert euler_213(np.tile([0.3062, 0.1768, 0.1768, 0.9186], (4, 1))).shape == (4, 3)


# --- environment --------------------------------------------------------------------------------------

def test_gravity_gradient_closed_form():
    """CircularOrbit.gravity_gradient = 3 n^2 c x (J c), c the nadir unit vector in body axes,
    n = sqrt(mu / r^3), computed here independently (scipy rotation, own orbit geometry)."""
    orbit = CircularOrbit(altitude=500e3, inclination=math.radians(51.6), raan=math.radians(30.0),
                          arg_latitude0=math.radians(10.0))
    mu, r = 3.986004418e14, 6378137.0 + 500e3
    n = math.sqrt(mu / r ** 3)
    assert_allclose(orbit.mean_motion, n, rtol=1e-15)
    J = np.array([[12.0, 0.3, -0.2], [0.3, 14.0, 0.1], [-0.2, 0.1, 10.0]])
    rng = np.random.default_rng(11)
    for t in (0.0, 1234.5, 4000.0):
        u = math.radians(10.0) + n * t
        # position: rotate the in-plane unit vector by RAAN (z) and inclination (x)
        r_hat = Rotation.from_euler('ZX', [math.radians(30.0), math.radians(51.6)]).apply([math.cos(u), math.sin(u), 0])
        for q in Rotation.random(5, random_state=rng).as_quat():
            c = Rotation.from_quat(q).inv().apply(-r_hat)
            expected = 3 * n ** 2 * np.cross(c, J @ c)
            assert_allclose(orbit.gravity_gradient(t, q, J), expected, rtol=1e-12, atol=1e-20)
            assert np.linalg.norm(expected) > 1e-9


def lvlh_attitude(orbit: CircularOrbit, t: float) -> np.ndarray:
    """Body x = along-track, y = -orbit normal, z = nadir (equatorial orbit, prograde)."""
    u = orbit.arg_latitude0 + orbit.mean_motion * t
    x_b = np.array([-math.sin(u), math.cos(u), 0.0])
    y_b = np.array([0.0, 0.0, -1.0])
    z_b = np.array([-math.cos(u), -math.sin(u), 0.0])
    return Rotation.from_matrix(np.column_stack([x_b, y_b, z_b])).as_quat()


def test_gravity_gradient_zero_at_principal_axis_equilibria():
    """Nadir along a principal axis (any of the 24 principal-axes-to-orbit-frame alignments): zero torque."""
    orbit = CircularOrbit(altitude=600e3)
    J = np.diag([16.0, 12.0, 10.0])
    q_lvlh = Rotation.from_quat(lvlh_attitude(orbit, 321.0))
    for perm in Rotation.create_group('O'):  # the 24 proper axis permutations / sign flips
        q = (q_lvlh * perm).as_quat()
        assert np.abs(orbit.gravity_gradient(321.0, q, J)).max() < 1e-20
    # ... and a generic attitude does feel a torque
    assert np.abs(orbit.gravity_gradient(321.0, Rotation.from_rotvec([0.1, 0.2, 0.3]).as_quat(), J)).max() > 1e-8


@pytest.mark.parametrize('Jx, Jz, restoring', [(16.0, 10.0, True), (10.0, 16.0, False)])
def test_gravity_gradient_pitch_sign(Jx, Jz, restoring):
    """Small pitch theta about y (orbit normal) from LVLH: T_y = -3 n^2 (Jx - Jz) sin(theta) cos(theta),
    restoring iff the along-track inertia exceeds the nadir one."""
    orbit = CircularOrbit(altitude=600e3)
    n = orbit.mean_motion
    J = np.diag([Jx, 12.0, Jz])
    for theta in (1e-3, -2e-2):
        q = (Rotation.from_quat(lvlh_attitude(orbit, 50.0)) * Rotation.from_rotvec([0, theta, 0])).as_quat()
        tau = orbit.gravity_gradient(50.0, q, J)
        assert_allclose(tau, [0.0, -3 * n ** 2 * (Jx - Jz) * math.sin(theta) * math.cos(theta), 0.0],
                        rtol=1e-9, atol=1e-12 * 3 * n ** 2 * abs(Jx - Jz) * abs(theta))
        assert (tau[1] * theta < 0) == restoring


def test_gravity_gradient_pitch_libration_in_plant():
    """Plant with gravity gradient: nadir pointing with w = orbit rate is an equilibrium, and a small
    pitch offset librates at Omega = n sqrt(3 (Jx - Jz) / Jy) (linearised; amplitude 1e-3 rad)."""
    orbit = CircularOrbit(altitude=600e3)
    n = orbit.mean_motion
    J = np.diag([16.0, 12.0, 10.0])
    plant = Plant(J, orbit=orbit, gravity_gradient=True)
    theta0 = 1e-3
    q0 = np.stack([lvlh_attitude(orbit, 0.0),
                   (Rotation.from_quat(lvlh_attitude(orbit, 0.0)) * Rotation.from_rotvec([0, theta0, 0])).as_quat()])
    x0 = np.concatenate([q0, np.tile([0.0, -n, 0.0], (2, 1))], axis=-1)
    Omega = n * math.sqrt(3 * (16.0 - 10.0) / 12.0)
    t, states = propagate(plant, x0, {}, 2 * math.pi / Omega * 1.25, period=2 * math.pi / Omega / 40, max_step=10.0)
    for k, tk in enumerate(t):
        c = rotate_to_body(states[k, :, :4], -orbit.position_unit(tk))  # nadir in body axes
        pitch = np.arctan2(-c[:, 0], c[:, 2])
        # equilibrium stays (RK4 phase error of the orbit-rate rotation, (n h)^4 / 120 per rad ~ 1e-10)
        assert abs(pitch[0]) < 1e-9 and np.abs(c[0, 1]) < 1e-9
        assert abs(pitch[1] - theta0 * math.cos(Omega * tk)) < 1e-3 * theta0
        assert np.abs(c[1, 1]) < 1e-10  # planar: no roll
    assert_allclose(states[:, 0, 4:7], np.tile([0.0, -n, 0.0], (len(t), 1)), rtol=0, atol=1e-12)


def test_disturbance_constant_plus_harmonic_closed_form():
    """Body-fixed disturbance c + A sin(f t + phi). Spherical body (J = j 1): w x J w = 0, so
    j dw/dt = tau(t) exactly and w(t) = (c t + A/f (cos(phi) - cos(f t + phi))) / j.
    Diagonal non-spherical body, torque on one principal axis only, at rest: same on that axis."""
    c = np.array([1e-4, -2e-4, 5e-5])
    A = np.array([3e-4, 1e-4, -2e-4])
    f = np.array([0.05, 0.1, 0.02])
    phi = np.array([0.3, -1.0, 2.0])
    dist = Disturbance(c, A, f, phi)
    j = 5.0
    t = np.linspace(0.0, 300.0, 31)
    integral = c * t[:, None] + A / f * (np.cos(phi) - np.cos(f * t[:, None] + phi))
    plant = Plant(np.eye(3) * j, disturbance=dist)
    _, states = propagate(plant, plant.initial_state(IDENTITY, np.zeros(3)), {}, 300.0, period=10.0, max_step=0.5)
    assert_allclose(states[:, 4:7], integral / j, rtol=0, atol=1e-10 * np.abs(integral / j).max())
    # spherical body: torque-free rotation of H is absent, so body H = integral of the torque
    assert_allclose(plant.angular_momentum(states), integral, rtol=0, atol=1e-10 * np.abs(integral).max())

    J = np.diag([12.0, 14.0, 10.0])
    one_axis = Disturbance([0.0, c[1], 0.0], [0.0, A[1], 0.0], f, phi)
    plant = Plant(J, disturbance=one_axis)
    _, states = propagate(plant, plant.initial_state(IDENTITY, np.zeros(3)), {}, 300.0, period=10.0, max_step=0.5)
    assert_allclose(states[:, 5], integral[:, 1] / 14.0, rtol=0, atol=1e-10 * np.abs(integral[:, 1] / 14).max())
    assert np.abs(states[:, [4, 6]]).max() == 0.0
    # rotation about a fixed axis: inertial H = body H = integral, along inertial y
    assert_allclose(plant.inertial_momentum(states)[:, 1], integral[:, 1], rtol=0,
                    atol=1e-10 * np.abs(integral[:, 1]).max())


def test_torquers_saturate_per_axis():
    """Ideal torquers: the commanded body torque clipped per axis; spherical body: w = tau T / j."""
    j, T = 4.0, 10.0
    plant = Plant(np.eye(3) * j, [Torquers(max_torque=[0.1, 0.2, 0.3])])
    cmds = {'torquers': np.array([1.0, -1.0, 0.05])}
    _, states = propagate(plant, plant.initial_state(IDENTITY, np.zeros(3)), cmds, T, period=1.0, max_step=0.5)
    assert_allclose(states[-1, 4:7], np.array([0.1, -0.2, 0.05]) * T / j, rtol=1e-13)


# --- batch axis, construction ---------------------------------------------------------------------------

def test_batch_equals_separate_runs():
    """Plant.step on x of shape (5, n) (per-run wheel commands) equals 5 separate runs."""
    wheels = make_wheels(SKEWED_AXES, SKEWED_JS, viscous=[1e-4] * 4, coulomb=[1e-5] * 4,
                         max_torque=[0.01] * 4, max_speed=[300.0] * 4, speed_gain=[0.5] * 4)
    orbit = CircularOrbit(altitude=500e3, inclination=0.9)
    plant = Plant(np.diag([12.0, 14.0, 10.0]), [wheels],
                  Disturbance([1e-5, 0, -1e-5], [1e-5, 2e-5, 0], [0.01, 0.02, 0.0], [0, 1, 0]),
                  orbit, gravity_gradient=True)
    rng = np.random.default_rng(5)
    x = np.stack([plant.initial_state(Rotation.random(random_state=rng).as_quat(), rng.normal(scale=0.01, size=3))
                  for _ in range(5)])
    x[:, 7:11] = rng.normal(scale=50.0, size=(5, 4))
    value = rng.normal(scale=0.01, size=(5, 4))
    value[:, 2] = rng.normal(scale=100.0, size=5)
    mode = np.array([False, False, True, False])
    batch_cmd = torque_cmd(plant, value, mode)
    xb = x
    xs = [x[i] for i in range(5)]
    for k in range(10):
        xb = plant.step(5.0 * k, xb, batch_cmd, 5.0, 0.5)
        xs = [plant.step(5.0 * k, xs[i], torque_cmd(plant, value[i], mode), 5.0, 0.5) for i in range(5)]
    # not bit-for-bit (BLAS may sum a batched matmul in another order): a few ulps
    assert_allclose(xb, np.stack(xs), rtol=4e-15, atol=1e-15)
    assert np.abs(xb - x).max() > 1e-3  # things happened


def test_bad_construction_raises():
    """Non-physical inertias are refused at construction."""
    with pytest.raises(ValueError, match='positive definite'):
        Plant(np.diag([1.0, -1.0, 2.0]))
    with pytest.raises(ValueError, match='triangle'):
        Plant(np.diag([1.0, 1.0, 3.0]))
    with pytest.raises(ValueError, match='symmetric'):
        Plant(np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    with pytest.raises(ValueError, match='spin inertia'):
        Plant(np.diag([2.0, 2.0, 2.0]), [make_wheels([1, 0, 0], 2.5)])   # J_s = diag(-0.5, 2, 2)
    with pytest.raises(ValueError, match='spin inertia'):
        Plant(np.diag([2.0, 2.0, 2.0]), [make_wheels([0, 0, 1], 2.0)])   # J_s singular
    with pytest.raises(ValueError, match='gravity gradient'):
        Plant(np.eye(3), gravity_gradient=True)
    Plant(np.diag([1.0, 1.0, 2.0]))  # triangle equality is a (flat) body: accepted


def test_a_batch_of_inertias_is_checked_as_one_stack_with_the_per_run_messages():
    """check_inertias checks a batch (the plant's, a campaign's) as one stack and falls back to the
    per-matrix loop for the message: accepts what check_inertia accepts, refuses with its very words."""
    from adcs_core.inertia import check_inertia, check_inertias
    rng = np.random.default_rng(8)
    good = np.array([12.0, 14.0, 10.0])[:, None] * np.eye(3) + rng.normal(0, 0.01, (50, 1, 1)) * np.eye(3)
    check_inertias(good, 'inertia')
    Plant(good)
    assert all(check_inertia(J) is None for J in good)
    assert (np.linalg.eigvalsh(good) == np.stack([np.linalg.eigvalsh(J) for J in good])).all()
    for bad_value, where in ((-1.0, (7, 0, 0)), (np.nan, (3, 1, 1)), (0.5, (9, 0, 1)), (30.0, (4, 2, 2))):
        bad = good.copy()
        bad[where] = bad_value
        with pytest.raises(ValueError) as ours:
            check_inertias(bad, 'inertia')
        assert str(ours.value) == f'run {where[0]}: {check_inertia(bad[where[0]], "inertia")}'
        with pytest.raises(ValueError, match=f'run {where[0]}: '):
            Plant(bad)
