"""Checks across the sections of one scenario, and of what its run needs, before anything starts.

Each section is valid alone (its schema); these make sure they describe one spacecraft and one
graph that can run: the controller, the fault injector and the dynamics name the same wheels and
thrusters, the dynamics node waits for exactly the commands the controller sends, and the run's
memory, integration work and actuator count fit. The whole run, not its first instant (issue #31):
each estimator's filter can do its arithmetic, every environment can be sampled up to the run's end
(field model years, a trial SGP4 propagation of each TLE), and the bag fits on the disk of the
output folder (:func:`check_disk`, called by the runner, which knows the folder). A refusal is a
ParameterError naming the section and key, and the need that cannot be met.
"""
from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import numpy as np

from adcs_controllers.estimators.families import covariance_problem
from adcs_core.environment.environment import span_problem
from adcs_msgs_py import names as topics
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.truth.schema import command_topics, step_timing
from adcs_sim.truth.sensor_schema import fault_targets, fitted_sensors

# Memory the dynamics node allocates per control step before the first one (the per-step
# link-fault draws of adcs_sim/truth/link_faults.py: a float64 draw, int64 temporaries, int8 fates).
DYNAMICS_BYTES_PER_STEP = 32
# Share of this machine's physical memory one run's dynamics node may claim at start.
MEMORY_SHARE = 0.5
# RK4 sub-steps per control period beyond which a step cannot run in reasonable wall time (each
# sub-step is a few tens of microseconds of Python; 10^5 of them are seconds per simulated step).
MAX_SUBSTEPS_PER_PERIOD = 100_000


# Actuators (wheels, thrusters) one run may have: the first command of a set of n actuators builds its
# message template (adcs_msgs_py.cdr.joint_state_template) in a time growing faster than n^2, in the
# dynamics node and the controller at the same step: 0.9 s at 100 wheels, 4.2 s at 300, 58 s at 1000
# measured on the 2-core machine under load (2026-12-06), against the 5 s default lockstep.timeout
# a step's commands have. 64 keeps that step a few tenths of a second (and every later one well
# under a millisecond); a spacecraft carries 3 to 12.
MAX_ACTUATORS = 64
# Bytes one recorded message takes in the bag: the 30 committed bags (bags/) hold 50-100 B a message
# (zstd chunks, indexes and summary included), whatever the topic; 128 is their largest with a margin.
BAG_BYTES_PER_MESSAGE = 128


def physical_memory_bytes() -> int:
    return os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')


def controller_commands(section: str, params: dict) -> set[str]:
    """The command topics a validated controller section publishes (its actuation's)."""
    return set(NODES[section].family.actuation_class(params).command_topics)


LOCKSTEP_WAIT = 'else every step waits out the lockstep timeout'


def _same_names(kind: str, dynamics: list, other: list, section: str, why: str = LOCKSTEP_WAIT) -> None:
    if sorted(other) != sorted(dynamics):
        raise ParameterError(f'{kind}.names', f'{list(other)} are not the dynamics section\'s {kind} '
                             f'(dynamics.{kind}.names: {list(dynamics)}): the {section} node and the plant '
                             f'must name the same {kind}, {why}', section)


def check_agreement(validated: dict) -> None:
    """The sections describe one spacecraft and one graph (ParameterError naming the disagreement)."""
    dyn = validated['dynamics']
    for name, params in validated.items():
        if NODES[name].role != 'controller':
            continue
        sends, waits = controller_commands(name, params), set(command_topics(dyn))
        if sends != waits:
            raise ParameterError('actuator' if 'actuator' in params else 'thrusters.names',
                                 f'the controller sends {sorted(sends)} but the dynamics node waits for '
                                 f'{sorted(waits) or "nothing"} (dynamics: wheels.names, torquers.enabled, '
                                 'thrusters.names, lockstep.commands): the actuator kinds disagree', name)
        if topics.WHEELS_CMD in sends:
            _same_names('wheels', dyn['wheels.names'], params['wheels.names'], name)
        if topics.THRUSTERS_CMD in sends:
            _same_names('thrusters', dyn['thrusters.names'], params['thrusters.names'], name)
    for name, params in validated.items():
        if NODES[name].role == 'estimator':
            missing = [s for s in params['sensors'] if s not in fitted_sensors(dyn)]
            if missing:
                raise ParameterError('sensors', f'the estimator uses {missing}, which the dynamics section does not '
                                     f'fit (sensors fitted: {list(fitted_sensors(dyn)) or "none"}; dynamics: '
                                     'sensors.<name>.enabled): it would wait for them every step', name)
    faults = validated.get('fault_injector')
    if faults is not None:
        unknown = sorted(set(faults['schedule.actuator']) - set(dyn['wheels.names']) - fault_targets(dyn))
        if unknown:
            raise ParameterError('schedule.actuator', f'fault on actuator(s) or sensor(s) {unknown} that the '
                                 f'dynamics section does not have (dynamics.wheels.names: {list(dyn["wheels.names"])}; '
                                 f'sensors fitted: {list(fitted_sensors(dyn)) or "none"})', 'fault_injector')
        if faults['wheels.names']:
            _same_names('wheels', dyn['wheels.names'], faults['wheels.names'], 'fault_injector',
                        'else its fault messages describe another set of wheels')


