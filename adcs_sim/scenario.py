"""Scenario parameters of the dynamics and recorder nodes, and the plant built from them (no ROS).

A scenario file is a ROS 2 params file with a section per node. This module declares the
``dynamics``, ``fault_injector`` and ``recorder`` sections (:data:`DYNAMICS_SCHEMA`,
:data:`FAULT_SCHEMA`, :data:`RECORDER_SCHEMA`), the spacecraft blocks shared with controllers
(inertia, wheels), :func:`build_plant` and the fault schedule (:func:`fault_schedule`).
"""
from __future__ import annotations

import math

import numpy as np

from adcs_msgs_py import names as topics
from adcs_msgs_py.params import (Param, ParameterError, Schema, all_non_negative, all_positive,
                                 non_negative, positive)
from adcs_sim.plant import (CircularOrbit, Disturbance, Plant, ReactionWheels, Torquers,
                            check_inertia)
from adcs_sim.thrusters import Thrusters

UNIT_TOLERANCE = 1e-3  # an initial quaternion further than this from unit norm is refused


def inertia_matrix(values) -> np.ndarray:
    """3 principal moments or 9 row-major entries -> 3x3 matrix (batch: (..., 3) -> (..., 3, 3))."""
    arr = np.asarray(values, dtype=float)
    if arr.shape[-1] == 3:
        return arr[..., :, None] * np.eye(3)
    return arr.reshape(arr.shape[:-1] + (3, 3))


def step_timing(v: dict) -> tuple[int, np.ndarray | int]:
    """(control period in integer ns, number of control steps) of a ``dynamics`` section.

    The one definition of the simulated time grid: step ``k`` starts at ``k * period_ns`` ns, on
    the graph and in the batch engine alike. A batched ``duration`` gives one count per run.
    """
    period_ns = int(round(float(v['control_period']) * 1e9))
    duration_ns = np.round(np.asarray(v['duration'], dtype=float) * 1e9)
    n_steps = np.floor(duration_ns / period_ns + 1e-9).astype(np.int64)
    return period_ns, (int(n_steps) if n_steps.ndim == 0 else n_steps)


def _check_inertia_values(values) -> str | None:
    return check_inertia(inertia_matrix(values), 'inertia')


def check_unit_quaternion(values) -> str | None:
    norm = math.sqrt(sum(v * v for v in values))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        return f'quaternion [x, y, z, w] must have unit norm (got {norm:.6g}, tolerance {UNIT_TOLERANCE})'
    return None


def inertia_param(doc: str) -> Param:
    return Param('inertia', 'double_array', doc=doc, length=(3, 9), check=_check_inertia_values, batch=True)


def wheel_params(with_physics: bool) -> list[Param]:
    """The ``wheels.*`` block. Controllers need names, axes, torque limits; the plant all of it."""
    params = [
        Param('wheels.names', 'string_array', default=[],
              doc='wheel names (the JointState names); empty: no wheels'),
        Param('wheels.axes', 'double_array', default=[],
              doc='spin axes in body axes, 3 per wheel, flattened (need not be unit)'),
        Param('wheels.max_torque', 'double_array', default=[],
              doc='motor torque limit per wheel (N m, > 0; .inf for none)', check=all_positive, finite=False, batch=True),
    ]
    if with_physics:
        params += [
            Param('wheels.spin_inertia', 'double_array', default=[],
                  doc='spin inertia per wheel (kg m^2, > 0); included in `inertia`', check=all_positive, batch=True),
            Param('wheels.max_speed', 'double_array', default=[],
                  doc='speed limit per wheel (rad/s, > 0; .inf for none)', check=all_positive,
                  finite=False, batch=True),
            Param('wheels.viscous_friction', 'double_array', default=[],
                  doc='viscous friction per wheel (N m s/rad, >= 0; default 0)', check=all_non_negative, batch=True),
            Param('wheels.coulomb_friction', 'double_array', default=[],
                  doc='Coulomb friction per wheel (N m, >= 0; default 0)', check=all_non_negative, batch=True),
            Param('wheels.speed_loop_gain', 'double_array', default=[],
                  doc='speed-mode loop bandwidth per wheel (1/s, > 0; default 1)', check=all_positive, batch=True),
            Param('wheels.initial_speed', 'double_array', default=[],
                  doc='initial speed per wheel relative to the body (rad/s; default 0)', batch=True),
        ]
    return params


