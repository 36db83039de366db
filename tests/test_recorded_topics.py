"""The topics the recorder writes from what it records (adcs_msgs_py/recorded_topics.py).

The dynamics node publishes ``/clock``, ``frames/*``, ``error/*`` and ``markers`` only to live
subscribers and sends the recorder its ``dynamics/recording`` config once; the recorder's messages
must be the dynamics node's, byte for byte as a subscriber receives them (zero-padded to 4 bytes),
for every kind of spacecraft (wheels, thrusters, both, an orbit or none, truth/state or state), in
whatever order the sources arrive. The config and the sources are untrusted: anything else is
an InvalidMessage (counted by the recorder), never another exception, and the pending steps are
bounded. In a graph: the bag's /clock and viewer topics equal what a live subscriber received in
the same run.
"""
from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.recorded_topics import ALL, dynamics_messages, padded, visual_messages
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_msgs_py import cdr, names
from adcs_msgs_py.conversions import InvalidMessage
from adcs_msgs_py.recorded_topics import MAX_PENDING, RecordedTopics, config_text, parse_config
from adcs_msgs_py.visual import VisualMessages

SETTINGS = settings(max_examples=300, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
def _topics(visual: VisualMessages) -> list[str]:
    return [t for t in ALL if t in visual.topics]


@pytest.mark.parametrize('wheels, thrusters, orbit', [(True, False, False), (False, True, True),
                                                      (True, True, True), (False, False, True)])
@pytest.mark.parametrize('attitude', [names.STATE, names.TRUTH_STATE])
def test_the_recorded_viewer_messages_are_the_dynamics_nodes_in_any_arrival_order(wheels, thrusters, orbit, attitude):
    visual = visual_messages(wheels, thrusters, orbit)
    sources, expected = dynamics_messages(visual, attitude, 40, np.random.default_rng(7))
    config = parse_config(config_text(None, visual, attitude, _topics(visual)))
    recording = RecordedTopics(config)
    out = [m for topic, data in sources for m in recording.derive(topic, data)]
    assert out == expected   # the dynamics' order, the same bytes
    shuffled = list(sources)   # messages of different topics may be reordered; a topic's never is
    random.Random(3).shuffle(shuffled)
    order = {}
    for topic, data in sources:
        order.setdefault(topic, []).append(data)
    reordered = [(topic, order[topic].pop(0)) for topic, _ in shuffled]
    recording = RecordedTopics(parse_config(config_text(None, visual, attitude, _topics(visual))))
    out = [m for topic, data in reordered for m in recording.derive(topic, data)]
    assert sorted(out) == sorted(expected)


def test_only_the_listed_topics_are_derived_and_only_their_sources_are_needed():
    visual = visual_messages(True, False, False)
    sources, expected = dynamics_messages(visual, names.STATE, 5, np.random.default_rng(1))
    recording = RecordedTopics(parse_config(config_text(None, visual, names.STATE, [names.MARKERS])))
    assert recording.sources == {names.APPLIED_TORQUE, names.WHEELS_STATE} and recording.topics == (names.MARKERS,)
    out = [m for topic, data in sources for m in recording.derive(topic, data)]
    assert out == [m for m in expected if m[0] == names.MARKERS]
    recording = RecordedTopics(parse_config(config_text(None, visual, names.STATE, [names.ERROR_EULER_213])))
    assert recording.sources == {names.STATE}


def test_the_config_round_trips_every_number_exactly():
    visual = visual_messages(True, True, True)
    config = parse_config(config_text('state', visual, names.TRUTH_STATE, ALL)).viewer
    again = VisualMessages(**config.arguments)
    assert again.config == visual.config
    assert np.array_equal(again.target, visual.target) and again.momentum_scale == visual.momentum_scale
    assert config.attitude_topic == names.TRUTH_STATE and config.topics == tuple(ALL)


def test_the_clock_is_the_states_stamps_as_the_dynamics_node_publishes_it():
    recorded = RecordedTopics(parse_config(config_text(names.STATE)))
    assert recorded.topics == (names.CLOCK,) and recorded.sources == {names.STATE}
    state, clock = cdr.StateCodec(), cdr.ClockCodec()
    for t in (0, 1, 999_999_999, 123 * 10 ** 9 + 5):
        data = state.encode(t, [0.0, 0.0, 0.6, 0.8], [0.0, 0.0, 0.0])
        assert recorded.derive(names.STATE, data) == [(names.CLOCK, padded(clock.encode(t)))]
        assert recorded.derive(names.WHEELS_STATE, data) == []
    with pytest.raises(InvalidMessage):   # a stamp simulated time never has
        recorded.derive(names.STATE, bytes([0, 1, 0, 0]) + (-1).to_bytes(4, 'little', signed=True) + bytes(300))
    both = RecordedTopics(parse_config(config_text(names.STATE, visual_messages(False, False, False), names.STATE,
                                                   [names.FRAMES_BODY])))
    out = both.derive(names.STATE, state.encode(7, [0.0, 0.0, 0.6, 0.8], [0.0, 0.0, 0.0]))
    assert [t for t, _ in out] == [names.CLOCK, names.FRAMES_BODY]


VALID = json.loads(config_text(None, visual_messages(True, True, True), names.STATE, ALL))['viewer']
BAD = [
    '', 'null', '[]', '{}', '{"clock": null}', '{"clock": "state", "viewer": null, "x": 1}',
    '{"clock": "/clock", "viewer": null}', '{"clock": 1, "viewer": null}', '{"clock": null, "viewer": []}',
    '{"clock": null, "viewer": {"target": 1}}', 'NaN', '[' * 100_000, '{"a": ' * 5000, 'x' * 70_000,
] + [json.dumps({'clock': None, 'viewer': viewer}) for viewer in (
    {**VALID, 'extra': 1}, {k: v for k, v in VALID.items() if k != 'orbit'},
    {**VALID, 'target': [0.0, 0.0, 0.0, 0.0]}, {**VALID, 'target': [1.0, 0.0, 0.0]},
    {**VALID, 'target': [True, 0.0, 0.0, 1.0]}, {**VALID, 'axis_length': -1.0},
    {**VALID, 'axis_length': 'long'}, {**VALID, 'spin_inertia': [0.01] * 3},
    {**VALID, 'wheel_axes': [[1.0, 0.0]] * 4}, {**VALID, 'wheel_axes': [[1.0, 0.0, 0.0]] * 65},
    {**VALID, 'wheel_axes': None}, {**VALID, 'thruster_directions': None},
    {**VALID, 'orbit': {**VALID['orbit'], 'mu': -1.0}}, {**VALID, 'orbit': {'altitude': 1.0}},
    {**VALID, 'orbit': None},   # frames/orbit listed without an orbit
    {**VALID, 'attitude_topic': '/evil'}, {**VALID, 'topics': ['markers', 'markers']},
    {**VALID, 'topics': ['/clock']}, {**VALID, 'topics': 'markers'},
    {**VALID, 'target': [math.inf, 0.0, 0.0, 1.0]}, {**VALID, 'max_speed': [math.nan] * 4},
    {**VALID, 'axis_length': 10 ** 400}, {**VALID, 'orbit': {**VALID['orbit'], 'raan': -10 ** 309}})]


@pytest.mark.parametrize('text', BAD, ids=range(len(BAD)))
def test_a_config_that_is_not_what_the_dynamics_node_sends_is_an_invalid_message(text):
    with pytest.raises(InvalidMessage, match='dynamics/recording'):
        parse_config(text)


JSON = st.recursive(st.none() | st.booleans() | st.floats(allow_nan=True) | st.integers() | st.text(max_size=8),
                    lambda kids: st.lists(kids, max_size=5) | st.dictionaries(st.text(max_size=8), kids, max_size=5),
                    max_leaves=30)


@SETTINGS
@given(key=st.sampled_from(sorted(VALID)), value=JSON, clock=st.sampled_from([None, 'state']) | JSON)
def test_fuzzed_configs_either_build_the_viewer_or_are_invalid_messages(key, value, clock):
    text = json.dumps({'clock': clock, 'viewer': {**VALID, key: value}})
    try:
        config = parse_config(text)
    except InvalidMessage:
        return
    RecordedTopics(config)   # whatever passes builds


@pytest.mark.slow
@SETTINGS
@given(topic=st.sampled_from([names.STATE, names.WHEELS_STATE, names.APPLIED_TORQUE, names.THRUSTERS_STATE]),
       data=st.binary(max_size=400), cut=st.integers(0, 400))
def test_fuzzed_sources_derive_or_are_invalid_messages(topic, data, cut):
    visual = visual_messages(True, True, True)
    recording = RecordedTopics(parse_config(config_text(None, visual, names.STATE, ALL)))
    good = dict(dynamics_messages(visual, names.STATE, 1, np.random.default_rng(0))[0])[topic]
    for candidate in (data, good[:cut] + data[:len(good) - cut], good[:cut]):
        try:
            recording.derive(topic, candidate)
        except InvalidMessage:
            pass


def test_a_non_unit_or_non_finite_attitude_is_refused_not_renormalised():
    visual = visual_messages(False, False, False)
    recording = RecordedTopics(parse_config(config_text(None, visual, names.STATE, _topics(visual))))
    for q in ([0.0, 0.0, 0.0, 1.0 + 1e-5], [0.0, 0.0, 0.0, math.nan], [0.0, 0.0, math.inf, 1.0]):
        with pytest.raises(InvalidMessage):
            recording.derive(names.STATE, cdr.StateCodec().encode(0, q, [0.0, 0.0, 0.0]))


def test_steps_that_never_complete_are_bounded():
    visual = visual_messages(True, False, False)
    recording = RecordedTopics(parse_config(config_text(None, visual, names.STATE, _topics(visual))))
    codec = cdr.JointStateCodec('x')
    for k in range(10 * MAX_PENDING):   # wheel states whose steps are never integrated
        assert recording.derive(names.WHEELS_STATE, codec.encode(k, list('abcd'), [0.0] * 4, [1.0] * 4, [0.0] * 4)) == []
    assert len(recording.viewer._pending) == MAX_PENDING
    with pytest.raises(InvalidMessage):   # a wheel count that is not the config's
        recording.derive(names.WHEELS_STATE, codec.encode(0, ['a'], [0.0], [1.0], [0.0]))


def test_in_a_graph_the_bag_holds_what_a_live_viewer_received(tmp_path, ros_domain):
    """Dynamics + PD + recorder, and a live viewer subscribed to /clock and every viewer topic:
    the dynamics node publishes them to the viewer only, the recorder writes its own, and both are
    the same."""
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.bag.reader import read_raw
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.recorder import RecorderNode

    n = 30
    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'startup.expect_recorder': True},
        'pd_controller': {'startup.expect_recorder': True}, 'recorder': {'output': str(bag_dir)}})
    live = {t: [] for t in (names.CLOCK, names.FRAMES_BODY, names.ERROR_EIGENAXIS, names.ERROR_EULER_213, names.MARKERS)}
    with InProcessGraph(scenario) as graph:
        viewer = graph.plain('live_viewer')
        from adcs_msgs_py import topics
        subs = [viewer.create_subscription(topics.TOPICS[t].msg_type, t, lambda data, t=t: live[t].append(data),
                                           topics.recorder_qos(topics.TOPICS[t].qos), raw=True) for t in live]
        rec = graph.add(RecorderNode)
        dyn = graph.add(DynamicsNode)
        pubs = {**dyn.pub_visual, names.CLOCK: dyn.pub_clock}
        graph.spin_until(lambda: all(pubs[t].get_subscription_count() >= 1 for t in live))
        pd = graph.add(PdController)
        pd.connect(graph.executor)
        dyn.run(graph.executor)
        graph.spin_until(lambda: all(len(m) == n + (t != names.MARKERS) for t, m in live.items())
                         and rec.bag.topics['/state'].count == n + 1 and '/markers' in rec.bag.topics
                         and rec.bag.topics['/markers'].count == n)
        rec.close()
        del subs
    recorded = {}
    for topic, _, _, data in read_raw(bag_dir):
        recorded.setdefault(topic, []).append(bytes(data))
    for t, messages in live.items():
        assert recorded[t if t.startswith('/') else '/' + t] == [padded(bytes(m)) for m in messages], t
    assert len(recorded['/tf']) == n + 1 and len(recorded['/dynamics/recording']) == 1
    assert rec.rejects.total == 0


