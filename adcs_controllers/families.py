"""The controller families: for each controller node, its parameter schema, its law and its
actuation, declared once (pure; no rclpy).

A family (:class:`ControllerFamily`) is what a controller node executable is: the node
(:mod:`adcs_controllers.nodes`) builds ``family.build(section)`` (its law, and its actuation: one
class per kind of actuator) from its validated section, and the batch engine (:mod:`adcs_sim.app.batch.engine`) builds the very same
objects, so a graph run and its batch run execute the same code. The application's registry
(:mod:`adcs_sim.app.scenario.registry`) lists :data:`FAMILIES` beside the simulator's own nodes.

A new control law: its module in :mod:`adcs_controllers.laws`, its schema and family here, a
three-line node module in :mod:`adcs_controllers.nodes` and its executable in ``setup.py``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from adcs_controllers.laws.allocation import (
    ACTUATION_KINDS,
    Actuation,
    TorquerActuation,
    WheelActuation,
)
from adcs_controllers.laws.backstepping import (
    ORBIT_REFERENCE_PARAMS,
    BacksteppingLaw,
    ThrusterActuation,
    actuator_matrix,
    positive_null_vector,
)
from adcs_controllers.laws.base import SHORTEST_PATH, TARGET_PARAMS
from adcs_controllers.laws.inverse_optimal import LGV, GsmnLaw, KtLaw, MinNormLaw
from adcs_controllers.laws.motion_to_rest import M2rLaw, actuation_matrix, check_m2r_gains
from adcs_controllers.laws.motion_to_spin import M2sLaw
from adcs_controllers.laws.pd import PD_SHORTEST_PATH, PdLaw
from adcs_controllers.laws.reconfiguration import TwoWheelReconfiguration
from adcs_controllers.laws.single_axis import (
    POINTING_A_PARAMS,
    SOLUTION,
    PointingALaw,
    PointingBLaw,
    body_axis_angles,
    elevation,
)
from adcs_controllers.laws.underactuated import TWO_WHEEL_PARAMS, SnlcGsmnLaw, SnlcLaw, SnlcMinNormLaw, ZeroMomentumLaw
from adcs_msgs_py.blocks import (
    check_per_wheel,
    check_thrusters,
    check_unit_quaternion,
    check_wheels,
    expect_faults_param,
    inertia_param,
    startup_params,
    thruster_params,
    wheel_params,
)
from adcs_msgs_py.names import ESTIMATE_STATE, STATE
from adcs_msgs_py.params import Param, ParameterError, Schema, all_positive, non_negative, positive
from adcs_msgs_py.sections import Section, section


def _actuator_check(v: dict) -> None:
    ACTUATION_KINDS[v['actuator']].check_section(v)


def _require_actuation(v: dict, kind: type[Actuation], why: str) -> None:
    """The section's ``actuator`` must be ``kind``'s (``why``: the law's reason)."""
    if ACTUATION_KINDS[v['actuator']] is not kind:
        raise ParameterError('actuator', f"{why}: it needs actuator '{kind.kind}'")


def feedback_param() -> Param:
    """What every controller flies on: the dynamics node's state or an estimator's estimate."""
    return Param('feedback', 'string', default='state', choices=('state', 'estimate'),
                 doc="the state the law flies on: 'state' (the dynamics node's, true or noisy) or "
                     "'estimate' (an estimator's estimate/state, as a remap state:=estimate/state)")


def state_topic(p: dict) -> str:
    """The topic a controller section's law reads its (q, w) from (``feedback``)."""
    return ESTIMATE_STATE if p['feedback'] == 'estimate' else STATE


def controller_params() -> list[Param]:
    """Parameters every controller node has: its actuators, its feedback and the startup handshake."""
    return [
        feedback_param(),
        Param('actuator', 'string', default='wheels', choices=('wheels', 'torquers'),
              doc='command reaction wheels (wheels/cmd) or ideal torquers (torque_cmd)'),
        *wheel_params(with_physics=False),
        Param('saturation', 'string', default='clip', choices=('clip', 'scale'),
              doc='torque saturation: per actuator (clip) or whole vector (scale)'),
        Param('torquers.max_torque', 'double', default=float('inf'), check=positive, finite=False,
              doc='torquer limit per axis (N m; .inf for none) when actuator is torquers', batch=True),
        *startup_params(),
        expect_faults_param(),
    ]


PD_SCHEMA = Schema('pd_controller', [
    inertia_param("the controller's inertia model (kg m^2): 3 principal moments or 9 entries"),
    Param('kp', 'double', check=non_negative, doc='proportional gain (1/s^2), multiplied by the inertia', batch=True),
    Param('kd', 'double', check=non_negative, doc='derivative gain (1/s), multiplied by the inertia', batch=True),
    *TARGET_PARAMS, PD_SHORTEST_PATH,
    *controller_params(),
], cross_check=_actuator_check, doc='quaternion PD benchmark law, seed 004 eq. (13)')


def _gain(name: str, doc: str) -> Param:
    return Param(name, 'double', check=positive, batch=True, doc=doc)


_INERTIA_MODEL = "the controller's inertia model I (kg m^2): 3 principal moments or 9 entries"
MINNORM_SCHEMA = Schema('minnorm_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('kp', 'PD gain of the reference torque u_PD = -kp I q - kd I w (1/s^2)'),
    _gain('kd', 'PD gain of the reference torque (1/s)'),
    _gain('gamma', 'cross-term weight of the Lyapunov function, eq. (15) (1/s)'),
    *TARGET_PARAMS, SHORTEST_PATH, LGV,
    *controller_params(),
], cross_check=_actuator_check, doc='standard minimum-norm law, seed 004 eq. (14) with V of eq. (15)')

