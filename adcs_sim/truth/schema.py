"""The ``dynamics`` section of a scenario and the plant built from it (no ROS).

A scenario file is a ROS 2 params file with a section per node. This module declares the
``dynamics`` section (:data:`DYNAMICS_SCHEMA`: plant, simulated clock, lockstep), the simulated
time grid (:func:`step_timing`), :func:`build_plant` and :func:`initial_state`. The blocks shared
with the controllers (inertia, wheels, thrusters, start-up) are in :mod:`adcs_msgs_py.blocks`; the
``fault_injector`` section is :mod:`adcs_sim.truth.fault_schedule`, the ``recorder`` section
:mod:`adcs_sim.bag.schema`.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_core.environment.environment import Environment, SourceOrbit, build_environment, orbit_source
from adcs_core.environment.frames import parse_epoch
from adcs_core.environment.tle import CircularOrbitSource
from adcs_core.inertia import check_inertia, check_inertias, inertia_matrix
from adcs_core.orbit import CircularOrbit
from adcs_msgs_py import names as topics
from adcs_msgs_py.blocks import (
    check_environment,
    check_thrusters,
    check_unit_quaternion,
    check_wheels,
    environment_params,
    expect_faults_param,
    inertia_param,
    startup_params,
    thruster_params,
    wheel_params,
)
from adcs_msgs_py.params import Param, ParameterError, Schema, all_positive, non_negative, positive
from adcs_msgs_py.sections import Section, as_section, flat
from adcs_sim.truth.plant import Disturbance, Plant, ReactionWheels, Torquers
from adcs_sim.truth.sensor_schema import check_sensors, sensor_params
from adcs_sim.truth.thrusters import Thrusters


def step_timing(v: dict | Section) -> tuple[int, np.ndarray | int]:
    """(control period in integer ns, number of control steps) of a ``dynamics`` section.

    The one definition of the simulated time grid: step ``k`` starts at ``k * period_ns`` ns, on
    the graph and in the batch engine alike. A batched ``duration`` gives one count per run.
    """
    v = as_section(v)
    period_ns = int(round(float(v.control_period) * 1e9))
    duration_ns = np.round(np.asarray(v.duration, dtype=float) * 1e9)
    n_steps = np.floor(duration_ns / period_ns + 1e-9).astype(np.int64)
    return period_ns, (int(n_steps) if n_steps.ndim == 0 else n_steps)


def _dynamics_cross_check(v: dict) -> None:
    check_wheels(v, with_physics=True)
    check_thrusters(v)
    if v['thrusters.min_on_time'] > v['control_period']:
        raise ParameterError('thrusters.min_on_time', f'must not exceed control_period '
                             f'({v["control_period"]} s), got {v["thrusters.min_on_time"]}')
    if len(v['initial.momentum']) not in (0, 3):
        raise ParameterError('initial.momentum', f'expected 3 values (inertial axes, N m s) or none, '
                             f'got {len(v["initial.momentum"])}')
    if len(v['initial.momentum']) and np.any(np.asarray(v['initial.rate']) != 0.0):
        raise ParameterError('initial.rate', 'must be left at zero when initial.momentum is given '
                             '(the initial rate is then computed from the momentum)')
    n = len(v['wheels.names'])
    if n:
        problem = check_inertia(inertia_matrix(v['inertia']) - _wheel_spin_inertia(v), _BODY_INERTIA)
        if problem:
            raise ParameterError('wheels.spin_inertia', problem + ' (`inertia` must include the wheels)')
    if v['integrator.max_step'] > v['control_period']:
        raise ParameterError('integrator.max_step', f'must not exceed control_period '
                             f'({v["control_period"]} s), got {v["integrator.max_step"]}')
    if v['duration'] < v['control_period']:
        raise ParameterError('duration', f'must be at least one control period ({v["control_period"]} s)')
    if v['gravity_gradient'] and v['orbit.altitude'] <= 0 and not v['environment.enabled']:
        raise ParameterError('orbit.altitude', 'gravity_gradient needs an orbit altitude > 0 (m), or '
                             'environment.enabled (its orbit)')
    if v['link_faults.drop'] + v['link_faults.delay'] > 1.0:
        raise ParameterError('link_faults.delay', 'link_faults.drop + link_faults.delay must not exceed 1')
    commands = v['lockstep.commands']
    allowed = set(topics.COMMAND_TOPICS) | {'auto', 'none'}
    bad = [c for c in commands if c not in allowed]
    if bad:
        raise ParameterError('lockstep.commands', f'unknown command topic(s) {bad}; allowed: {sorted(allowed)}')
    if 'wheels/cmd' in command_topics(v) and not n:
        raise ParameterError('lockstep.commands', 'waits for wheels/cmd but no wheels are configured')
    if 'torque_cmd' in command_topics(v) and not v['torquers.enabled']:
        raise ParameterError('lockstep.commands', 'waits for torque_cmd but torquers.enabled is false')
    if topics.THRUSTERS_CMD in command_topics(v) and not v['thrusters.names']:
        raise ParameterError('lockstep.commands', 'waits for thrusters/cmd but no thrusters are configured')
    if v['environment.enabled']:
        check_environment(v)
        _check_one_orbit(v)
    check_sensors(v)


_ORBIT_KEYS = ('altitude', 'inclination_deg', 'raan_deg', 'arg_latitude_deg')


def _check_one_orbit(v: dict) -> None:
    """The truth model has one orbit: with ``environment.enabled`` the environment's (the sensors',
    the estimator references', the gravity gradient's, :func:`plant_orbit`). ``orbit.*`` may then only
    repeat a circular ``environment.circular.*``."""
    if v['orbit.altitude'] <= 0:
        return
    same = v['environment.orbit'] == 'circular' and all(
        v[f'orbit.{k}'] == v[f'environment.circular.{k}'] for k in _ORBIT_KEYS)
    if not same:
        raise ParameterError('orbit.altitude', f'orbit.* (gravity gradient) and environment.orbit '
                             f'({v["environment.orbit"]}: sensors, references) name two different orbits; '
                             'with environment.enabled leave orbit.* unset: the environment\'s orbit is the plant\'s')


_BODY_INERTIA = 'inertia minus the wheels\' spin inertia'


def _wheel_spin_inertia(v: dict) -> np.ndarray:
    """The wheels' spin inertia about the body axes, sum_i Js_i a_i a_i^T (3, 3), a_i the unit axes."""
    axes = np.asarray(v['wheels.axes'], dtype=float).reshape(len(v['wheels.names']), 3)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return np.einsum('i,ij,ik->jk', np.asarray(v['wheels.spin_inertia']), axes, axes)