def check_resources(dyn: dict, memory: int | None = None) -> None:
    """The run's needs fit: the dynamics node's per-step memory, the actuators a step can afford and
    the RK4 sub-steps per period."""
    period_ns, n_steps = step_timing(dyn)
    steps = int(np.max(n_steps))
    memory = physical_memory_bytes() if memory is None else memory
    need = steps * DYNAMICS_BYTES_PER_STEP
    if need > MEMORY_SHARE * memory:
        raise ParameterError('duration', f'{steps} control steps (duration {np.max(dyn["duration"]):g} s / '
                             f'control_period {dyn["control_period"]:g} s): the dynamics node would allocate '
                             f'{need / 2**30:.3g} GiB at start ({DYNAMICS_BYTES_PER_STEP} B per step), more '
                             f'than {MEMORY_SHARE:.0%} of this machine\'s {memory / 2**30:.3g} GiB', 'dynamics')
    for kind in ('wheels', 'thrusters'):
        count = len(dyn.get(f'{kind}.names', ()))
        if count > MAX_ACTUATORS:
            raise ParameterError(f'{kind}.names', f'{count} {kind}: at most {MAX_ACTUATORS} '
                                 '(the first command of n actuators costs a time growing faster than n^2: '
                                 f'seconds per step beyond ~100; adcs_sim.app.scenario.checks)', 'dynamics')
    substeps = math.ceil(dyn['control_period'] / dyn['integrator.max_step'] - 1e-9)
    if substeps > MAX_SUBSTEPS_PER_PERIOD:
        raise ParameterError('integrator.max_step', f'control_period / integrator.max_step = {substeps} RK4 '
                             f'sub-steps per control step, more than the {MAX_SUBSTEPS_PER_PERIOD} that can run '
                             'in reasonable wall time per step', 'dynamics')


def check_whole_run(validated: dict) -> None:
    """What the run meets after its first instant (issue #31): each estimator's filter arithmetic at
    the start (:func:`~adcs_controllers.estimators.families.covariance_problem`) and every environment
    (the dynamics', an estimator's onboard one) over ``[epoch, epoch + duration]``: the field model's
    years and a trial SGP4 propagation of each TLE (:func:`~adcs_core.environment.environment.span_problem`)."""
    dyn = validated['dynamics']
    duration, period = float(np.max(dyn['duration'])), float(dyn['control_period'])
    environments = [('dynamics', dyn)] if dyn['environment.enabled'] else []
    for name, params in validated.items():
        if NODES[name].role != 'estimator':
            continue
        problem = covariance_problem(params, period)
        if problem is not None:
            raise ParameterError(*problem, name)
        if params['references.model'] == 'environment':
            environments.append((name, params))
    for name, params in environments:
        found = span_problem(params, duration, period)
        if found is not None:
            kind, why = found
            if kind == 'orbit':
                key = 'environment.tle.line1'
            else:   # the span's end: the dynamics' duration, or an estimator's own epoch
                key = 'duration' if name == 'dynamics' else 'environment.epoch'
            raise ParameterError(key, why, name)


def recorded_per_step(validated: dict) -> int:
    """The messages a run of ``validated`` records each control step (the topics of its bag that
    carry one a step; checked against the committed bags)."""
    dyn = validated['dynamics']
    roles = [NODES[name].role for name in validated]
    fitted = fitted_sensors(dyn)
    n = 3   # state, /clock, actuators/torque
    n += bool(dyn['wheels.names']) + bool(dyn['thrusters.names'])   # wheels/state, thrusters/state
    n += len(command_topics(dyn)) + roles.count('controller')       # commands, controller/status
    n += len(fitted) + 2 * roles.count('estimator')                  # sensors/*, estimate/state + status
    n += bool(fitted or dyn['noise.attitude_std'] or dyn['noise.rate_std'] or any(dyn['noise.gyro_bias']))
    if dyn['visualization.enabled']:   # frames/body, markers, error/*, /tf; the orbit frame and its /tf
        n += 5 + 2 * (dyn['orbit.altitude'] > 0)
    return n


def check_disk(validated: dict, out: Path) -> None:
    """The run's bag fits on the disk of ``out`` (its first existing ancestor): ParameterError naming
    ``duration`` and the disk otherwise, before anything starts."""
    steps = int(np.max(step_timing(validated['dynamics'])[1])) + 1
    per_step = recorded_per_step(validated)
    need = steps * per_step * BAG_BYTES_PER_MESSAGE
    where = Path(out).absolute()
    while not where.exists():
        where = where.parent
    free = shutil.disk_usage(where).free
    if need > free:
        raise ParameterError('duration', f'the bag of {steps} steps x {per_step} messages would take ~'
                             f'{need / 2**30:.3g} GiB ({BAG_BYTES_PER_MESSAGE} B a message), more than the '
                             f'{free / 2**30:.3g} GiB free on the disk of {where}', 'dynamics')