GSMN_SCHEMA = Schema('gsmn_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('kp1', 'low (benchmark) proportional gain, multiplied by I (1/s^2)'),
    _gain('kd1', 'low (benchmark) derivative gain, multiplied by I (1/s)'),
    _gain('kp2', 'high proportional gain, multiplied by I (1/s^2)'),
    _gain('kd2', 'high derivative gain, multiplied by I (1/s)'),
    _gain('gamma', 'cross-term weight of the Lyapunov function, eq. (15) (1/s)'),
    Param('epsilon', 'double', check=positive, batch=True,
          doc='switching threshold on |u2|_inf (N m): high gains below it (eq. 17)'),
    *TARGET_PARAMS, SHORTEST_PATH, LGV,
    *controller_params(),
], cross_check=_actuator_check, doc='gain-scheduled minimum-norm law, seed 004 eq. (17)')

KT_SCHEMA = Schema('kt_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('k1', 'Krstic-Tsiotras gain k1 (1/s)'),
    _gain('k2', 'Krstic-Tsiotras gain k2 (1/s)'),
    *TARGET_PARAMS,
    *controller_params(),
], cross_check=_actuator_check, doc='Krstic-Tsiotras inverse-optimal law, seed 004 eq. (18)')


# --- seed 000: two-wheel (underactuated) laws, optionally after a three-wheel PD phase ----------

def _two_wheel_check(v: dict) -> None:
    _actuator_check(v)
    if v['three_wheel.enabled']:
        for key in ('three_wheel.kp', 'three_wheel.kd'):
            if not v[key] > 0:
                raise ParameterError(key, 'must be > 0 when three_wheel.enabled is true (the PD of '
                                     'the three-wheel phase, seed 004 eq. 13)')


def _zero_momentum_check(v: dict) -> None:
    _two_wheel_check(v)
    _require_actuation(v, WheelActuation, 'the zero-momentum law commands wheel speeds')
    check_per_wheel(v, required=['wheels.spin_inertia'], optional=['wheels.bias_speed'],
                    why=' (wheel speed = commanded momentum / spin inertia + bias, eq. 13)')


def _two_wheel_params(*gains: Param) -> list[Param]:
    """The parameters every seed 000 node has, around its own gains."""
    return [
        inertia_param("the controller's inertia model I (kg m^2), total (wheels locked)"),
        *gains,
        *TWO_WHEEL_PARAMS,
        Param('three_wheel.enabled', 'bool', default=False,
              doc='start with the three-wheel PD and switch to the two-wheel law when a wheel fails '
                  '(seed 000 VI.A); false: the two-wheel law from the start'),
        Param('three_wheel.kp', 'double', default=0.0, check=non_negative,
              doc='PD gain of the three-wheel phase (1/s^2), multiplied by the inertia'),
        Param('three_wheel.kd', 'double', default=0.0, check=non_negative,
              doc='PD gain of the three-wheel phase (1/s), multiplied by the inertia'),
        Param('three_wheel.target.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
              check=check_unit_quaternion,
              doc='attitude [x, y, z, w] the three-wheel phase holds (the off-pointing of VI.A)'),
        *TARGET_PARAMS, SHORTEST_PATH,
        *controller_params(),
    ]