def _dynamics_batch_check(v: dict, stacked: dict) -> bool:
    """Whether every run passes :func:`_dynamics_cross_check` when the values of ``stacked``
    (parameters it reads by value, one row per run) vary and the others are those of ``v`` (the
    first run's section, which passed it): its tests of those values over the rows at once, the
    same operations (Schema.validate_stacked). False for a parameter it has no such test for."""
    if not set(stacked) <= {'inertia', 'duration', 'initial.rate'}:
        return False
    if 'duration' in stacked and np.any(stacked['duration'] < v['control_period']):
        return False
    if 'initial.rate' in stacked and len(v['initial.momentum']) and np.any(stacked['initial.rate'] != 0.0):
        return False
    if 'inertia' in stacked and len(v['wheels.names']):
        try:
            check_inertias(inertia_matrix(stacked['inertia']) - _wheel_spin_inertia(v), _BODY_INERTIA)
        except ValueError:
            return False
    return True


def command_topics(v: dict) -> list[str]:
    """The command topics the dynamics node waits for each step (``auto`` / ``none`` resolved)."""
    commands = v['lockstep.commands']
    if 'none' in commands:
        return []
    if 'auto' in commands:
        auto = []
        if v['wheels.names']:
            auto.append(topics.WHEELS_CMD)
        if v['torquers.enabled']:
            auto.append(topics.TORQUE_CMD)
        if v.get('thrusters.names'):
            auto.append(topics.THRUSTERS_CMD)
        return auto
    return list(dict.fromkeys(commands))


# The time grid is in integer nanoseconds (step_timing): a shorter period rounds to 0 ns; a period's
# stamp carries int32 seconds.
MIN_CONTROL_PERIOD = 1e-9
MAX_CONTROL_PERIOD = 2 ** 31 - 1   # s (68 years)


def _control_period(v) -> str | None:
    return None if MIN_CONTROL_PERIOD <= v <= MAX_CONTROL_PERIOD else \
        f'must be in [{MIN_CONTROL_PERIOD:g}, {MAX_CONTROL_PERIOD}] s (the time grid is in integer ns), got {v!r}'


def _fraction(v) -> str | None:
    return None if 0.0 <= v <= 1.0 else f'must be a fraction in [0, 1], got {v}'


