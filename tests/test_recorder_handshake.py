"""The recorder's start-up handshake: a writer of a recorded topic sends nothing before the recorder's
*readers* have matched it (``recorder/matched``, :meth:`AdcsNode.wait_recorder_matched`).

Why: DDS matches a writer and a reader on each side on its own. A writer's start-up wait
(``get_subscription_count``) sees only its own side; a VOLATILE reader whose side matches later
takes only what is written after that. A fresh-clone CI run recorded a bag without the first 59
steps of every topic that way. The handshake's two halves are tested here on their own (the late
match itself cannot be provoked on demand), and its message at the validation boundary.
"""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from std_msgs.msg import String
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import names, topics


# --- the message ----------------------------------------------------------------------------------

@settings(derandomize=True, max_examples=60, deadline=None)
@given(st.dictionaries(st.text(max_size=12), st.lists(st.text(max_size=12), max_size=4), max_size=5))
def test_the_matched_message_round_trips(matched):
    assert cv.matched_from_msg(cv.matched_to_msg(matched)) == {t: frozenset(n) for t, n in matched.items()}


@settings(derandomize=True, max_examples=200, deadline=None)
@given(st.text(max_size=64) | st.sampled_from(['[]', '{"a": 1}', '{"a": [1]}', '{"a": "b"}', 'null', '3']))
def test_any_other_text_is_refused_or_read_as_a_mapping_of_names(text):
    try:
        out = cv.matched_from_msg(String(data=text))
    except cv.InvalidMessage as exc:
        assert str(exc).startswith('recorder/matched: ')
    else:
        assert all(isinstance(t, str) and all(isinstance(n, str) for n in ns) for t, ns in out.items())


@pytest.mark.parametrize('text', ['[' * 100_000, 'x' * (cv.MAX_MATCHED_TEXT + 1)], ids=['nesting bomb', 'too long'])
def test_hostile_texts_are_refused_in_one_line(text):
    with pytest.raises(cv.InvalidMessage, match=r'^recorder/matched: not '):
        cv.matched_from_msg(String(data=text))


# --- a writer waits for it ------------------------------------------------------------------------

def test_a_controller_sends_nothing_until_the_recorders_readers_matched_it(ros_domain, tmp_path):
    """A stand-in recorder subscribes to the PD controller's topics (its writers' side of the match
    is complete) but names nobody in ``recorder/matched``: the controller does not subscribe to the
    state and times out naming its topics; once named, it connects."""
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_msgs_py.node import GraphTimeout

    scenario = make_scenario(tmp_path, {'pd_controller': {'startup.expect_recorder': True, 'startup.timeout': 1.0}},
                             drop=('dynamics', 'recorder'))
    with InProcessGraph(scenario) as graph:
        pd = graph.add(PdController)
        stand_in = graph.plain('recorder')
        for name in (topics.WHEELS_CMD, topics.WHEELS_CMD, topics.CONTROLLER_STATUS):   # the dynamics and a recorder
            s = topics.spec(name)
            stand_in.create_subscription(s.msg_type, name, lambda _m: None, s.qos)
        announce = stand_in.create_publisher(String, names.RECORDER_MATCHED, topics.spec(names.RECORDER_MATCHED).qos)
        announce.publish(cv.matched_to_msg({'/wheels/cmd': ['/dynamics']}))
        waited = 'the recorder matching its publishers on /controller/status, /wheels/cmd'
        with pytest.raises(GraphTimeout, match=waited):
            pd.connect(graph.executor)
        assert getattr(pd, 'sub_state', None) is None
        announce.publish(cv.matched_to_msg({'/wheels/cmd': ['/pd_controller', '/dynamics'],
                                            '/controller/status': ['/pd_controller']}))
        pd.connect(graph.executor)
        assert pd.sub_state is not None


def test_without_a_recorder_nothing_is_awaited(ros_domain, tmp_path):
    from adcs_controllers.nodes.pd_controller import PdController

    scenario = make_scenario(tmp_path, {'pd_controller': {'startup.timeout': 1.0}}, drop=('dynamics', 'recorder'))
    with InProcessGraph(scenario) as graph:
        pd = graph.add(PdController)
        stand_in = graph.plain('dynamics')
        s = topics.spec(topics.WHEELS_CMD)
        stand_in.create_subscription(s.msg_type, topics.WHEELS_CMD, lambda _m: None, s.qos)
        pd.connect(graph.executor)
        assert pd._matched_names_sub is None and pd.sub_state is not None


# --- the recorder says it -------------------------------------------------------------------------

def test_the_recorder_names_the_nodes_whose_publishers_its_readers_matched(ros_domain, tmp_path):
    """The publishers of ``state`` and ``wheels/state`` of the interface's type and QoS are named; a
    best-effort publisher of ``dynamics/status`` can never deliver to the recorder's reliable reader:
    it is neither named nor counted against a topic (``can_deliver``; a publisher of another type is
    left out by the same test, but one participant cannot hold two types of one topic)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from adcs_sim.nodes.recorder import RecorderNode

    scenario = make_scenario(tmp_path, {'recorder': {'output': str(tmp_path / 'bag')}})
    heard = []
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        ours = graph.plain('dynamics')
        other = graph.plain('stranger')
        listener = graph.plain('listener')
        ours.create_publisher(topics.spec(topics.STATE).msg_type, topics.STATE, topics.spec(topics.STATE).qos)
        ours.create_publisher(topics.spec(topics.WHEELS_STATE).msg_type, topics.WHEELS_STATE,
                              topics.spec(topics.WHEELS_STATE).qos)
        other.create_publisher(topics.spec(topics.DYNAMICS_STATUS).msg_type, topics.DYNAMICS_STATUS,
                               QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
        listener.create_subscription(String, names.RECORDER_MATCHED,
                                     lambda m: heard.append(cv.matched_from_msg(m)),
                                     topics.spec(names.RECORDER_MATCHED).qos)
        graph.spin_until(lambda: heard and {'/state', '/wheels/state'} <= set(heard[-1]),
                         what='the recorder naming /state and /wheels/state')
        assert heard[-1]['/state'] == {'/dynamics'}
        assert heard[-1]['/wheels/state'] == {'/dynamics'}
        assert '/dynamics/status' not in heard[-1]   # nobody it can match publishes there
        assert '/recorder/matched' not in rec.bag.topics   # start-up plumbing, not recorded
        rec.close()