def _k_g():
    return [_gain('k', 'gain k of the desired rates, eq. (7)/(8) (rad/s)'),
            _gain('g', 'gain g of the singular term of eq. (7)/(8) (rad/s)')]


ZERO_MOMENTUM_SCHEMA = Schema('zero_momentum_controller', [
    *_two_wheel_params(*_k_g()),
    Param('wheels.spin_inertia', 'double_array', default=[], check=all_positive,
          doc='spin inertia per wheel (kg m^2): wheel speed = commanded momentum / spin inertia (eq. 13)'),
    Param('wheels.bias_speed', 'double_array', default=[],
          doc='speed added to each wheel\'s command (rad/s; default 0): the bias momentum kept on a '
              'wheel in orbit (seed 000 VI.B: -60 rpm on UoSAT-12\'s Y wheel, 100 rpm on UK-DMC\'s Z)'),
], cross_check=_zero_momentum_check,
    doc='two-wheel zero-momentum law, seed 000 eq. (12-13): attitude-only feedback, wheel speed commands')

SNLC_SCHEMA = Schema('snlc_controller', [
    *_two_wheel_params(*_k_g(), _gain('K', 'rate-tracking gain K of eq. (14)/(31) (N m s/rad)')),
], cross_check=_two_wheel_check, doc='two-wheel angular-velocity tracking law "snlc", seed 000 eq. (14)/(24)')

SNLC_MINNORM_SCHEMA = Schema('snlc_minnorm_controller', [
    *_two_wheel_params(*_k_g(), _gain('K', 'rate-tracking gain K of the benchmark (N m s/rad)'),
                       _gain('gamma', 'gain gamma of the Lyapunov rates, eq. (27) (rad/s)'),
                       _gain('sigma', 'gain sigma of the Lyapunov rates, eq. (27) (rad/s)')),
], cross_check=_two_wheel_check, doc='two-wheel min-norm law on the snlc benchmark, seed 000 eq. (25-27)')

SNLC_GSMN_SCHEMA = Schema('snlc_gsmn_controller', [
    *_two_wheel_params(
        _gain('k1', 'low gain k1 of eq. (31) (rad/s)'), _gain('g1', 'low gain g1 of eq. (31) (rad/s)'),
        _gain('K1', 'low rate-tracking gain K1 (N m s/rad)'),
        _gain('k2', 'high gain k2 of eq. (32) (rad/s)'), _gain('g2', 'high gain g2 of eq. (32) (rad/s)'),
        _gain('K2', 'high rate-tracking gain K2 (N m s/rad)'),
        _gain('gamma', 'gain gamma of the Lyapunov rates, eq. (27) (rad/s)'),
        _gain('sigma', 'gain sigma of the Lyapunov rates, eq. (27) (rad/s)'),
        Param('epsilon', 'double', check=positive, batch=True,
              doc='torque threshold of eq. (30) on |u_hg|_inf (N m): high gains below it')),
], cross_check=_two_wheel_check, doc='two-wheel gain-scheduled min-norm law, seed 000 eq. (30-32)')


# --- seed 001: inertia-free motion to rest (M2R) and adaptive motion to spin (M2S), torquers ----

def _distinct_positive(vs) -> str | None:
    if not all(v > 0 for v in vs) or len(set(vs)) != len(vs):
        return f'A = diag(a1, a2, a3) needs three distinct positive entries (eq. 13), got {vs!r}'
    return None


def _inertia_free_check(v: dict) -> None:
    """Both seed 001 laws act through ideal torquers (the paper's "continuously variable torques
    without momentum storage"); the torquer limit is the paper's u_max."""
    _require_actuation(v, TorquerActuation, 'the seed 001 laws command external torques (and need '
                       'torquers.enabled in the dynamics section)')
    B = actuation_matrix(v['B'])
    if B is not None and np.linalg.matrix_rank(B) != 3:
        raise ParameterError('B', f'the actuation matrix must be invertible (u = -B^-1(...)), got {v["B"]!r}')


