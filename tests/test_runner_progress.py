"""The runner's own participant (the progress bar on /clock) is one of the run's: it listens on the
run's leased domain with the run's discovery range, whatever the shell's ROS_DOMAIN_ID (issue #17)."""
from __future__ import annotations

import os
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from adcs_sim.app.graph.domains import DomainLease
from adcs_sim.app.graph.processes import Progress, graph_env

pytestmark = pytest.mark.graph   # rclpy contexts of its own (no ros_domain)

DEADLINE = 60.0   # a hang guard only


def _clock_publisher(domain_id: int):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('clock_source', context=context)
    pub = node.create_publisher(Clock, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    return context, node, pub


def _clock(sec: int) -> Clock:
    msg = Clock()
    msg.clock.sec = sec
    return msg


def test_progress_follows_the_runs_clock_not_the_shells(monkeypatch):
    shell, run = DomainLease(100, 232), DomainLease(100, 232)
    try:
        monkeypatch.setenv('ROS_DOMAIN_ID', str(shell.domain_id))
        env = graph_env(run)
        progress = Progress(100.0, False, env)
        pubs = [_clock_publisher(shell.domain_id), _clock_publisher(run.domain_id)]
        try:
            deadline = time.monotonic() + DEADLINE
            while progress.sim_time == 0:
                assert time.monotonic() < deadline, 'the runner never saw the run\'s /clock'
                pubs[0][2].publish(_clock(1000))   # the shell's domain: must never be seen
                pubs[1][2].publish(_clock(7))      # the run's domain
                progress.spin(0.05)
            assert progress.sim_time == 7.0
        finally:
            for context, node, _ in pubs:
                node.destroy_node()
                rclpy.try_shutdown(context=context)
            progress.close()
        assert os.environ['ROS_DOMAIN_ID'] == str(shell.domain_id)   # restored after the init
    finally:
        shell.release()
        run.release()
