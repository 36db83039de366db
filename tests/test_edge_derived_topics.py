"""Issue #31, "Derived topics lost under load": the recorder derives the viewer topics from complete
steps however far one source topic runs ahead of another, within what the acknowledgement pacing
allows (adcs_msgs_py/recorded_topics.py: MAX_LAG, MAX_PENDING); beyond it a step given up is a
broken invariant, counted and logged, never silent.

Before: 32 incomplete steps were held and the oldest silently forgotten, so under load (one topic
more than 32 steps ahead of another) the bag missed markers (758 of 10 000 steps) and two lockstep
runs did not record identical bags.
"""
from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.recorded_topics import ALL, dynamics_messages, visual_messages
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_msgs_py import cdr, names, topics
from adcs_msgs_py.recorded_topics import MAX_LAG, MAX_PENDING, RecordedTopics, config_text, parse_config

MARKER_INPUTS = (names.WHEELS_STATE, names.APPLIED_TORQUE, names.THRUSTERS_STATE)
SOURCES = (names.STATE, *MARKER_INPUTS)


@cache
def _dynamics(steps: int):
    """What the dynamics node of a spacecraft with wheels, thrusters and an orbit sends for ``steps``
    steps, by topic in its order, and the viewer messages it publishes, by topic."""
    sources, expected = dynamics_messages(visual_messages(True, True, True), names.STATE, steps, np.random.default_rng(31))
    by_topic, viewer = {t: [] for t in SOURCES}, {t: [] for t in ALL}
    for topic, data in sources:
        by_topic[topic].append(data)
    for topic, data in expected:
        viewer[topic].append(data)
    return sources, by_topic, viewer


def _recorded(arrivals, derived=ALL) -> tuple[dict, RecordedTopics]:
    """The viewer messages ``derived`` the recorder writes from ``arrivals`` (topic, data), by topic."""
    recording = RecordedTopics(parse_config(config_text(None, visual_messages(True, True, True), names.STATE, list(derived))))
    out = {t: [] for t in derived}
    for topic, data in arrivals:
        for name, message in recording.derive(topic, data):
            out[name].append(message)
    return out, recording