def _m2r_check(v: dict) -> None:
    _inertia_free_check(v)
    if any(v['target.rate']):
        raise ParameterError('target.rate', f'M2R brings the body to rest: must be [0, 0, 0], got {v["target.rate"]!r}')
    u_max = v['torquers.max_torque']
    if u_max != float('inf'):
        try:
            check_m2r_gains(v['alpha'], v['beta'], u_max, actuation_matrix(v['B']), v['proposition'])
        except ValueError as exc:
            raise ParameterError('alpha', str(exc)) from None


def _inertia_free_params() -> list[Param]:
    return [
        inertia_param('the true inertia J (kg m^2): the law does not use it (inertia free); only the '
                      'Lyapunov value V on the status topic does'),
        _gain('alpha', 'alpha (N m): Kp = alpha / tr A (eq. 15)'),
        _gain('beta', 'beta (N m): Kv = beta diag f(w) (M2R, eq. 16) or beta I (M2S, eq. 44)'),
        Param('A', 'double_array', default=[1.0, 2.0, 3.0], length=3, check=_distinct_positive, batch=True,
              doc='diag(A) of the attitude error S, eq. (13)'),
        Param('B', 'double_array', default=[], length=(0, 3, 9), batch=True,
              doc='actuation matrix B of eq. (1): 3 diagonal or 9 row-major values (empty: I)'),
        *TARGET_PARAMS,
        *controller_params(),
    ]


M2R_SCHEMA = Schema('m2r_controller', [
    *_inertia_free_params(),
    Param('f', 'string', default='eq25', choices=('eq25', 'eq24'),
          doc='the rate shaping f of Kv(w): eq. (25) with omega_bar, or eq. (24) 1/(1 + |x|)'),
    Param('omega_bar', 'double', default=0.2, check=positive, batch=True, doc='w_bar of eq. (25) (rad/s)'),
    Param('proposition', 'int', default=1, choices=None, check=lambda v: None if v in (1, 2) else
          f'must be 1 or 2, got {v!r}',
          doc='which torque bound the gains are checked against: Proposition 1 (eq. 18, 20; '
              'diagonal B) or 2 (eq. 22-23)'),
], cross_check=_m2r_check, doc='inertia-free motion-to-rest law, seed 001 eq. (11-25), with the '
                               'torque bounds of Propositions 1-2; external torquers')

M2S_SCHEMA = Schema('m2s_controller', [
    *_inertia_free_params(),
    Param('K1', 'double_array', default=[], length=(0, 1, 3, 9), doc='K1 of z = w_err + K1 S, eq. (38) (empty: I)'),
    Param('Q', 'double_array', default=[], length=(0, 6, 36),
          doc='Q0 of the adaptation gain Q = q Q0, eq. (37), (55): 6 diagonal or 36 values (empty: I6)'),
    Param('J_hat0', 'double_array', default=[1.0, 1.0, 1.0], length=(3, 9), batch=True,
          doc='initial inertia estimate J_hat(0) (kg m^2), eq. (37): 3 diagonal or 9 values'),
    Param('C_d', 'double_array', default=[],
          doc='disturbance output matrix C_d (3 x nd, row-major), eq. (35); empty or zeros: the '
              'disturbance is not estimated (the paper\'s C_d = 0)'),
    Param('A_d', 'double_array', default=[], doc='disturbance model A_d (nd x nd), eq. (34) (empty: 0, constant)'),
    Param('D', 'double_array', default=[], doc='D of the disturbance update, eq. (39) (nd or nd^2 values; empty: I)'),
    Param('d_hat0', 'double_array', default=[], doc='initial disturbance-state estimate (empty: 0)'),
    Param('d_true', 'double_array', default=[],
          doc='the true disturbance state, only for V on the status (empty: V without the d term)'),
    Param('vag', 'bool', default=False, batch=True,
          doc='varying adaptation gain, eq. (56): VAG-C with saturation clip, VAG-S with scale'),
    Param('q_max', 'double', default=10000.0, check=positive, doc='q_max of eq. (56)'),
    Param('K_Q', 'double', default=0.001, check=positive, doc='K_Q of eq. (56)'),
    Param('vag_excess', 'string', default='printed', choices=('printed', 'positive'),
          doc="eq. (56)'s || |u| - u_max ||: over all axes as printed, or the positive excess only"),
    Param('vag_disturbance', 'bool', default=False,
          doc='also slow the disturbance estimate by q (the remedy the paper suggests after fig. 18)'),
    Param('extremum', 'bool', default=False, doc='extremum tracking of the spin rate, eq. (60-64)'),
    Param('t_max', 'double', default=250.0, check=positive, doc='t_max of eq. (62) (s)'),
    Param('phi_max', 'double', default=0.17453292519943295, check=positive,
          doc='phi_max of eq. (62): largest spin-axis error (rad; 10 deg)'),
    Param('K_omega', 'double', default=0.5, check=lambda v: None if 0 < v < 1 else f'must be in (0, 1), got {v!r}',
          doc='K_w of eq. (63)'),
    Param('delta0', 'double', default=0.0, check=non_negative,
          doc='first rate change delta_0 of eq. (63) (rad/s; 0: ||w_d||, a bisection)'),
    Param('max_step', 'double', default=0.02, check=positive,
          doc='largest RK4 step (s) of the continuous-time estimator between two control calls'),
], cross_check=_inertia_free_check,
    doc='adaptive motion-to-spin law, seed 001 Theorem 2 (eq. 31-46), saturation by cutoff/scaling '
        '(eq. 47-51; the `saturation` clip/scale), VAG-C/S (eq. 55-58), extremum tracking (eq. 60-67); '
        'external torquers')


