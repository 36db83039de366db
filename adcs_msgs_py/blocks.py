"""Parameter blocks shared by several node schemas (the spacecraft's inertia and wheels, the
thrusters, the start-up options, the environment of attitude determination), built on the schema
machinery of :mod:`adcs_msgs_py.params`."""
from __future__ import annotations

import math

import numpy as np

from adcs_core.environment.frames import parse_epoch
from adcs_core.environment.options import IGRF_YEARS, MAGNETIC_MODELS, ORBIT_KINDS, SHADOW_MODELS
from adcs_core.environment.tle import parse_tle, tle_line_problem
from adcs_core.inertia import check_inertia, check_inertias, inertia_matrix
from adcs_msgs_py.names import parse_publishers
from adcs_msgs_py.params import (
    Param,
    ParameterError,
    all_non_negative,
    all_positive,
    non_negative,
    positive,
    vectorised,
)

UNIT_TOLERANCE = 1e-3  # an initial quaternion further than this from unit norm is refused


def _physical_inertias(values: np.ndarray) -> bool:
    """Whether :func:`_check_inertia_values` passes each row of ``values`` (runs, 3 or 9)."""
    try:
        check_inertias(inertia_matrix(values), 'inertia')
    except ValueError:
        return False
    return True


@vectorised(_physical_inertias)
def _check_inertia_values(values) -> str | None:
    return check_inertia(inertia_matrix(values), 'inertia')


def _unit_quaternions(q: np.ndarray) -> bool:
    """:func:`check_unit_quaternion` of each row of ``q`` (runs, n): its sum of squares in its order."""
    total = q[:, 0] * q[:, 0]
    for j in range(1, q.shape[1]):
        total = total + q[:, j] * q[:, j]
    return not np.any(np.abs(np.sqrt(total) - 1.0) > UNIT_TOLERANCE)


@vectorised(_unit_quaternions)
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
              doc='motor torque limit per wheel (N m, > 0; .inf for none)', check=all_positive, finite=False,
              batch=True, cross='length'),
    ]
    if with_physics:
        params += [
            Param('wheels.spin_inertia', 'double_array', default=[],
                  doc='spin inertia per wheel (kg m^2, > 0); included in `inertia`', check=all_positive, batch=True),
            Param('wheels.max_speed', 'double_array', default=[],
                  doc='speed limit per wheel (rad/s, > 0; .inf for none)', check=all_positive,
                  finite=False, batch=True, cross='length'),
            Param('wheels.viscous_friction', 'double_array', default=[],
                  doc='viscous friction per wheel (N m s/rad, >= 0; default 0)', check=all_non_negative, batch=True,
                  cross='length'),
            Param('wheels.coulomb_friction', 'double_array', default=[],
                  doc='Coulomb friction per wheel (N m, >= 0; default 0)', check=all_non_negative, batch=True,
                  cross='length'),
            Param('wheels.speed_loop_gain', 'double_array', default=[],
                  doc='speed-mode loop bandwidth per wheel (1/s, > 0; default 1)', check=all_positive, batch=True,
                  cross='length'),
            Param('wheels.initial_speed', 'double_array', default=[],
                  doc='initial speed per wheel relative to the body (rad/s; default 0)', batch=True,
                  cross='length'),
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


def _check_publishers(entries) -> str | None:
    try:
        parse_publishers(entries)
    except ValueError as exc:
        return str(exc)
    return None


def startup_params() -> list[Param]:
    return [
        Param('startup.expect_recorder', 'bool', default=False,
              doc='wait until a recorder is subscribed to every topic this node publishes'),
        Param('startup.timeout', 'double', default=60.0, check=positive,
              doc='wall seconds to wait for the graph to connect before giving up'),
        Param('startup.publishers', 'string_array', default=[], check=_check_publishers,
              doc='which nodes may publish on each topic this node listens to, as '
                  '"topic=node[,node...]" ("faults=": nobody); a publisher of another node is an '
                  'intruder (adcs_msgs_py.guard); the runner sets it from the scenario; empty: not checked'),
    ]


def expect_faults_param() -> Param:
    """Nodes that act on faults (dynamics, controllers) wait for the whole schedule before t = 0."""
    return Param('startup.expect_faults', 'bool', default=False,
                 doc='wait for the complete fault schedule on `faults` (a fault_injector) before '
                     'the first step; the runner sets it when the scenario has a fault_injector')


def _check_epoch(value) -> str | None:
    try:
        parse_epoch(value)
    except ValueError as exc:
        return str(exc)
    return None


def _tle_line_check(number: int):
    return lambda line: None if line == '' else tle_line_problem(line, number)


def environment_params() -> list[Param]:
    """The ``environment.*`` block: what :func:`adcs_core.environment.environment.build_environment`
    takes (epoch, orbit, magnetic and shadow models); in the dynamics section (the truth model's
    environment) and in an estimator's (its onboard reference models)."""
    return [
        Param('environment.epoch', 'string', default='2026-03-20T12:00:00Z', check=_check_epoch,
              doc='UTC epoch of t = 0, ISO-8601 (e.g. "2026-03-20T12:00:00Z"; no offset means UTC)'),
        Param('environment.orbit', 'string', default='circular', choices=ORBIT_KINDS,
              doc='orbit propagation: circular (the elements below) or tle (SGP4 of environment.tle.*)'),
        Param('environment.circular.altitude', 'double', default=500e3, check=positive,
              doc='circular orbit altitude above the equatorial radius (m, > 0)'),
        Param('environment.circular.inclination_deg', 'double', default=0.0, doc='deg'),
        Param('environment.circular.raan_deg', 'double', default=0.0, doc='deg'),
        Param('environment.circular.arg_latitude_deg', 'double', default=0.0,
              doc='argument of latitude at t = 0 (deg)'),
        Param('environment.tle.line1', 'string', default='', check=_tle_line_check(1),
              doc='TLE line 1 (69 characters, checksum checked); required when environment.orbit is tle'),
        Param('environment.tle.line2', 'string', default='', check=_tle_line_check(2),
              doc='TLE line 2 (69 characters, checksum checked); required when environment.orbit is tle'),
        Param('environment.magnetic_model', 'string', default='igrf', choices=MAGNETIC_MODELS,
              doc='Earth field: igrf (IGRF-14, degree 13) or dipole (its first-degree terms at the epoch)'),
        Param('environment.shadow_model', 'string', default='conical', choices=SHADOW_MODELS,
              doc='Earth shadow: cylindrical (0 or 1) or conical (umbra, penumbra fraction)'),
    ]


def check_environment(v: dict) -> None:
    """Cross-check the environment block: the epoch inside the IGRF's years (both field models take
    its coefficients), a TLE orbit's two lines present and accepted by SGP4."""
    year = 2000.0 + parse_epoch(v['environment.epoch']) / 365.25
    if not IGRF_YEARS[0] <= year < IGRF_YEARS[1]:
        raise ParameterError('environment.epoch', f'the IGRF-14 field models cover {IGRF_YEARS[0]}-{IGRF_YEARS[1]}, '
                             f'got {v["environment.epoch"]!r}')
    if v['environment.orbit'] != 'tle':
        return
    for key in ('environment.tle.line1', 'environment.tle.line2'):
        if not v[key]:
            raise ParameterError(key, 'required when environment.orbit is tle')
    try:
        parse_tle(v['environment.tle.line1'], v['environment.tle.line2'])
    except ValueError as exc:
        raise ParameterError('environment.tle.line1', str(exc)) from None
