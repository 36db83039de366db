"""Checks across the sections of one scenario, and of what its run needs, before anything starts.

Each section is valid alone (its schema); these make sure they describe one spacecraft and one
graph that can run: the controller, the fault injector and the dynamics name the same wheels and
thrusters, the dynamics node waits for exactly the commands the controller sends, and the run's
memory and integration work fit. A refusal is a ParameterError naming the section and key, and
the need that cannot be met.
"""
from __future__ import annotations

import math
import os

import numpy as np

from adcs_msgs_py import names as topics
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.registry import NODES
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


def physical_memory_bytes() -> int:
    return os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')


def controller_commands(params: dict) -> set[str]:
    """The command topics a validated controller section publishes (adcs_controllers/nodes)."""
    if params.get('thrusters.names'):   # the backstepping controller: thrusters and its wheel
        return {topics.THRUSTERS_CMD, topics.WHEELS_CMD}
    return {topics.WHEELS_CMD if params.get('actuator', 'wheels') == 'wheels' else topics.TORQUE_CMD}


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
        sends, waits = controller_commands(params), set(command_topics(dyn))
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
    """The run's needs fit: the dynamics node's per-step memory and the RK4 sub-steps per period."""
    period_ns, n_steps = step_timing(dyn)
    steps = int(np.max(n_steps))
    memory = physical_memory_bytes() if memory is None else memory
    need = steps * DYNAMICS_BYTES_PER_STEP
    if need > MEMORY_SHARE * memory:
        raise ParameterError('duration', f'{steps} control steps (duration {np.max(dyn["duration"]):g} s / '
                             f'control_period {dyn["control_period"]:g} s): the dynamics node would allocate '
                             f'{need / 2**30:.3g} GiB at start ({DYNAMICS_BYTES_PER_STEP} B per step), more '
                             f'than {MEMORY_SHARE:.0%} of this machine\'s {memory / 2**30:.3g} GiB', 'dynamics')
    substeps = math.ceil(dyn['control_period'] / dyn['integrator.max_step'] - 1e-9)
    if substeps > MAX_SUBSTEPS_PER_PERIOD:
        raise ParameterError('integrator.max_step', f'control_period / integrator.max_step = {substeps} RK4 '
                             f'sub-steps per control step, more than the {MAX_SUBSTEPS_PER_PERIOD} that can run '
                             'in reasonable wall time per step', 'dynamics')
