"""Identity on the run's domain (issue 31 item 7, class "Identity").

* A process that takes the name of a node of the run: two nodes of one name in the graph at once.
  Every node of the run has one publisher on a topic, so a second publisher under an allowed
  node's name is a second node of that name: an intruder, refused as a foreign publisher is (the
  node acting on the topic stops, the recorder names it and quarantines what it sent, ``adcs-run``
  exits 1 naming it). A second node of a run node's name that publishes nothing vetted is found
  in the graph's node names. A controller the runner may restart (``--restart``) leaves its killed
  predecessor in the graph for a while: its topics are held until one of the two leaves.
* A publisher of another type on a run topic never matches, so it can never deliver: reported (the
  recorder's ``intrusions`` record, as a warning; ``adcs-run``'s output), and the run goes on with
  none of its messages quarantined.

Fake-graph tests for the vetting, and one short ``adcs-run`` of the PD slew with a rogue for each case.
"""
from __future__ import annotations

import numpy as np
import pytest
from std_msgs.msg import String
from support.rogue import FakeGraph, FakeSub, first_unclean_step, has_messages, run_with_rogue

from adcs_msgs_py import names, topics
from adcs_msgs_py.guard import PublisherVetting
from adcs_sim.app.analysis.metrics import RunData, bag_intrusions
from adcs_sim.app.analysis.run_data import intrusion_lines, unmatchable_lines
from adcs_sim.app.graph.runner import allowed_publishers
from adcs_sim.bag.reader import read_raw

RUN = {'wheels/cmd': ['pd_controller'], 'state': ['dynamics'],
       names.RUN_NODES: ['dynamics', 'pd_controller', 'recorder']}


def _vetting(graph, restartable=()):
    found, unmatchable = [], []
    allowed = {**RUN, names.RESTARTABLE: list(restartable)} if restartable else RUN
    return PublisherVetting(graph, allowed, found.extend, unmatchable.extend), found, unmatchable


# --- two nodes of one name ----------------------------------------------------------------------

def test_a_second_node_under_an_allowed_name_is_an_intruder():
    graph = FakeGraph()
    vetting, found, _ = _vetting(graph)
    sub = FakeSub(graph, '/wheels/cmd')
    graph.add('/wheels/cmd', 'pd_controller', 1)
    assert vetting.admit(sub, {})
    graph.add('/wheels/cmd', 'pd_controller', 2)      # a rogue that took the controller's name
    assert not vetting.admit(sub, {})                  # the first message after its match
    assert [(i.node, i.gid, i.duplicate) for i in found] == [('/pd_controller', '02' * 16, True)]
    assert 'a second node named /pd_controller' in found[0].describe()
    assert not vetting.admit(sub, {}) and len(found) == 1   # compromised, reported once
    # with per-message GIDs (a later rclpy) the node vetted first stays usable, the second is refused
    graph2 = FakeGraph()
    vetting2, found2, _ = _vetting(graph2)
    graph2.add('/wheels/cmd', 'pd_controller', 1)
    assert vetting2.admit(FakeSub(graph2, '/wheels/cmd'), {'publisher_gid': bytes([1] * 16)})
    graph2.add('/wheels/cmd', 'pd_controller', 2)
    assert not vetting2.admit(FakeSub(graph2, '/wheels/cmd'), {'publisher_gid': bytes([2] * 16)})
    assert vetting2.admit(FakeSub(graph2, '/wheels/cmd'), {'publisher_gid': bytes([1] * 16)})
    assert [i.gid for i in found2] == ['02' * 16]


def test_two_nodes_of_one_name_at_the_first_look_are_both_named():
    graph = FakeGraph()
    vetting, found, _ = _vetting(graph)
    graph.add('/state', 'dynamics', 1)
    graph.add('/state', 'dynamics', 2)
    assert not vetting.admit(FakeSub(graph, '/state'), {})
    assert sorted(i.gid for i in found) == ['01' * 16, '02' * 16] and all(i.duplicate for i in found)