DYNAMICS_SCHEMA = Schema('dynamics', [
    inertia_param('total inertia incl. wheel spin inertia (kg m^2): 3 principal moments or 9 entries'),
    Param('initial.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
          check=check_unit_quaternion, doc='initial quaternion [x, y, z, w], body in inertial', batch=True,
          cross='none'),
    Param('initial.rate', 'double_array', default=[0.0, 0.0, 0.0], length=3,
          doc='initial body rate (rad/s, body axes)', batch=True),
    Param('initial.momentum', 'double_array', default=[],
          doc='total angular momentum H in inertial axes (N m s; empty: not given). When given, '
              'the initial body rate is the rest of H once the wheels hold their initial_speed: '
              'w0 = J^-1 (R(q0)^T H - sum_i a_i Js_i Omega0_i) (initial.rate must then be left '
              'at zero; seed 003: all of H in the body, wheels at rest)'),
    *wheel_params(with_physics=True),
    Param('torquers.enabled', 'bool', default=False, doc='ideal external torquers (torque_cmd)'),
    Param('torquers.max_torque', 'double_array', default=[math.inf] * 3, length=3, check=all_positive,
          finite=False, doc='per-axis torquer limit (N m; .inf for none)', batch=True, cross='none'),
    *thruster_params(with_physics=True),
    *[Param(f'disturbance.{name}', 'double_array', default=[0.0] * 3, length=3, doc=doc, batch=True, cross='none')
      for name, doc in (('constant', 'N m, body axes'), ('amplitude', 'N m, body axes'), ('frequency', 'rad/s'),
                        ('phase', 'rad'))],
    Param('gravity_gradient', 'bool', default=False,
          doc="gravity-gradient torque on the orbit: orbit.*, or with environment.enabled the environment's"),
    Param('orbit.altitude', 'double', default=0.0, check=non_negative,
          doc='circular orbit altitude (m); with environment.enabled leave orbit.* unset (one orbit: environment.*)'),
    Param('orbit.inclination_deg', 'double', default=0.0, doc='deg'),
    Param('orbit.raan_deg', 'double', default=0.0, doc='deg'),
    Param('orbit.arg_latitude_deg', 'double', default=0.0, doc='argument of latitude at t = 0 (deg)'),
    Param('control_period', 'double', default=1.0, check=_control_period,
          doc='zero-order-hold control period (s, at least 1 ns: the time grid is in integer ns); '
              'state published each period'),
    Param('duration', 'double', check=positive, doc='simulated duration (s)', batch=True),
    Param('integrator.max_step', 'double', default=0.1, check=positive,
          doc='largest RK4 step inside a control period (s)'),
    Param('mode', 'string', default='lockstep', choices=('lockstep', 'realtime'),
          doc='lockstep: wait for commands each step (deterministic); realtime: paced, no waiting'),
    Param('real_time_factor', 'double', default=1.0, check=positive,
          doc='realtime mode: simulated seconds per wall second'),
    Param('lockstep.commands', 'string_array', default=['auto'],
          doc="command topics to wait for each step; 'auto': those of the configured actuators; "
              "'none': free flight"),
    Param('lockstep.timeout', 'double', default=5.0, check=positive,
          doc='wall seconds to wait for a step\'s commands before applying the timeout policy'),
    Param('lockstep.timeout_policy', 'string', default='hold', choices=('hold', 'zero'),
          doc='on a missed step: hold the last command or apply zero'),
    Param('link_faults.seed', 'int', default=0, check=non_negative,
          doc='seed of the lost / late command draws (>= 0: numpy\'s seeds)'),
    Param('link_faults.drop', 'double', default=0.0, check=_fraction,
          doc='fraction of lockstep steps whose commands are lost (missed steps; adcs_sim/truth/link_faults.py)'),
    Param('link_faults.delay', 'double', default=0.0, check=_fraction,
          doc='fraction of lockstep steps whose commands come after the deadline (missed, then stale)'),
    Param('noise.seed', 'int', default=0, check=non_negative, batch=True, cross='none',
          doc='seed of the measurement noise generator (>= 0: numpy\'s seeds)'),
    Param('noise.attitude_std', 'double', default=0.0, check=non_negative,
          doc='star-tracker noise, rad (1 sigma per axis, small-angle rotation)'),
    Param('noise.rate_std', 'double', default=0.0, check=non_negative, doc='gyro noise, rad/s (1 sigma)'),
    Param('noise.gyro_bias', 'double_array', default=[0.0] * 3, length=3, doc='constant gyro bias, rad/s'),
    *sensor_params(),
    Param('environment.enabled', 'bool', default=False,
          doc='compute the environment at each step (orbit, Sun, eclipse, field: environment.*) for the '
              'sensors: needed by the sun sensor and the magnetometer, gives the star tracker its exclusions'),
    *environment_params(),
    Param('visualization.enabled', 'bool', default=True,
          doc='publish frames/body, frames/orbit, markers, error/eigenaxis and error/euler_213 for viewers '
              '(adcs_msgs_py/visual.py; each built only while subscribed, as the recorder always is)'),
    Param('visualization.target_attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
          check=check_unit_quaternion,
          doc="target [x, y, z, w] of error/* and of the target-axes markers; adcs-run sets it to the "
              "controller section's target.attitude (the offline analysis' target)"),
    Param('visualization.axis_length', 'double', default=1.0, check=positive,
          doc='length of the body-axes markers (m); the other markers scale with it'),
    Param('startup.state_subscribers', 'int', default=-1,
          doc='matched subscribers of `state` to wait for before t = 0 (-1: one per awaited command '
              'topic, plus the recorder)'),
    Param('startup.sensor_subscribers', 'int', default=-1,
          doc='matched subscribers of each fitted sensor\'s topic (sensors/*) to wait for before t = 0, '
              'the recorder included (-1: the recorder, if expected; the runner sets it when an estimator listens)'),
    *startup_params(),
    expect_faults_param(),
], cross_check=_dynamics_cross_check, batch_cross_check=_dynamics_batch_check,
    doc='plant, simulated clock and lockstep loop')