# --- seed 003: single-axis pointing with two wheels and non-zero angular momentum -------------

def _nonzero_vector(v) -> str | None:
    return None if sum(x * x for x in v) > 1e-24 else f'must not be the zero vector, got {v!r}'


def _pointing_check(v: dict) -> None:
    """Wheels with their spin inertia (the node forms h = sum a_i Js_i Omega_i from wheels/state),
    and the pointing request feasible: eq. (14), |alpha| <= pi/2 - |lambda|."""
    _actuator_check(v)
    _require_actuation(v, WheelActuation, "the pointing laws need the wheels' momentum")
    check_per_wheel(v, required=['wheels.spin_inertia'],
                    why=' (h = sum_i a_i Js_i Omega_i from wheels/state)')
    lam, _ = body_axis_angles(np.asarray(v['sigma'], dtype=float))
    alpha = elevation(np.asarray(v['tau'], dtype=float), np.asarray(v['momentum'], dtype=float))
    if abs(alpha) > np.pi / 2 - abs(lam) + 1e-12:
        raise ParameterError('tau', 'pointing infeasible, eq. (14) needs |alpha| <= 90 deg - |lambda|: '
                             f'tau is {np.degrees(abs(alpha)):.6g} deg from the plane normal to '
                             f'`momentum` but sigma is only {90 - np.degrees(abs(lam)):.6g} deg from the '
                             f'failed wheel axis e3 (lambda = {np.degrees(lam):.6g} deg, sigma = '
                             f'{list(v["sigma"])}, tau = {list(v["tau"])}, momentum = {list(v["momentum"])})')


def _pointing_params(*gains: Param) -> list[Param]:
    """Parameters of both seed 003 laws (adcs_controllers/laws/single_axis.py; paper symbols)."""
    return [
        inertia_param("J, the controller's model of the total inertia (wheels locked), kg m^2"),
        Param('sigma', 'double_array', length=3, check=_nonzero_vector,
              doc='body axis to point, sigma (eq. 9; normalised), body axes'),
        Param('tau', 'double_array', length=3, check=_nonzero_vector,
              doc='target direction tau (normalised), inertial axes (the frame of the attitude)'),
        Param('momentum', 'double_array', length=3, check=_nonzero_vector,
              doc='total angular momentum H of the system in inertial axes (N m s): defines F_I (eq. 6)'),
        SOLUTION,
        _gain('K_p', 'gain K_p of eq. (22)/(33) (N m s/rad)'),
        _gain('K_h', 'gain K_h of eq. (20)/(32) (rad/(N m s))'),
        *gains,
        Param('wheels.spin_inertia', 'double_array', default=[], check=all_positive,
              doc='spin inertia per wheel (kg m^2): h = sum_i a_i Js_i Omega_i from wheels/state'),
        *controller_params(),
    ]


POINTING_A_SCHEMA = Schema('pointing_a_controller', [
    *_pointing_params(
        *POINTING_A_PARAMS),
], cross_check=_pointing_check,
    doc='seed 003 controller A: momentum stabilisation (eq. 20-22), then LQR on eq. (18)')