def test_a_second_node_of_a_run_nodes_name_is_found_in_the_graphs_node_names():
    """One that publishes nothing vetted (it may subscribe, counted as the run's by the handshake)."""
    graph = FakeGraph()
    vetting, found, _ = _vetting(graph)
    graph.nodes += [('recorder', '/'), ('bystander', '/'), ('bystander', '/')]
    vetting.sweep([])
    assert found == []                                 # one recorder; a name outside the run: not ours
    graph.nodes.append(('recorder', '/'))
    vetting.sweep([])
    vetting.sweep([])
    assert [(i.node, i.topic, i.duplicate) for i in found] == [('/recorder', '', True)]
    assert found[0].describe() == 'a second node named /recorder in the graph'
    # a second node named as a publisher already found so is not named twice
    graph2 = FakeGraph()
    vetting2, found2, _ = _vetting(graph2)
    graph2.add('/wheels/cmd', 'pd_controller', 1, participant=1)
    vetting2.admit(FakeSub(graph2, '/wheels/cmd'), {})
    graph2.add('/wheels/cmd', 'pd_controller', 2, participant=2)
    vetting2.sweep([FakeSub(graph2, '/wheels/cmd')])
    assert [(i.node, i.topic) for i in found2] == [('/pd_controller', '/wheels/cmd')]


def test_a_restarted_controller_is_held_beside_its_predecessor_until_one_leaves(monkeypatch):
    """``adcs-run --restart``: a SIGKILLed controller stays in the graph until its participant's
    lease runs out; the restarted one's messages wait (missed steps) instead of ending the run."""
    graph = FakeGraph()
    vetting, found, _ = _vetting(graph, restartable=['pd_controller'])
    sub = FakeSub(graph, '/wheels/cmd')
    graph.add('/wheels/cmd', 'pd_controller', 1)
    assert vetting.admit(sub, {})
    graph.add('/wheels/cmd', 'pd_controller', 2)       # restarted; the killed one still listed
    assert not vetting.admit(sub, {}) and not vetting.admit(sub, {})
    graph.remove('/wheels/cmd', 1)                     # its lease ran out
    assert vetting.admit(sub, {}) and vetting.admit(sub, {})
    assert found == []
    # both still there after the grace: an intrusion; a node that is not restartable: at once
    monkeypatch.setattr('adcs_msgs_py.guard.DUPLICATE_GRACE_S', 0.0)
    graph.add('/wheels/cmd', 'pd_controller', 3)
    assert not vetting.admit(sub, {})
    assert [(i.node, i.gid) for i in found] == [('/pd_controller', '03' * 16)]


def test_the_runner_makes_the_controllers_restartable_only_with_restarts():
    def entries(restarts):
        return dict(e.split('=') for e in allowed_publishers(['dynamics', 'pd_controller', 'recorder'], restarts))
    assert names.RESTARTABLE not in entries(0)
    assert entries(2)[names.RESTARTABLE] == 'pd_controller'


# --- a publisher of another type ------------------------------------------------------------------

def test_a_publisher_of_another_type_is_reported_not_an_intruder():
    graph = FakeGraph()
    vetting, found, unmatchable = _vetting(graph)
    sub = FakeSub(graph, '/wheels/cmd')
    graph.add('/wheels/cmd', 'pd_controller', 1)
    graph.add('/wheels/cmd', 'rogue', 2, type_name='std_msgs/msg/String')
    assert all(vetting.admit(sub, {}) for _ in range(3))
    vetting.sweep([sub])
    assert found == [] and not vetting.compromised and vetting.refused['/wheels/cmd'] == 0
    assert [(u.node, u.topic, u.type_name) for u in unmatchable] == [('/rogue', '/wheels/cmd', 'std_msgs/msg/String')]
    assert 'can never deliver' in unmatchable[0].describe()
    # a rogue of the topic's own type after it is still an intruder
    graph.add('/wheels/cmd', 'rogue', 4)
    assert not vetting.admit(sub, {}) and [i.gid for i in found] == ['04' * 16]


