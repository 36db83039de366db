"""The ``fault_injector`` section: a schedule of actuator and sensor faults, validated, and the snapshots
it publishes on the latched ``faults`` topic (pure, no ROS; the node is :mod:`adcs_sim.nodes.fault_injector`).

An event names a wheel (of ``wheels.names``) or a sensor fault target of
:data:`adcs_msgs_py.sensor_interfaces.SENSOR_FAULT_MODES` (``star_tracker``, ``sun``, ``magnetometer``: ``failed`` /
``recovered``; ``gyro.x`` / ``gyro.y`` / ``gyro.z``: ``bias`` (value rad/s), ``stuck``, ``recovered``).
A snapshot holds every wheel and the sensor targets the schedule names (none: as before)."""
from __future__ import annotations

import math

from adcs_core.faults import FAULT_ERROR_MODES, FAULT_OK_MODES, FaultState
from adcs_msgs_py.blocks import startup_params
from adcs_msgs_py.params import Param, ParameterError, Schema
from adcs_msgs_py.sensor_interfaces import SENSOR_FAULT_MODES

FAULT_MODES = FAULT_ERROR_MODES + ('recovered',)  # what a schedule may say


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
    clash = sorted(set(wheels) & set(SENSOR_FAULT_MODES))
    if clash:
        raise ParameterError('wheels.names', f'{clash} name(s) sensor fault targets; choose other wheel names')
    unknown = [a for a in actuators if a not in wheels and a not in SENSOR_FAULT_MODES]
    if unknown:
        raise ParameterError('schedule.actuator', f'unknown actuator(s) {sorted(set(unknown))}; the '
                             f'scenario\'s wheels (wheels.names) are {list(wheels)}, the sensor fault '
                             f'targets {list(SENSOR_FAULT_MODES)}')
    for i, (actuator, mode) in enumerate(zip(actuators, modes)):
        allowed = SENSOR_FAULT_MODES.get(actuator)
        if allowed is not None and mode not in allowed + FAULT_OK_MODES:
            raise ParameterError('schedule.mode', f'event {i}: {actuator} has no mode {mode!r}; allowed: '
                                 f'{list(allowed + FAULT_OK_MODES)}')
    for i, (mode, value) in enumerate(zip(modes, values)):
        if mode == 'degraded' and value < 0:
            raise ParameterError('schedule.value', f'event {i}: a degraded torque limit must be >= 0 '
                                 f'(N m), got {value}')
    _check_gyro_bias(actuators, modes, values)


MAX_GYRO_BIAS = 10.0  # rad/s: a gyro bias jump beyond this is not a gyro any more


def _check_gyro_bias(actuators, modes, values) -> None:
    for i, (actuator, mode, value) in enumerate(zip(actuators, modes, values)):
        if actuator.startswith('gyro.') and mode == 'bias' and not (math.isfinite(value)
                                                                    and abs(value) <= MAX_GYRO_BIAS):
            raise ParameterError('schedule.value', f'event {i}: a gyro bias jump must be within '
                                 f'+-{MAX_GYRO_BIAS} rad/s, got {value}')


FAULT_SCHEMA = Schema('fault_injector', [
    Param('wheels.names', 'string_array', default=[],
          doc="the scenario's wheel names (as in the dynamics section): what a fault may name"),
    Param('schedule.time', 'double_array', default=[], doc='event times (sim seconds, >= 0)'),
    Param('schedule.actuator', 'string_array', default=[],
          doc='wheel name or sensor fault target (star_tracker, sun, magnetometer, gyro.x, gyro.y, gyro.z) '
              'of each event'),
    Param('schedule.mode', 'string_array', default=[],
          doc='mode of each event: failed (no motor torque), degraded (torque limit = value), '
              'bias (extra motor torque = value), stuck (speed relative to the body frozen), '
              'recovered (nominal); sensors: failed (no measurement: star tracker outage, failed '
              'magnetometer or sun sensor), gyro axis bias (reads value rad/s more), gyro axis stuck '
              '(repeats its reading of that step), recovered'),
    Param('schedule.value', 'double_array', default=[],
          doc='per event: degraded limit or bias torque (N m), gyro bias jump (rad/s); ignored otherwise; '
              'empty: all 0'),
    *startup_params(),
], cross_check=_fault_cross_check, doc='publishes the fault schedule on `faults`')


def fault_schedule(v: dict) -> list[tuple[int, dict[str, FaultState]]]:
    """The schedule of a validated ``fault_injector`` section as snapshots: ``[(t_ns, {wheel:
    FaultState(mode, value, time of its last event)})]``, one per distinct event time (events at the same
    time in schedule order), preceded by the all-nominal snapshot at 0. Each snapshot is the full
    state of every wheel after the events up to its time."""
    wheels = list(v['wheels.names'])
    values = v['schedule.value'] or [0.0] * len(v['schedule.time'])
    events = sorted(zip((int(round(t * 1e9)) for t in v['schedule.time']), range(len(values)),
                        v['schedule.actuator'], v['schedule.mode'], values))
    named = [t for t in SENSOR_FAULT_MODES if t in v['schedule.actuator']]
    state = {w: FaultState('nominal', 0.0, 0.0) for w in wheels + named}
    out = [(0, dict(state))]
    for t_ns, _, wheel, mode, value in events:
        state[wheel] = FaultState(mode, float(value) if mode in ('degraded', 'bias') else 0.0, t_ns / 1e9)
        if out[-1][0] == t_ns and len(out) > 1:
            out[-1] = (t_ns, dict(state))
        else:
            out.append((t_ns, dict(state)))
    return out