def check_wheels(v: dict, with_physics: bool) -> None:
    """Cross-check the wheels block: lengths agree with ``wheels.names``, axes are not zero."""
    names = v['wheels.names']
    n = len(names)
    if len(set(names)) != n:
        raise ParameterError('wheels.names', f'wheel names must be unique, got {names}')
    if any(not name for name in names):
        raise ParameterError('wheels.names', 'wheel names must be non-empty strings')
    if len(v['wheels.axes']) != 3 * n:
        raise ParameterError('wheels.axes', f'expected 3 values per wheel ({3 * n} for {n} wheels), '
                             f'got {len(v["wheels.axes"])}')
    axes = np.asarray(v['wheels.axes'], dtype=float).reshape(n, 3)
    for i, axis in enumerate(axes):
        if np.linalg.norm(axis) < 1e-9:
            raise ParameterError('wheels.axes', f'axis of wheel {names[i]!r} has zero length')
    required = ['wheels.max_torque'] + (['wheels.spin_inertia', 'wheels.max_speed'] if with_physics else [])
    optional = ['wheels.viscous_friction', 'wheels.coulomb_friction', 'wheels.speed_loop_gain',
                'wheels.initial_speed'] if with_physics else []
    check_per_wheel(v, required, optional)


def check_per_wheel(v: dict, required=(), optional=(), why: str = '') -> None:
    """Each ``required`` key has one value per wheel of ``wheels.names``; each ``optional`` key one
    per wheel or none. ``why`` is appended to the message."""
    n = len(v['wheels.names'])
    for key in [*required, *optional]:
        got = len(v[key])
        if got != n and not (key in optional and got == 0):
            raise ParameterError(key, f'expected one value per wheel ({n}), got {got}{why}')


def thruster_params(with_physics: bool) -> list[Param]:
    """The ``thrusters.*`` block (seed 002 section 2.5): geometry and force for the plant and the
    controller's model; the valve's minimum on-time for the plant only."""
    params = [
        Param('thrusters.names', 'string_array', default=[],
              doc='thruster names (the JointState names of thrusters/cmd and thrusters/state); empty: none'),
        Param('thrusters.positions', 'double_array', default=[], batch=True,
              doc='positions from the centre of mass, body axes (m), 3 per thruster, flattened'),
        Param('thrusters.directions', 'double_array', default=[], batch=True,
              doc='thrust directions (body axes; the force on the body), 3 per thruster, need not be unit'),
        Param('thrusters.max_force', 'double_array', default=[], check=all_positive, batch=True,
              doc='thrust while on, per thruster (N, > 0)'),
    ]
    if with_physics:
        params += [
            Param('thrusters.min_on_time', 'double', default=0.0, check=non_negative,
                  doc='shortest valve opening (s); shorter commanded on-times follow min_on_rule'),
            Param('thrusters.min_on_rule', 'string', default='drop', choices=('drop', 'extend'),
                  doc='an on-time below min_on_time is dropped to 0 or extended to min_on_time'),
        ]
    return params


def check_thrusters(v: dict) -> None:
    """Cross-check the thrusters block: lengths agree with ``thrusters.names``, no zero direction."""
    names = v['thrusters.names']
    n = len(names)
    if len(set(names)) != n or any(not name for name in names):
        raise ParameterError('thrusters.names', f'thruster names must be unique non-empty strings, got {names}')
    for key in ('thrusters.positions', 'thrusters.directions'):
        if len(v[key]) != 3 * n:
            raise ParameterError(key, f'expected 3 values per thruster ({3 * n} for {n} thrusters), '
                                 f'got {len(v[key])}')
    d = np.asarray(v['thrusters.directions'], dtype=float).reshape(n, 3)
    for i, axis in enumerate(d):
        if np.linalg.norm(axis) < 1e-9:
            raise ParameterError('thrusters.directions', f'direction of thruster {names[i]!r} has zero length')
    if np.shape(v['thrusters.max_force'])[-1:] != (n,) and not (n == 0 and np.size(v['thrusters.max_force']) == 0):
        raise ParameterError('thrusters.max_force', f'expected one value per thruster ({n}), '
                             f'got {np.shape(v["thrusters.max_force"])[-1:]}')


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
        J = inertia_matrix(v['inertia'])
        axes = np.asarray(v['wheels.axes'], dtype=float).reshape(n, 3)
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        spin = np.einsum('i,ij,ik->jk', np.asarray(v['wheels.spin_inertia']), axes, axes)
        problem = check_inertia(J - spin, 'inertia minus the wheels\' spin inertia')
        if problem:
            raise ParameterError('wheels.spin_inertia', problem + ' (`inertia` must include the wheels)')
    if v['integrator.max_step'] > v['control_period']:
        raise ParameterError('integrator.max_step', f'must not exceed control_period '
                             f'({v["control_period"]} s), got {v["integrator.max_step"]}')
    if v['duration'] < v['control_period']:
        raise ParameterError('duration', f'must be at least one control period ({v["control_period"]} s)')
    if v['gravity_gradient'] and v['orbit.altitude'] <= 0:
        raise ParameterError('orbit.altitude', 'gravity_gradient needs an orbit altitude > 0 (m)')
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


