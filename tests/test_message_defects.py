"""Small defects of the nodes' message handling (issue 17, "found while reading"), each pinned.

* The dynamics node mapped a lost ``thrusters/cmd`` to the ``'torquers'`` command key: a KeyError
  at the first lost step of a thruster scenario with ``link_faults`` and ``timeout_policy: zero``
  (seed 002's ESEO scenario). And with the ``hold`` policy a lost thruster command was applied
  anyway (the on-times are held apart from the plant's command dict).
* The backstepping controller never took the due fault snapshot (``FaultTracker.due``), so its
  ``late_faults`` was always 0.
"""
from __future__ import annotations

import numpy as np
import pytest
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_core.faults import FaultState
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_sim.truth.link_faults import DROP

ESEO = 'eseo_backstepping_slew.yaml'


def _lost_step(dyn) -> int:
    return int(np.flatnonzero(dyn.link.fates == DROP)[0])


@pytest.mark.parametrize('policy', ['zero', 'hold'])
def test_a_lost_thruster_step_follows_the_timeout_policy(ros_domain, tmp_path, policy):
    from adcs_sim.nodes.dynamics import DynamicsNode
    scenario = make_scenario(tmp_path, {'dynamics': {'link_faults.seed': 3, 'link_faults.drop': 0.5,
                                                     'lockstep.timeout_policy': policy}}, base=ESEO)
    with InProcessGraph(scenario) as graph:
        dyn = graph.add(DynamicsNode)
        assert set(dyn.awaited) == {topics.THRUSTERS_CMD, topics.WHEELS_CMD}
        k = _lost_step(dyn)
        before_on_time = np.full(dyn.thrusters.count, 0.25)
        dyn.on_time = before_on_time.copy()
        held = dyn._link_before(k)
        # step k's commands arrive (and are taken), then the simulated link loses them
        for msg, handler in ((cv.thruster_cmd_to_msg(0, dyn.thrusters.names, [0.5] * 4), dyn._on_thruster_cmd),
                             (cv.wheel_cmd_to_msg(0, dyn.wheels.names, effort=[0.001]), dyn._on_wheel_cmd)):
            dyn.step_ns = 0
            handler(msg)
        assert dyn.received == set(dyn.awaited)
        dyn._link_after(k, held)   # raised KeyError: 'torquers'
        assert dyn.missed_steps == 1
        wheels = dyn.commands['wheels'].value
        if policy == 'zero':
            assert not dyn.on_time.any() and not wheels.any()
        else:   # the commands in force before the lost step: not the lost ones
            np.testing.assert_array_equal(dyn.on_time, before_on_time)
            np.testing.assert_array_equal(wheels, np.zeros(1))


def test_backstepping_controller_counts_a_late_fault(ros_domain, tmp_path):
    from adcs_controllers.nodes.backstepping_controller import BacksteppingController
    scenario = make_scenario(tmp_path, base=ESEO)
    with InProcessGraph(scenario) as graph:
        ctrl = graph.add(BacksteppingController)
        q, w, speed = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(1)
        period = int(1e9)
        ctrl.on_pair(0, q, w, speed)
        ctrl.on_pair(period, q, w, speed)
        # a snapshot due at t = 1 s arrives after that step was answered: applied at the next, late
        ctrl.faults.add(period, 0, 1, {'rw_pitch': FaultState('failed', 0.0, 1.0)})
        ctrl.on_pair(2 * period, q, w, speed)
        assert ctrl.faults.late == 1
        assert ctrl.faults.applied == 0