def test_the_analysis_tells_intruders_from_unmatchable_publishers():
    recorded = [{'topic': '/wheels/cmd', 'node': '/rogue', 'gid': 'ab', 'allowed': 'pd_controller'},
                {'topic': '/wheels/cmd', 'node': '/pd_controller', 'gid': 'cd', 'allowed': 'pd_controller',
                 'duplicate': 'true'},
                {'topic': '', 'node': '/recorder', 'gid': '', 'allowed': 'none', 'duplicate': 'true'},
                {'topic': '/state', 'node': '/rogue', 'gid': 'ef', 'type': 'std_msgs/msg/String',
                 'expected': 'nav_msgs/msg/Odometry', 'unmatchable': 'true'}]
    assert intrusion_lines(recorded) == [
        'intruder node /rogue published on /wheels/cmd (GID ab; allowed: pd_controller)',
        'intruder node /pd_controller (a second node of that name) published on /wheels/cmd (GID cd; '
        'allowed: pd_controller)',
        'intruder node /recorder (a second node of that name) in the graph']
    assert unmatchable_lines(recorded) == [
        'node /rogue published std_msgs/msg/String on /state, which carries nav_msgs/msg/Odometry (GID ef): '
        'it could never deliver; ignored']


# --- through the graph ------------------------------------------------------------------------------

@pytest.mark.graph
def test_a_node_that_takes_a_run_nodes_name_is_refused_as_an_intrusion(tmp_path, monkeypatch):
    """A node named ``pd_controller`` (not the run's) sends maximum-torque commands from t = 2 s:
    the dynamics node stops before applying one, ``adcs-run`` exits 1 naming the second node of
    that name, the bag records it and every applied torque recorded is the clean run's."""
    code, err, out = run_with_rogue(tmp_path, monkeypatch, topics.WHEELS_CMD, name='pd_controller')
    assert code == 1, err
    assert 'run compromised' in err and 'node /pd_controller (a second node of that name)' in err, err
    bag = out / 'bag'
    found = bag_intrusions(bag)
    assert any('/pd_controller (a second node of that name) published on /wheels/cmd' in f for f in found), found
    run = RunData.from_bag(bag)
    assert run.intrusions == found and len(run.u) >= 2
    assert first_unclean_step(run.u) is None   # the dynamics node stops at once on wheels/cmd
    assert 'recorder.intrusions' in (bag / 'metadata.yaml').read_text()


@pytest.mark.graph
def test_a_publisher_of_another_type_is_reported_and_the_run_goes_on(tmp_path, monkeypatch):
    """A ``std_msgs/String`` publisher on ``wheels/cmd``, there before the run's nodes, answering
    every state: the run completes (exit 0), ``adcs-run`` warns naming the node, topic and type,
    the bag's ``intrusions`` record has it as a warning, nothing is quarantined and the run is the
    clean run, bit for bit."""
    steps = 3000   # the recorder discovers the rogue while the run goes on (a 300-step run once ended first)
    code, err, out = run_with_rogue(tmp_path, monkeypatch, topics.WHEELS_CMD, start_s=0.0,
                                    duration_s=steps, msg_type=String)
    assert code == 0, err
    warning = [line for line in err.splitlines() if line.startswith('adcs-run: warning: ')]
    assert len(warning) == 1 and all(w in warning[0] for w in ('/rogue', '/wheels/cmd', 'std_msgs/msg/String')), err
    bag = out / 'bag'
    assert bag_intrusions(bag) == []
    assert not any(names.quarantined(topic) for topic, *_ in read_raw(bag))
    assert has_messages(bag, '/intrusions')
    run = RunData.from_bag(bag)
    assert run.intrusions == [] and len(run.unmatchable) == 1 and 'std_msgs/msg/String' in run.unmatchable[0]
    np.testing.assert_array_equal(run.t, np.arange(steps + 1.0))
    assert first_unclean_step(run.u) is None


if __name__ == '__main__':
    raise SystemExit(pytest.main([__file__, '-q']))
