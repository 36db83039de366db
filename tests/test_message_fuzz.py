"""Every subscribed topic of every node, fuzzed (issue 17 item 1): whatever the message, it is
applied or rejected and counted; nothing escapes a callback; the run goes on.

The nodes are real (in this process, on leased loopback domains), their subscriptions' callbacks
are the ones the executor calls (``sub.callback``: the validation boundary of
:meth:`adcs_msgs_py.node.AdcsNode.subscription`), fed with hypothesis-generated messages: NaN,
Inf, huge values, negative and out-of-range stamps, wrong lengths, unknown and repeated names,
unknown fault modes, garbage key/values, and (for the recorder's raw subscriptions) arbitrary
bytes. For each message, when the interface's conversion refuses it the node's rejection count
grows by one. Then the fuzzed graph runs its lockstep loop to the end (the dynamics node, the PD
controller, the recorder and the fault injector of the PD slew), the plant state is finite and the
recorder closes a readable bag.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TransformStamped, Vector3Stamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from support.ros_graph import InProcessGraph, refused
from support.scenarios import make_scenario

from adcs_msgs_py import conversions as cv
from adcs_sim.app.graph.domains import DomainLease
from adcs_sim.bag.tf import tf_message_cdr

FUZZ = settings(derandomize=True, max_examples=40, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

WHEELS = ['rw_x', 'rw_y', 'rw_z']
_INJECTOR_CLOCK: dict = {}   # the fault injector's /clock subscription as it started (graphs)
ANY_FLOAT = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                      st.sampled_from([0.0, 1e308, -1e308, 1e-320, math.nan, math.inf]))
SEC = st.one_of(st.integers(-2**31, 2**31 - 1), st.sampled_from([-1, 0, 1, 2**31 - 1]))
NANOSEC = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from([0, 999_999_999, 10**9]))
NAMES = st.lists(st.one_of(st.sampled_from(WHEELS + ['rw_q', '', 'thr_1']), st.text(max_size=4)), max_size=5)
FLOATS = st.lists(ANY_FLOAT, max_size=5)


def _stamp(msg, sec, nanosec):
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return msg


@st.composite
def states(draw):
    msg = _stamp(Odometry(), draw(SEC), draw(NANOSEC))
    o = msg.pose.pose.orientation
    q = draw(st.one_of(st.lists(ANY_FLOAT, min_size=4, max_size=4), st.just([0.0, 0.0, 0.0, 1.0])))
    o.x, o.y, o.z, o.w = q
    a = msg.twist.twist.angular
    a.x, a.y, a.z = draw(st.lists(ANY_FLOAT, min_size=3, max_size=3))
    return msg


@st.composite
def joint_states(draw):
    return _stamp(JointState(name=draw(NAMES), position=draw(FLOATS), velocity=draw(FLOATS),
                             effort=draw(FLOATS)), draw(SEC), draw(NANOSEC))


@st.composite
def vectors(draw):
    msg = _stamp(Vector3Stamped(), draw(SEC), draw(NANOSEC))
    msg.vector.x, msg.vector.y, msg.vector.z = draw(st.lists(ANY_FLOAT, min_size=3, max_size=3))
    return msg


TEXT_NUMBER = st.one_of(ANY_FLOAT.map(repr), st.integers(-5, 200).map(str), st.text(max_size=4))


@st.composite
def fault_arrays(draw):
    statuses = []
    for _ in range(draw(st.integers(0, 4))):
        keys = draw(st.lists(st.sampled_from(['mode', 'value', 'time', 'event', 'events']), unique=True))
        values = {'mode': st.sampled_from(['failed', 'stuck', 'degraded', 'bias', 'nominal', 'recovered', 'bogus']),
                  'value': TEXT_NUMBER, 'time': TEXT_NUMBER, 'event': TEXT_NUMBER, 'events': TEXT_NUMBER}
        statuses.append(DiagnosticStatus(
            name=draw(st.sampled_from(WHEELS + ['rw_q', ''])), message=draw(st.text(max_size=6)),
            values=[KeyValue(key=k, value=draw(values[k])) for k in keys]))
    return _stamp(DiagnosticArray(status=statuses), draw(SEC), draw(NANOSEC))


@st.composite
def clocks(draw):
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = draw(SEC), draw(NANOSEC)
    return msg


def feed(node, sub, msg, convert=None) -> None:
    """``msg`` through ``sub``'s callback (what the executor calls: its serialized bytes for a raw
    subscription, adcs_msgs_py.cdr); no exception may escape, and a message the interface refuses
    is counted (exactly once)."""
    before = node.rejects.total
    sub.callback(serialize_message(msg) if sub.raw and not isinstance(msg, bytes) else msg, {})
    if convert is not None and refused(convert):
        assert node.rejects.total == before + 1, (sub.topic_name, msg)


@pytest.fixture(scope='module')
def graphs(tmp_path_factory):
    """The PD slew graph (recorder, fault injector, dynamics, PD controller) and seed 002's
    backstepping controller, each in this process on its own leased domain."""
    from adcs_controllers.nodes.backstepping_controller import BacksteppingController
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.fault_injector import FaultInjectorNode
    from adcs_sim.nodes.recorder import RecorderNode
    tmp = tmp_path_factory.mktemp('fuzz')
    steps = 5
    pd = make_scenario(tmp, {'dynamics': {'duration': float(steps), 'startup.expect_recorder': True},
                             'pd_controller': {'startup.expect_recorder': True},
                             'recorder': {'output': str(tmp / 'bag')},
                             'fault_injector': {'wheels.names': WHEELS, 'schedule.time': [2.0],
                                                'schedule.actuator': ['rw_y'], 'schedule.mode': ['failed']}})
    eseo = make_scenario(tmp, base='eseo_backstepping_slew.yaml')
    leases = [DomainLease(100, 232), DomainLease(100, 232)]
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        mp.setenv('ROS_DOMAIN_ID', str(leases[0].domain_id))
        with InProcessGraph(pd) as a:
            mp.setenv('ROS_DOMAIN_ID', str(leases[1].domain_id))
            with InProcessGraph(eseo) as b:
                nodes = {'recorder': a.add(RecorderNode), 'fault_injector': a.add(FaultInjectorNode),
                         'dynamics': a.add(DynamicsNode), 'pd_controller': a.add(PdController),
                         'backstepping_controller': b.add(BacksteppingController)}
                # the injector's /clock subscription as it started, kept: a run to the end drops it
                _INJECTOR_CLOCK['sub'] = nodes['fault_injector'].sub_clock
                nodes['pd_controller'].wait_for_faults(a.executor)
                nodes['pd_controller'].connect(a.executor)
                b.add(DynamicsNode)   # what the backstepping controller's start-up waits for
                nodes['backstepping_controller'].connect(b.executor)
                yield a, nodes, steps, tmp / 'bag'
    for lease in leases:
        lease.release()


@pytest.mark.graph
@FUZZ
@given(wheel_cmd=joint_states(), torque=vectors(), faults=fault_arrays())
def test_dynamics_node_survives_any_command_or_fault(graphs, wheel_cmd, torque, faults):
    _, nodes, _, _ = graphs
    dyn = nodes['dynamics']
    feed(dyn, dyn.subs['wheels/cmd'], wheel_cmd, lambda: cv.wheel_cmd_from_msg(wheel_cmd, dyn.wheel_index))
    feed(dyn, dyn.sub_faults, faults, lambda: cv.faults_from_msg(faults, dyn.wheel_index))
    assert np.all(np.isfinite(dyn.commands['wheels'].value))


@FUZZ
@given(state=states(), faults=fault_arrays())
def test_pd_controller_survives_any_state_or_fault(graphs, state, faults):
    _, nodes, _, _ = graphs
    pd = nodes['pd_controller']
    feed(pd, pd.sub_state, state, lambda: cv.state_from_msg(state))
    feed(pd, pd.sub_faults, faults, lambda: cv.faults_from_msg(faults, pd.wheel_index))


@FUZZ
@given(state=states(), wheels=joint_states(), faults=fault_arrays())
def test_backstepping_controller_survives_any_state_wheel_state_or_fault(graphs, state, wheels, faults):
    _, nodes, _, _ = graphs
    ctrl = nodes['backstepping_controller']
    known = {n: i for i, n in enumerate(ctrl.wheel_names)}
    feed(ctrl, ctrl.sub_state, state, lambda: cv.state_from_msg(state))
    feed(ctrl, ctrl.sub_wheels, wheels, lambda: cv.wheel_speeds_from_msg(wheels, ctrl.wheel_names))
    feed(ctrl, ctrl.sub_faults, faults, lambda: cv.faults_from_msg(faults, known))


@FUZZ
@given(clock=clocks())
def test_fault_injector_survives_any_clock(graphs, clock):
    """Any clock, also once a fuzzed clock (or the run to the end) past the last event made the
    injector drop its /clock subscription (the subscription object it started with is kept by the
    fixture: its callback must still take anything, and the drop happens exactly when every event
    is announced)."""
    _, nodes, _, _ = graphs
    inj = nodes['fault_injector']
    sub = _INJECTOR_CLOCK['sub']
    assert sub is not None, 'the injector of a two-snapshot schedule follows /clock from the start'
    feed(inj, sub, clock, lambda: cv.clock_from_msg(clock))
    assert (inj.sub_clock is None) == (inj._logged + 1 == len(inj.schedule))


@FUZZ
@given(msg=st.one_of(states(), joint_states(), vectors(), fault_arrays(), clocks()),
       garbage=st.binary(max_size=40))
def test_recorder_survives_any_bytes_and_keeps_recording(graphs, msg, garbage):
    _, nodes, _, _ = graphs
    rec = nodes['recorder']
    # (a clock message on a stamped topic: the recorder writes /clock itself, from the state)
    topic = {Odometry: '/state', JointState: '/wheels/cmd', Vector3Stamped: '/torque_cmd',
             DiagnosticArray: '/dynamics/status', Clock: '/controller/status'}[type(msg)]
    data = serialize_message(msg)
    count = rec.bag.topics[topic].count
    feed(rec, rec.subs[topic], data, lambda: cv.checked_cdr_stamp(topic, data))
    feed(rec, rec.subs[topic], garbage, lambda: cv.checked_cdr_stamp(topic, garbage))
    written = rec.bag.topics[topic].count - count
    assert written == (not refused(lambda: cv.checked_cdr_stamp(topic, data))) + \
        (not refused(lambda: cv.checked_cdr_stamp(topic, garbage)))


FRAME_IDS = st.one_of(st.sampled_from(['inertial', 'body', 'orbit', '', 'x' * 300, 'bad\nid']), st.text(max_size=6))


@st.composite
def transforms(draw):
    msg = _stamp(TransformStamped(), draw(SEC), draw(NANOSEC))
    msg.header.frame_id, msg.child_frame_id = draw(FRAME_IDS), draw(FRAME_IDS)
    t = msg.transform.translation
    t.x, t.y, t.z = draw(st.one_of(st.lists(ANY_FLOAT, min_size=3, max_size=3), st.just([0.0] * 3)))
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = draw(st.one_of(st.lists(ANY_FLOAT, min_size=4, max_size=4), st.just([0.0, 0.0, 0.6, 0.8])))
    return msg


def _tf(topic: str, data: bytes) -> bytes:
    cv.checked_cdr_stamp(topic, data)
    try:
        return tf_message_cdr(data)
    except ValueError as exc:
        raise cv.InvalidMessage(str(exc)) from None


@FUZZ
@given(msg=transforms(), garbage=st.binary(max_size=60))
def test_recorder_writes_tf_only_from_valid_transforms(graphs, msg, garbage):
    """A frames/body message (the recorder writes them itself since issue 18: ``_write_tf`` of
    every one it writes) goes on /tf only when it is a well-formed transform (frame ids, finite,
    unit rotation), else it is counted, once."""
    _, nodes, _, _ = graphs
    rec = nodes['recorder']
    topic = '/frames/body'
    for data in (serialize_message(msg), garbage):
        tf_before = rec.bag.topics['/tf'].count if '/tf' in rec.bag.topics else 0
        before = rec.rejects.total
        if refused(lambda d=data: cv.checked_cdr_stamp(topic, d)):
            continue   # the recorder writes no frame without a valid stamp
        rec._write_tf(topic, data)
        tf_after = rec.bag.topics['/tf'].count if '/tf' in rec.bag.topics else 0
        bad = refused(lambda d=data: _tf(topic, d))
        assert tf_after - tf_before == (not bad) and rec.rejects.total == before + bad


@FUZZ
@given(text=st.one_of(st.text(max_size=200), st.binary(max_size=200).map(lambda b: b.decode('latin-1'))))
def test_recorder_counts_a_hostile_viewer_config_and_keeps_recording(graphs, text):
    """dynamics/recording with anything in it: recorded, and counted when it is not a config the
    recorder can build the viewer topics from; nothing escapes its callback."""
    from std_msgs.msg import String
    _, nodes, _, _ = graphs
    rec = nodes['recorder']
    before, recorded = rec.rejects.total, rec.recorded
    feed(rec, rec.subs['/dynamics/recording'], String(data=text))
    assert rec.recorded is recorded or rec.rejects.total == before


def test_the_fuzzed_graph_runs_to_the_end(graphs):
    """After all of the above, the lockstep loop of the fuzzed nodes completes and the recorder
    closes a readable bag (its rejections in the bag's metadata). Selected alone, the nodes are
    first given one message each that they refuse, so that they too have rejected something."""
    from adcs_sim.app.analysis.metrics import RunData
    graph, nodes, steps, bag_dir = graphs
    dyn, pd, rec = nodes['dynamics'], nodes['pd_controller'], nodes['recorder']
    state, cmd = _stamp(Odometry(), -1, 0), _stamp(JointState(name=WHEELS, effort=[0.0] * 3), -1, 0)
    for node, sub, msg, convert in (
            (pd, pd.sub_state, state, lambda: cv.state_from_msg(state)),
            (dyn, dyn.subs['wheels/cmd'], cmd, lambda: cv.wheel_cmd_from_msg(cmd, dyn.wheel_index)),
            (rec, rec.subs['/state'], b'\x00', lambda: cv.checked_cdr_stamp('/state', b'\x00'))):
        assert refused(convert)   # negative stamps; one byte, no CDR message
        feed(node, sub, msg, convert)
    assert dyn.rejects.total > 0 and pd.rejects.total > 0 and rec.rejects.total > 0
    dyn.step_ns = 0
    dyn.run(graph.executor)
    assert dyn.step_ns == steps * dyn.period_ns
    counts = rec.bag.topics
    graph.spin_until(lambda: counts['/dynamics/status'].count >= 2 and counts['/state'].count >= steps + 1)
    rec.close()
    assert np.all(np.isfinite(dyn.x))   # the plant: only validated commands reached it
    # the bag reads back (it also holds the fuzzed messages the recorder was given and accepted:
    # the recorder records what comes with a valid stamp, it does not judge content)
    run = RunData.from_bag(bag_dir)
    assert len(run.t) >= steps + 1
    assert 'recorder.rejected_messages' in (bag_dir / 'metadata.yaml').read_text()