def _fraction(v) -> str | None:
    return None if 0.0 <= v <= 1.0 else f'must be a fraction in [0, 1], got {v}'


def startup_params() -> list[Param]:
    return [
        Param('startup.expect_recorder', 'bool', default=False,
              doc='wait until a recorder is subscribed to every topic this node publishes'),
        Param('startup.timeout', 'double', default=60.0, check=positive,
              doc='wall seconds to wait for the graph to connect before giving up'),
    ]


def expect_faults_param() -> Param:
    """Nodes that act on faults (dynamics, controllers) wait for the whole schedule before t = 0."""
    return Param('startup.expect_faults', 'bool', default=False,
                 doc='wait for the complete fault schedule on `faults` (a fault_injector) before '
                     'the first step; the runner sets it when the scenario has a fault_injector')


DYNAMICS_SCHEMA = Schema('dynamics', [
    inertia_param('total inertia incl. wheel spin inertia (kg m^2): 3 principal moments or 9 entries'),
    Param('initial.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
          check=check_unit_quaternion, doc='initial quaternion [x, y, z, w], body in inertial', batch=True),
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
          finite=False, doc='per-axis torquer limit (N m; .inf for none)', batch=True),
    *thruster_params(with_physics=True),
    Param('disturbance.constant', 'double_array', default=[0.0] * 3, length=3, doc='N m, body axes', batch=True),
    Param('disturbance.amplitude', 'double_array', default=[0.0] * 3, length=3, doc='N m, body axes', batch=True),
    Param('disturbance.frequency', 'double_array', default=[0.0] * 3, length=3, doc='rad/s', batch=True),
    Param('disturbance.phase', 'double_array', default=[0.0] * 3, length=3, doc='rad', batch=True),
    Param('gravity_gradient', 'bool', default=False, doc='gravity-gradient torque on the orbit'),
    Param('orbit.altitude', 'double', default=0.0, check=non_negative, doc='circular orbit altitude (m)'),
    Param('orbit.inclination_deg', 'double', default=0.0, doc='deg'),
    Param('orbit.raan_deg', 'double', default=0.0, doc='deg'),
    Param('orbit.arg_latitude_deg', 'double', default=0.0, doc='argument of latitude at t = 0 (deg)'),
    Param('control_period', 'double', default=1.0, check=positive,
          doc='zero-order-hold control period (s); state published each period'),
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
    Param('link_faults.seed', 'int', default=0, doc='seed of the lost / late command draws'),
    Param('link_faults.drop', 'double', default=0.0, check=_fraction,
          doc='fraction of lockstep steps whose commands are lost (missed steps; adcs_sim/link_faults.py)'),
    Param('link_faults.delay', 'double', default=0.0, check=_fraction,
          doc='fraction of lockstep steps whose commands come after the deadline (missed, then stale)'),
    Param('noise.seed', 'int', default=0, doc='seed of the measurement noise generator', batch=True),
    Param('noise.attitude_std', 'double', default=0.0, check=non_negative,
          doc='star-tracker noise, rad (1 sigma per axis, small-angle rotation)'),
    Param('noise.rate_std', 'double', default=0.0, check=non_negative, doc='gyro noise, rad/s (1 sigma)'),
    Param('noise.gyro_bias', 'double_array', default=[0.0] * 3, length=3, doc='constant gyro bias, rad/s'),
    Param('startup.state_subscribers', 'int', default=-1,
          doc='matched subscribers of `state` to wait for before t = 0 (-1: one per awaited command '
              'topic, plus the recorder)'),
    *startup_params(),
    expect_faults_param(),
], cross_check=_dynamics_cross_check, doc='plant, simulated clock and lockstep loop')