def test_the_recorder_still_finds_a_rogue_on_a_topic_it_writes_itself(tmp_path, ros_domain):
    """/clock and frames/body reach the recorder no more (it writes its own), yet a rogue publisher
    on them is found by the recorder's look at the graph and written into the bag as an intrusion
    (the look is repeated until the graph lists the rogue: discovery, not a sleep)."""
    from rosgraph_msgs.msg import Clock

    from adcs_msgs_py import topics
    from adcs_sim.bag.reader import read_raw
    from adcs_sim.nodes.recorder import RecorderNode
    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {'recorder': {
        'output': str(bag_dir), 'startup.publishers': ['/clock=dynamics', 'frames/body=dynamics']}})
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        rogue = graph.plain('rogue')
        rogue.create_publisher(Clock, '/clock', topics.QOS_CLOCK)
        rogue.create_publisher(topics.TOPICS[names.FRAMES_BODY].msg_type, names.FRAMES_BODY, topics.QOS_LOCKSTEP)
        assert '/clock' not in rec.subs and '/frames/body' not in rec.subs

        def found() -> bool:
            rec._sweep()
            return {i.topic for i in rec.vetting.intruders.values()} == {'/clock', '/frames/body'}
        graph.spin_until(found, what='the rogue in the recorder\'s look at the graph')
        rec.close()
    written = [data for topic, _, _, data in read_raw(bag_dir) if topic == '/intrusions']
    assert written and all(b'/rogue' in data for data in written)