class TestDerivedTopicsLostUnderLoad:
    """Derived topics lost under load."""

    @pytest.mark.parametrize('ahead', [31, 32, topics.ACK_INTERVAL, MAX_LAG])
    @pytest.mark.parametrize('lead', MARKER_INPUTS)
    def test_one_topic_up_to_the_bound_ahead_loses_no_step(self, lead, ahead):
        """``lead`` delivered ``ahead`` steps before the other sources, up to MAX_LAG (the pacing
        keeps it within topics.ACK_INTERVAL): every step gets its markers, the dynamics node's
        bytes. (Before: 32 incomplete steps held, ``ahead`` 32 lost markers.)"""
        assert topics.ACK_INTERVAL < MAX_LAG <= topics.DEPTH
        steps = MAX_LAG + 4
        sources, by_topic, viewer = _dynamics(steps)
        arrivals = [(lead, data) for data in by_topic[lead][:ahead]]
        following = iter(by_topic[lead][ahead:])
        for topic, data in sources:   # the others in the dynamics' order, lead ``ahead`` steps before them
            if topic == names.STATE:   # the others start a step: lead's step ``ahead`` later
                arrivals += [(lead, step) for step in [next(following, None)] if step is not None]
            if topic != lead:
                arrivals.append((topic, data))
        arrivals += [(lead, data) for data in following]
        assert sorted(arrivals) == sorted(sources)
        out, recording = _recorded(arrivals)
        assert out == viewer, [t for t in ALL if out[t] != viewer[t]]
        assert len(out[names.MARKERS]) == steps and recording.viewer.lost == 0

    @settings(max_examples=20, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(stalls=st.lists(st.lists(st.tuples(st.integers(0, MAX_LAG + 3), st.integers(1, MAX_LAG)), max_size=3),
                           min_size=len(MARKER_INPUTS), max_size=len(MARKER_INPUTS)),
           ranks=st.permutations(range(len(MARKER_INPUTS))))
    def test_any_arrival_order_within_the_bound_gives_the_same_bytes(self, stalls, ranks):
        """Each source of the markers stalls (up to three times, from a drawn step, for a drawn
        number of steps) as DDS may hold back one reader, never more than MAX_LAG steps in all, its
        own order kept: every step gets its markers, the same bytes in the same order as when the
        sources arrive in the dynamics node's order. (The attitude topics are derived from one
        message each: the order cannot change them.)"""
        steps = MAX_LAG + 4
        _, by_topic, viewer = _dynamics(steps)
        keyed = []
        for i, topic in enumerate(MARKER_INPUTS):
            for step, data in enumerate(by_topic[topic]):
                delay = min(MAX_LAG, sum(length for start, length in stalls[i] if start <= step))
                keyed.append(((step + delay, ranks[i], step), (topic, data)))
        arrivals = [m for _, m in sorted(keyed, key=lambda k: k[0])]
        out, recording = _recorded(arrivals, [names.MARKERS])
        assert out[names.MARKERS] == viewer[names.MARKERS] and recording.lost == 0

    def test_beyond_the_bound_a_step_given_up_is_counted_never_silent(self):
        """More incomplete steps than MAX_PENDING (never in a paced run): the one that has waited
        longest is given up, counted in ``lost`` and reported to ``on_lost`` with its stamp; memory
        stays bounded."""
        given_up = []
        config = parse_config(config_text(None, visual_messages(True, False, False), names.STATE, [names.MARKERS]))
        recording = RecordedTopics(config, on_lost=given_up.append)
        codec = cdr.JointStateCodec('x')
        extra = 3
        for k in range(MAX_PENDING + extra):   # wheel states whose steps are never integrated
            recording.derive(names.WHEELS_STATE, codec.encode(k, list('abcd'), [0.0] * 4, [1.0] * 4, [0.0] * 4))
        assert recording.lost == recording.viewer.lost == extra and given_up == list(range(extra))
        assert len(recording.viewer._pending) == MAX_PENDING
        assert RecordedTopics(parse_config(config_text('state'))).lost == 0   # no viewer: nothing to lose

    def test_the_recorder_logs_a_step_given_up_and_writes_the_count_into_the_bag(self, tmp_path, ros_domain,
                                                                                monkeypatch):
        """The recorder's side of the broken invariant: an error naming the step and the bound, and
        ``recorder.viewer_steps_lost`` in the bag's summary (metadata.yaml)."""
        from rclpy.serialization import serialize_message
        from std_msgs.msg import String

        from adcs_sim.nodes.recorder import RecorderNode
        bag_dir = tmp_path / 'bag'
        errors = []
        with InProcessGraph(make_scenario(tmp_path, {'recorder': {'output': str(bag_dir)}})) as graph:
            rec = graph.add(RecorderNode)
            logger = rec.get_logger()
            monkeypatch.setattr(logger, 'error', lambda text, **kw: errors.append(text), raising=False)
            monkeypatch.setattr(rec, 'get_logger', lambda: logger)
            config = config_text(None, visual_messages(True, False, False), names.STATE, [names.MARKERS])
            rec._on_recording_config('/dynamics/recording', serialize_message(String(data=config)))
            assert rec.recorded is not None and rec.recorded.lost == 0
            codec = cdr.JointStateCodec('x')
            for k in range(MAX_PENDING + 1):
                rec._write_own('/wheels/state', names.WHEELS_STATE,
                               codec.encode(k * 10 ** 9, list('abcd'), [0.0] * 4, [1.0] * 4, [0.0] * 4))
            rec.close()
        assert rec.recorded.lost == 1
        assert len(errors) == 1 and 't = 0 s' in errors[0] and str(MAX_PENDING) in errors[0]
        summary = yaml.safe_load((bag_dir / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        assert summary['custom_data'] == {'recorder.viewer_steps_lost': '1'}