def build_plant(v: dict) -> Plant:
    """Plant from validated ``dynamics`` parameters."""
    actuators = []
    names = v['wheels.names']
    if names:
        n = len(names)
        opt = lambda key, default: v[key] if np.size(v[key]) else [default] * n  # noqa: E731
        actuators.append(ReactionWheels(
            names=list(names), axes=np.asarray(v['wheels.axes']).reshape(n, 3),
            spin_inertia=v['wheels.spin_inertia'], max_torque=v['wheels.max_torque'],
            max_speed=v['wheels.max_speed'], viscous=opt('wheels.viscous_friction', 0.0),
            coulomb=opt('wheels.coulomb_friction', 0.0), speed_gain=opt('wheels.speed_loop_gain', 1.0),
            initial_speed=opt('wheels.initial_speed', 0.0)))
    if v['torquers.enabled']:
        actuators.append(Torquers(max_torque=v['torquers.max_torque']))
    if v['thrusters.names']:
        n = len(v['thrusters.names'])
        actuators.append(Thrusters(
            names=list(v['thrusters.names']), positions=v['thrusters.positions'],
            directions=v['thrusters.directions'],  # (3 n,) or a batch (N, 3 n) of geometries
            max_force=v['thrusters.max_force'], min_on_time=v['thrusters.min_on_time'],
            min_on_rule=v['thrusters.min_on_rule']))
    orbit = None
    if v['orbit.altitude'] > 0:
        orbit = CircularOrbit(altitude=v['orbit.altitude'],
                              inclination=math.radians(v['orbit.inclination_deg']),
                              raan=math.radians(v['orbit.raan_deg']),
                              arg_latitude0=math.radians(v['orbit.arg_latitude_deg']))
    disturbance = Disturbance(v['disturbance.constant'], v['disturbance.amplitude'],
                              v['disturbance.frequency'], v['disturbance.phase'])
    return Plant(inertia_matrix(v['inertia']), actuators, disturbance, orbit, v['gravity_gradient'])


