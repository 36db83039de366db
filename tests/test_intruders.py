"""Intruders (issue 17 item 2): a publisher the run does not allow is detected, not applied, and
named by ``adcs-run``'s non-zero exit; the bag says so.

* :class:`adcs_msgs_py.guard.PublisherVetting` against a fake graph: allowed publishers pass, a
  foreign one makes the topic compromised before any message after its match is applied; with
  a per-message ``publisher_gid`` (a later rclpy) messages are filtered one by one.
* The rogue-publisher test: a participant outside the run, on the run's domain (loopback only),
  publishes well-formed, correctly stamped commands (maximum torque ``wheels/cmd``), spoofed
  ``state``, "all wheels failed" ``faults`` (no fault injector in the scenario). The run ends
  non-zero naming the intruder's node and topic, the bag holds it on ``intrusions``, and every
  applied torque recorded before the detection is the clean run's (the batch engine's), bit for bit.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from support.rogue import FakeGraph, FakeSub, first_unclean_step, has_messages, run_with_rogue

from adcs_msgs_py import topics
from adcs_msgs_py.guard import UNKNOWN_NODE, PublisherVetting
from adcs_sim.app.analysis.metrics import RunData, bag_intrusions
from adcs_sim.app.graph.runner import allowed_publishers
from adcs_sim.bag.reader import read_messages


def test_vetting_admits_the_allowed_and_compromises_a_topic_with_an_intruder():
    graph, found = FakeGraph(), []
    vetting = PublisherVetting(graph, {'wheels/cmd': ['pd_controller'], 'faults': []}, found.extend)
    sub = FakeSub(graph, '/wheels/cmd')
    graph.add('/wheels/cmd', 'pd_controller', 1)
    assert all(vetting.admit(sub, {}) for _ in range(3))
    graph.add('/wheels/cmd', 'rogue', 2)
    assert not vetting.admit(sub, {})           # the first message after the rogue's match
    assert [(i.node, i.topic) for i in found] == [('/rogue', '/wheels/cmd')]
    assert not vetting.admit(sub, {}) and vetting.refused['/wheels/cmd'] == 2
    assert len(found) == 1                      # reported once
    # nobody may publish faults in a scenario without a fault injector
    faults = FakeSub(graph, '/faults')
    graph.add('/faults', 'dynamics', 3)
    assert not vetting.admit(faults, {}) and found[-1].node == '/dynamics'
    # a topic nobody vets is not looked at
    assert vetting.admit(FakeSub(graph, '/rosout'), {})


def test_vetting_waits_for_a_publishers_name_and_filters_by_gid_when_rclpy_gives_it(monkeypatch):
    monkeypatch.setattr('adcs_msgs_py.guard.GRAPH_SETTLE_S', 0.0)
    graph, found = FakeGraph(), []
    vetting = PublisherVetting(graph, {'state': ['dynamics']}, found.extend)
    sub = FakeSub(graph, '/state')
    graph.add('/state', 'dynamics', 1)
    graph.add('/state', 'rogue', 2)
    assert vetting.admit(sub, {'publisher_gid': bytes([1] * 16)})       # the dynamics node's
    assert not vetting.admit(sub, {'publisher_gid': bytes([2] * 16)})   # the rogue's
    assert vetting.admit(sub, {'publisher_gid': {'data': [1] * 16}})    # topic still usable
    assert [i.node for i in found] == ['/rogue']
    # a publisher still unnamed when the settle time is out is not vouched for
    graph2, found2 = FakeGraph(), []
    vetting2 = PublisherVetting(graph2, {'state': ['dynamics']}, found2.extend)
    graph2.add('/state', UNKNOWN_NODE, 5)
    assert not vetting2.admit(FakeSub(graph2, '/state'), {})


def test_the_runner_allows_each_topic_to_its_nodes_only():
    allowed = dict(e.split('=') for e in allowed_publishers(['dynamics', 'pd_controller', 'recorder']))
    assert allowed['wheels/cmd'] == allowed['controller/status'] == 'pd_controller'
    assert allowed['state'] == allowed['/clock'] == allowed['actuators/torque'] == 'dynamics'
    assert allowed['faults'] == ''   # no fault injector: nobody


# --- the rogue publisher (tests/support/rogue.py) -------------------------------------------------

@pytest.mark.graph
@pytest.mark.parametrize('topic', [topics.WHEELS_CMD, topics.STATE, topics.FAULTS])
def test_rogue_publisher_is_detected_not_applied_and_named(tmp_path, monkeypatch, topic):
    code, err, out = run_with_rogue(tmp_path, monkeypatch, topic)
    assert code != 0, err
    assert 'run compromised' in err and 'rogue' in err and f'/{topic}' in err, err
    bag = out / 'bag'
    found = bag_intrusions(bag)
    assert found and all('/rogue' in f for f in found) and any(f'/{topic} ' in f for f in found), found
    if has_messages(bag, '/state') or topic != topics.STATE:
        run = RunData.from_bag(bag)
        assert run.intrusions == found   # the analysis' one pass reads what the intrusions reader reads
        u = run.u
    else:   # a recorder that lagged (a loaded machine) took every state after it had seen the rogue:
        # all under quarantine/state, none analysed as the run's (adcs_sim.app.analysis.run_data._namespace)
        assert has_messages(bag, '/quarantine/state')
        with pytest.raises(ValueError, match=r'no /state .* under /quarantine/state, not analysed\): nothing to '
                                             r'analyse; run compromised: intruder node /rogue'):
            RunData.from_bag(bag)
        u = np.array([[m.vector.x, m.vector.y, m.vector.z] for _, _, m in read_messages(bag, {'/actuators/torque'})])
    assert len(u) >= 2, 'the rogue starts at t = 2 s: the run had clean steps before it'
    # Every applied torque recorded is the clean run's, bit for bit, up to the node that applies the
    # topic stopping on the intrusion; after that only the last command held (missed steps, the
    # hold policy) until the runner stops the graph: never a command the rogue caused.
    first = first_unclean_step(u)
    if first is not None:
        assert first >= 2 and topic != topics.WHEELS_CMD   # the dynamics node stops at once on wheels/cmd
    assert (bag / 'metadata.yaml').exists() and 'recorder.intrusions' in (bag / 'metadata.yaml').read_text()
    analyzed = subprocess.run([sys.executable, '-m', 'adcs_sim.app.analysis.analyze', str(bag), '--no-report'],
                              capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert analyzed.returncode != 0 and 'run compromised' in analyzed.stderr and '/rogue' in analyzed.stderr


@pytest.mark.slow
@pytest.mark.graph
def test_a_spoofed_record_is_quarantined_not_analysed(tmp_path, monkeypatch):
    """actuators/torque is only recorded (nobody applies it): the run goes on, but the injected
    torques (issue 17: peak torque [123, 456, 789], exit 0) never reach the analysed topic; the
    recorder keeps everything of the compromised topic under quarantine/, and the run exits
    non-zero naming the intruder. The run is ended by SIGINT once the recorder has acknowledged
    20 of the rogue's messages (a 20-step run on a loaded machine once ended before the
    recorder's participant had discovered the rogue: exit 0, nothing to quarantine); an
    interrupted run that was compromised says both."""
    code, err, out = run_with_rogue(tmp_path, monkeypatch, topics.APPLIED_TORQUE, start_s=0.0, interrupt_after=20)
    assert code != 0 and 'interrupted by SIGINT' in err, err
    assert 'run compromised' in err and '/rogue' in err and '/actuators/torque' in err, err
    bag = out / 'bag'
    recorded = {name: [m.vector.x for _, _, m in read_messages(bag, {name})]
                for name in ('/actuators/torque', '/quarantine/actuators/torque')}
    assert 123.0 not in recorded['/actuators/torque']
    assert 123.0 in recorded['/quarantine/actuators/torque']
    run = RunData.from_bag(bag)
    assert len(run.t) > topics.ACK_INTERVAL and not np.any(run.u == 123.0)


# --- DDS Security (SROS2) -------------------------------------------------------------------------

def test_the_pypi_fast_dds_build_has_no_dds_security(ros_domain, tmp_path):
    """What the README says: the pinned PyPI Fast DDS (ros-fastrtps 2.14.5, used by
    ros-rmw-fastrtps-cpp 8.4.3) is built without -DSECURITY=ON, so an enclave (SROS2) cannot be
    used: rcl finds the enclave, then the rmw refuses to create the participant. If a later wheel
    ships the security plugins this fails, and ``adcs-run --secure`` becomes possible."""
    enclave = tmp_path / 'keystore' / 'enclaves' / 'probe'
    enclave.mkdir(parents=True)
    for name in ('identity_ca.cert.pem', 'cert.pem', 'key.pem', 'governance.p7s', 'permissions.p7s',
                 'permissions_ca.cert.pem'):
        (enclave / name).write_text('')
    env = ros_domain.env({**os.environ, 'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce',
                          'ROS_SECURITY_KEYSTORE': str(tmp_path / 'keystore')})
    probe = ('import rclpy\nfrom rclpy.context import Context\nc = Context()\n'
             "rclpy.init(context=c, args=['--ros-args', '--enclave', '/probe'])\n"
             "rclpy.create_node('probe', context=c)\n")
    result = subprocess.run([sys.executable, '-c', probe], env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode != 0
    assert "doesn't have the security libraries" in result.stderr and 'SECURITY=ON' in result.stderr