POINTING_B_SCHEMA = Schema('pointing_b_controller', [
    *_pointing_params(_gain('K_Psi', 'precession gain K_Psi of eq. (24) (1/s)')),
], cross_check=_pointing_check, doc='seed 003 controller B: desired-rate tracking, eq. (24-33)')


# --- seed 002: quaternion integrator backstepping, four thrusters and one pitch wheel -----------

def _backstepping_check(v: dict) -> None:
    check_wheels(v, with_physics=False)
    if len(v['wheels.names']) != 1:
        raise ParameterError('wheels.names', 'the backstepping allocation (eq. 20-21) has exactly one '
                             f'wheel (ESEO\'s pitch wheel), got {len(v["wheels.names"])}')
    check_per_wheel(v, required=['wheels.spin_inertia', 'wheels.max_speed'],
                    why=' (the allocation clips the wheel torque to what it can deliver, R5)')
    check_thrusters(v)
    if not v['thrusters.names']:
        raise ParameterError('thrusters.names', 'the backstepping controller needs its thrusters')
    if v['firing.off_level'] > v['firing.on_level']:
        raise ParameterError('firing.off_level', f'must not exceed firing.on_level '
                             f'({v["firing.on_level"]} N), got {v["firing.off_level"]}')

    n = len(v['thrusters.names'])
    B = actuator_matrix(np.reshape(v['thrusters.positions'], (n, 3)),
                        np.reshape(v['thrusters.directions'], (n, 3)), np.asarray(v['wheels.axes']))
    if np.linalg.matrix_rank(B) < 3:
        raise ParameterError('thrusters.positions', 'the thrusters and the wheel give no torque about '
                             'some axis: B_a B_a^T of eq. (21) is singular (readings R3: r_x != r_y)')
    if v['allocation.mapping'] == 'nullspace':
        try:
            positive_null_vector(B[:, :n])
        except ValueError as exc:
            raise ParameterError('allocation.mapping', f"'nullspace' needs a one-signed null vector "
                                 f'of the thruster torques: {exc}') from None


BACKSTEPPING_SCHEMA = Schema('backstepping_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('K1', 'backstepping gain K1 of eq. (29), alpha_1 = -K1 G z1 (rad/s)'),
    _gain('K2', 'backstepping gain K2 of eq. (32) (N m s)'),
    *TARGET_PARAMS,
    *ORBIT_REFERENCE_PARAMS,
    Param('control_period', 'double', check=positive,
          doc='control period (s), as the dynamics: a firing lasts one period'),
    *thruster_params(with_physics=False),
    *wheel_params(with_physics=False),
    Param('wheels.spin_inertia', 'double_array', default=[], check=all_positive,
          doc='spin inertia of the wheel (kg m^2): its momentum in D_a (eq. 20)'),
    Param('wheels.max_speed', 'double_array', default=[], check=all_positive, finite=False,
          doc='speed limit of the wheel (rad/s): the allocation gives it no more than it can take'),
    Param('allocation.mapping', 'string', default='nullspace', choices=('nullspace', 'pairs'),
          doc='signed allocated forces -> pushing thrusters: shift along the positive null vector '
              '(torque kept) or move a negative force to the opposed thruster (readings R7)'),
    Param('allocation.reallocate_saturated_wheel', 'bool', default=True,
          doc='re-allocate the torque a saturated wheel cannot give over the thrusters (readings R5)'),
    Param('firing.on_level', 'double', check=non_negative, batch=True,
          doc='bang-bang deadzone (N): a thruster fires for the whole period when its demand exceeds it'),
    Param('firing.off_level', 'double', check=non_negative, batch=True,
          doc='Schmitt trigger (N): a firing thruster stays on while its demand exceeds it; '
              'equal to on_level: no hysteresis'),
    feedback_param(),
    *startup_params(),
    expect_faults_param(),
], cross_check=_backstepping_check,
    doc='quaternion integrator backstepping, seed 002 eq. (22-35), thrusters + pitch wheel (eq. 20-21)')


# --- the families: schema, law and actuation of each controller node ---------------------------

# What a run of a law is (the quantities its paper plots): to a fixed attitude at rest, along an
# orbit-defined target, to a spin about an axis, or one body axis pointed at a direction.
RUN_KINDS = {
    'regulation': 'rest to rest: the body brought to a fixed target attitude at rest',
    'tracking': 'tracking: the body follows a target attitude defined relative to the orbit frame',
    'spin': 'motion to spin: the body brought to a spin at a commanded rate about a commanded axis',
    'pointing': 'single-axis pointing: one body axis pointed at an inertial direction (rotation about it free)',
}