def build_truth_environment(v: dict | Section) -> Environment | None:
    """The truth model's environment of a validated dynamics section (None unless
    ``environment.enabled``): what its sensors measure."""
    v = as_section(v)
    return build_environment(flat(v.environment, 'environment.')) if v.environment.enabled else None


def build_plant(v: dict | Section, warm: bool = True) -> Plant:
    """Plant from validated ``dynamics`` parameters (``warm``: as :class:`Plant`'s)."""
    v = as_section(v)
    actuators = []
    wheels, thrusters = v.wheels, v.thrusters
    names = wheels.names
    if names:
        n = len(names)
        # an empty per-wheel list is the model's neutral value on every wheel (the schema's doc)
        opt = lambda value, neutral: value if np.size(value) else [neutral] * n  # noqa: E731
        actuators.append(ReactionWheels(
            names=list(names), axes=np.asarray(wheels.axes).reshape(n, 3),
            spin_inertia=wheels.spin_inertia, max_torque=wheels.max_torque,
            max_speed=wheels.max_speed, viscous=opt(wheels.viscous_friction, 0.0),
            coulomb=opt(wheels.coulomb_friction, 0.0), speed_gain=opt(wheels.speed_loop_gain, 1.0),
            initial_speed=opt(wheels.initial_speed, 0.0)))
    if v.torquers.enabled:
        actuators.append(Torquers(max_torque=v.torquers.max_torque))
    if thrusters.names:
        actuators.append(Thrusters(
            names=list(thrusters.names), positions=thrusters.positions,
            directions=thrusters.directions,  # (3 n,) or a batch (N, 3 n) of geometries
            max_force=thrusters.max_force, min_on_time=thrusters.min_on_time,
            min_on_rule=thrusters.min_on_rule))
    d = v.disturbance
    disturbance = Disturbance(d.constant, d.amplitude, d.frequency, d.phase)
    return Plant(inertia_matrix(v.inertia), actuators, disturbance, plant_orbit(v), v.gravity_gradient, warm=warm)


def plant_orbit(v: dict | Section) -> CircularOrbit | SourceOrbit | None:
    """The truth model's one orbit (the gravity gradient's; the viewers' orbit frame when circular):
    with ``environment.enabled`` the environment's, the very elements its circular orbit samples
    (:func:`adcs_core.environment.environment.orbit_source`) or the SGP4 of its TLE
    (:class:`~adcs_core.environment.environment.SourceOrbit`); else ``orbit.*`` (None at altitude 0).
    :func:`_check_one_orbit` refuses a scenario giving both, different."""
    v = as_section(v)
    if v.environment.enabled:
        source = orbit_source(flat(v.environment, 'environment.'))
        if isinstance(source, CircularOrbitSource):
            return source.orbit
        return SourceOrbit(source, parse_epoch(v.environment.epoch))
    if v.orbit.altitude <= 0:
        return None
    return CircularOrbit(altitude=v.orbit.altitude, inclination=math.radians(v.orbit.inclination_deg),
                         raan=math.radians(v.orbit.raan_deg),
                         arg_latitude0=math.radians(v.orbit.arg_latitude_deg))


def initial_state(plant: Plant, v: dict | Section) -> np.ndarray:
    """The plant's state at t = 0. With ``initial.momentum`` (H, inertial axes) the wheels start at
    their ``initial_speed`` and the body carries the rest: ``J w0 = R(q0)^T H - sum_i a_i Js_i
    Omega0_i`` (total J, the plant's convention ``H = J w + sum_i a_i Js_i Omega_i``)."""
    v = as_section(v)
    q = np.asarray(v.initial.attitude, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    H = np.asarray(v.initial.momentum, dtype=float)
    if H.shape[-1:] != (3,):
        return plant.initial_state(q, v.initial.rate)
    from adcs_core.attitude import matvec, rotate_to_body
    x0 = plant.initial_state(q, np.zeros(3))
    h_wheels = plant.angular_momentum(x0)          # the wheels' part alone (w = 0)
    w0 = matvec(np.linalg.inv(plant.inertia), rotate_to_body(q, H) - h_wheels)
    return plant.initial_state(q, w0)


# --- faults -------------------------------------------------------------------------------------