def initial_state(plant: Plant, v: dict) -> np.ndarray:
    """The plant's state at t = 0. With ``initial.momentum`` (H, inertial axes) the wheels start at
    their ``initial_speed`` and the body carries the rest: ``J w0 = R(q0)^T H - sum_i a_i Js_i
    Omega0_i`` (total J, the plant's convention ``H = J w + sum_i a_i Js_i Omega_i``)."""
    q = np.asarray(v['initial.attitude'], dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    H = np.asarray(v.get('initial.momentum', []), dtype=float)
    if H.shape[-1:] != (3,):
        return plant.initial_state(q, v['initial.rate'])
    from adcs_sim.attitude import matvec
    from adcs_sim.plant import rotate_to_body
    x0 = plant.initial_state(q, np.zeros(3))
    h_wheels = plant.angular_momentum(x0)          # the wheels' part alone (w = 0)
    w0 = matvec(np.linalg.inv(plant.inertia), rotate_to_body(q, H) - h_wheels)
    return plant.initial_state(q, w0)


RECORDER_SCHEMA = Schema('recorder', [
    Param('output', 'string', default='', doc='bag folder to create (empty: runs/<timestamp>)'),
    Param('scenario_file', 'string', default='',
          doc='scenario file embedded in the bag as metadata (the runner sets it)'),
    Param('topics', 'string_array', default=['all'],
          doc="topics to record; 'all': every topic of the interface plus any discovered"),
    Param('chunk_size', 'int', default=65536, check=positive,
          doc='MCAP chunk size (bytes): smaller loses less on a crash'),
    Param('flush_period', 'double', default=0.5, check=positive,
          doc='wall seconds between flushes of the open chunk to disk'),
    Param('discovery_period', 'double', default=1.0, check=positive,
          doc='wall seconds between looks for new topics to record'),
    *startup_params(),
], doc='records every topic of the graph to a rosbag2 MCAP bag')


# --- faults -------------------------------------------------------------------------------------

FAULT_MODES = topics.FAULT_ERROR_MODES + ('recovered',)  # what a schedule may say
MAX_FAULT_EVENTS = 64  # the latched `faults` topic keeps 100 messages: the whole schedule fits


def _fault_cross_check(v: dict) -> None:
    times, actuators = v['schedule.time'], v['schedule.actuator']
    modes, values = v['schedule.mode'], v['schedule.value']
    n = len(times)
    for key, seq in (('schedule.actuator', actuators), ('schedule.mode', modes)):
        if len(seq) != n:
            raise ParameterError(key, f'expected one entry per scheduled event ({n} in schedule.time), '
                                 f'got {len(seq)}')
    if len(values) not in (0, n):
        raise ParameterError('schedule.value', f'expected one entry per scheduled event ({n} in '
                             f'schedule.time) or none, got {len(values)}')
    if n > MAX_FAULT_EVENTS:
        raise ParameterError('schedule.time', f'at most {MAX_FAULT_EVENTS} events, got {n}')
    bad = [t for t in times if t < 0]
    if bad:
        raise ParameterError('schedule.time', f'event times must be >= 0 (sim seconds), got {bad}')
    bad = [m for m in modes if m not in FAULT_MODES]
    if bad:
        raise ParameterError('schedule.mode', f'unknown mode(s) {bad}; allowed: {list(FAULT_MODES)}')
    wheels = v['wheels.names']
    if len(set(wheels)) != len(wheels):
        raise ParameterError('wheels.names', f'wheel names must be unique, got {wheels}')
    unknown = [a for a in actuators if a not in wheels]
    if unknown:
        raise ParameterError('schedule.actuator', f'unknown actuator(s) {sorted(set(unknown))}; the '
                             f'scenario\'s wheels (wheels.names) are {list(wheels)}')
    for i, (mode, value) in enumerate(zip(modes, values)):
        if mode == 'degraded' and value < 0:
            raise ParameterError('schedule.value', f'event {i}: a degraded torque limit must be >= 0 '
                                 f'(N m), got {value}')


FAULT_SCHEMA = Schema('fault_injector', [
    Param('wheels.names', 'string_array', default=[],
          doc="the scenario's wheel names (as in the dynamics section): what a fault may name"),
    Param('schedule.time', 'double_array', default=[], doc='event times (sim seconds, >= 0)'),
    Param('schedule.actuator', 'string_array', default=[], doc='wheel name of each event'),
    Param('schedule.mode', 'string_array', default=[],
          doc='mode of each event: failed (no motor torque), degraded (torque limit = value), '
              'bias (extra motor torque = value), stuck (speed relative to the body frozen), '
              'recovered (nominal)'),
    Param('schedule.value', 'double_array', default=[],
          doc='per event: degraded limit or bias torque (N m); ignored otherwise; empty: all 0'),
    *startup_params(),
], cross_check=_fault_cross_check, doc='publishes the fault schedule on `faults`')


def fault_schedule(v: dict) -> list[tuple[int, dict[str, tuple[str, float, float]]]]:
    """The schedule of a validated ``fault_injector`` section as snapshots: ``[(t_ns, {wheel:
    (mode, value, time of its last event)})]``, one per distinct event time (events at the same
    time in schedule order), preceded by the all-nominal snapshot at 0. Each snapshot is the full
    state of every wheel after the events up to its time."""
    wheels = list(v['wheels.names'])
    values = v['schedule.value'] or [0.0] * len(v['schedule.time'])
    events = sorted(zip((int(round(t * 1e9)) for t in v['schedule.time']), range(len(values)),
                        v['schedule.actuator'], v['schedule.mode'], values))
    state = {w: ('nominal', 0.0, 0.0) for w in wheels}
    out = [(0, dict(state))]
    for t_ns, _, wheel, mode, value in events:
        state[wheel] = (mode, float(value) if mode in ('degraded', 'bias') else 0.0, t_ns / 1e9)
        if out[-1][0] == t_ns and len(out) > 1:
            out[-1] = (t_ns, dict(state))
        else:
            out.append((t_ns, dict(state)))
    return out