@dataclass(frozen=True)
class ControllerFamily:
    """One controller node: its section's ``schema``, its ``law`` (a class or builder called with the
    validated section) and, for a law with actuators of its own (seed 002's thrusters), its
    ``actuation`` class (default: the section's ``actuator`` in
    :data:`~adcs_controllers.laws.allocation.ACTUATION_KINDS`: wheel allocation and saturation, or
    the ideal torquers). ``kind``: what a run of the law is, which
    the reports lead with (:data:`RUN_KINDS`)."""

    schema: Schema
    law: Callable[[dict], Any]
    actuation: type[Actuation] | None = None
    kind: str = 'regulation'

    @property
    def node(self) -> str:
        """The section, executable and node name."""
        return self.schema.node

    @property
    def module(self) -> str:
        """The node's module (``python -m`` target, ``setup.py`` entry point)."""
        return f'adcs_controllers.nodes.{self.schema.node}'

    def section(self, p: dict | Section) -> Section:
        """A validated (or stacked) section as its typed section (:mod:`adcs_msgs_py.sections`)."""
        return section(self.schema, p)

    def actuation_class(self, p: dict | Section) -> type[Actuation]:
        """The class of a validated section's actuation (its commands, topics, fault following)."""
        return self.actuation or ACTUATION_KINDS[self.section(p).actuator]

    def build(self, p: dict | Section) -> tuple[Any, Any]:
        """``(law, actuation)`` from a validated (or stacked) section, read as its typed section:
        what the node and the batch engine run."""
        sec = self.section(p)
        return self.law(sec), self.actuation_class(sec)(sec)


def _pointing(law_class):
    """Seed 003's laws from a validated section: the section's ``momentum`` is the law's ``H``."""
    def build(p):
        p = law_class.section(p)
        return law_class(p, H=p.momentum)
    build.__name__ = f'{law_class.__name__}_from_section'
    return build


# seed 004: PD benchmark, min-norm, gain-scheduled min-norm, Krstic-Tsiotras
PD = ControllerFamily(PD_SCHEMA, PdLaw)
MINNORM = ControllerFamily(MINNORM_SCHEMA, MinNormLaw)
GSMN = ControllerFamily(GSMN_SCHEMA, GsmnLaw)
KT = ControllerFamily(KT_SCHEMA, KtLaw)
# seed 000: two wheels (optionally after a three-wheel PD phase, switching on a wheel fault)
ZERO_MOMENTUM = ControllerFamily(ZERO_MOMENTUM_SCHEMA, TwoWheelReconfiguration.factory(ZeroMomentumLaw))
SNLC = ControllerFamily(SNLC_SCHEMA, TwoWheelReconfiguration.factory(SnlcLaw))
SNLC_MINNORM = ControllerFamily(SNLC_MINNORM_SCHEMA, TwoWheelReconfiguration.factory(SnlcMinNormLaw))
SNLC_GSMN = ControllerFamily(SNLC_GSMN_SCHEMA, TwoWheelReconfiguration.factory(SnlcGsmnLaw))
# seed 001: inertia-free laws on ideal external torquers
M2R = ControllerFamily(M2R_SCHEMA, M2rLaw)
M2S = ControllerFamily(M2S_SCHEMA, M2sLaw, kind='spin')  # regulation when target.rate is zero
# seed 003: single-axis pointing, two wheels, non-zero momentum (laws need the wheel momentum)
POINTING_A = ControllerFamily(POINTING_A_SCHEMA, _pointing(PointingALaw), kind='pointing')
POINTING_B = ControllerFamily(POINTING_B_SCHEMA, _pointing(PointingBLaw), kind='pointing')
# seed 002: thrusters + pitch wheel, backstepping tracking
BACKSTEPPING = ControllerFamily(BACKSTEPPING_SCHEMA, BacksteppingLaw, ThrusterActuation, kind='tracking')

FAMILIES: dict[str, ControllerFamily] = {f.node: f for f in (
    PD, MINNORM, GSMN, KT, ZERO_MOMENTUM, SNLC, SNLC_MINNORM, SNLC_GSMN, M2R, M2S, POINTING_A, POINTING_B,
    BACKSTEPPING)}
