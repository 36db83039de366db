"""The viewer topics in a committed bag (issue #21 items 1-2): bags/eseo_backstepping_slew.

The recording carries the body and orbit frames (``frames/*``, geometry_msgs/TransformStamped, and
``/tf``, tf2_msgs/TFMessage, written by the recorder), the markers (visualization_msgs/MarkerArray)
and the error series, with the standard ``ros2msg`` schemas: read back here by mcap_ros2 and by
rosbags, and checked against the physics the bag also holds (the state, the wheels, the
thrusters, the scenario's orbit and target) and against the offline analysis. Its layouts
(bags/eseo_backstepping_slew/layouts/) parse and name only topics and fields the bag has.
"""
from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from collections import defaultdict

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from numpy.testing import assert_allclose
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Nodetype
from support.paths import ROOT

from adcs_core.orbit import CircularOrbit, orbit_frame_attitude
from adcs_msgs_py.topics import QOS_CLOCK
from adcs_sim.app.analysis.metrics import RunData, attitude_errors
from adcs_sim.app.analysis.analyze import main as analyze
from adcs_sim.app.graph.layouts import (
    DIAGNOSTIC_ARRAY,
    JOINT_STATE,
    foxglove_layout,
    load_layout,
    plotjuggler_layout,
)
from adcs_sim.bag.storage import typestore
from adcs_sim.bag.writer import BagWriter, qos_dicts

BAG = ROOT / 'bags' / 'eseo_backstepping_slew'
ADD, DELETE = 0, 2   # visualization_msgs/Marker actions
TYPES = {'/tf': 'tf2_msgs/msg/TFMessage', '/frames/body': 'geometry_msgs/msg/TransformStamped',
         '/frames/orbit': 'geometry_msgs/msg/TransformStamped', '/markers': 'visualization_msgs/msg/MarkerArray',
         '/markers/static': 'visualization_msgs/msg/MarkerArray',
         '/error/eigenaxis': 'geometry_msgs/msg/Vector3Stamped', '/error/euler_213': 'geometry_msgs/msg/Vector3Stamped'}


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@pytest.fixture(scope='module')
def decoded():
    """{topic: [(stamp ns, message)]} of the viewer topics and the state, decoded by mcap_ros2."""
    out = defaultdict(list)
    with open(BAG / 'bag' / 'bag_0.mcap', 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {ch.topic: summary.schemas[ch.schema_id] for ch in summary.channels.values()}
        for topic, type_name in TYPES.items():
            assert schemas[topic].name == type_name and schemas[topic].encoding == 'ros2msg', topic
        for _, channel, message, msg in reader.iter_decoded_messages(topics=[*TYPES, '/state']):
            out[channel.topic].append((message.log_time, msg))
    return out


@pytest.fixture(scope='module')
def run() -> RunData:
    return RunData.from_bag(BAG / 'bag')


def test_rosbags_reads_the_viewer_topics_with_their_standard_types():
    with AnyReader([BAG / 'bag']) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert {t: types.get(t) for t in TYPES} == TYPES
        conns = [c for c in reader.connections if c.topic == '/tf']
        first = next(reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns))
    assert first.transforms[0].header.frame_id == 'inertial' and first.transforms[0].child_frame_id == 'body'


@pytest.mark.slow
def test_tf_is_the_frames_and_the_body_frame_is_the_state(decoded, run):
    body = {_ns(m.header.stamp): m for _, m in decoded['/frames/body']}
    orbit = {_ns(m.header.stamp): m for _, m in decoded['/frames/orbit']}
    assert len(body) == len(orbit) == len(run.t) == 3001
    tf = defaultdict(dict)
    for log_time, msg in decoded['/tf']:
        (transform,) = msg.transforms
        assert log_time == _ns(transform.header.stamp)
        tf[transform.child_frame_id][log_time] = transform
    for child, frames in (('body', body), ('orbit', orbit)):
        assert tf[child].keys() == frames.keys()
        for t, m in frames.items():
            r, s = tf[child][t].transform.rotation, m.transform.rotation
            assert (r.x, r.y, r.z, r.w) == (s.x, s.y, s.z, s.w)
    q = np.array([[m.transform.rotation.x, m.transform.rotation.y, m.transform.rotation.z, m.transform.rotation.w]
                  for _, m in sorted(body.items())])
    assert np.array_equal(q, run.q)   # the true attitude (no noise here: = state), bit for bit
    o = run.scenario['dynamics']['ros__parameters']['orbit']
    circ = CircularOrbit(o['altitude'], math.radians(o['inclination_deg']), math.radians(o['raan_deg']),
                         math.radians(o['arg_latitude_deg']))
    for t, m in list(orbit.items())[::500]:
        r = m.transform.rotation
        assert_allclose([r.x, r.y, r.z, r.w], orbit_frame_attitude(circ, t * 1e-9), atol=1e-12)


@pytest.mark.slow
def test_error_topics_are_the_analysis_errors(decoded, run):
    _, eigen, euler = attitude_errors(run)   # deg; Euler in sequence order y, x, z
    e = np.array([m.vector.x for _, m in decoded['/error/eigenaxis']])
    xyz = np.array([[m.vector.x, m.vector.y, m.vector.z] for _, m in decoded['/error/euler_213']])
    assert_allclose(e, eigen, rtol=0, atol=1e-9)
    assert_allclose(xyz, euler[:, [1, 0, 2]], rtol=0, atol=1e-9)
    assert e[0] == pytest.approx(135.68, abs=0.01)   # seed 002's slew (test_seed002_reproduction)


def _by_ns(markers) -> dict:
    return {(m.ns, m.id): m for m in markers}


@pytest.mark.slow
def test_markers_show_target_wheel_momentum_and_the_firing_thrusters(decoded, run):
    (stamp, static), = decoded['/markers/static']   # once, latched, at t = 0
    m = _by_ns(static.markers)
    assert stamp == 0 and set(m) == {('body', 0), *(('body_axes', i) for i in range(3)),
                                     *(('target_axes', i) for i in range(3))}
    assert all(mk.header.frame_id == 'body' and mk.frame_locked for (ns, _), mk in m.items() if ns != 'target_axes')
    for i in range(3):
        o = m[('target_axes', i)].pose.orientation
        assert m[('target_axes', i)].header.frame_id == 'inertial'
        assert_allclose([o.x, o.y, o.z, o.w], run.q_ref, atol=1e-15)   # the analysis' target
    arrays = decoded['/markers']
    assert len(arrays) == len(run.t_thrusters) == 3000
    dyn = run.scenario['dynamics']['ros__parameters']
    max_speed = dyn['wheels']['max_speed'][0]
    ends = {}   # thruster -> its plume's segment (body axes)
    for i, (p, d) in enumerate(zip(np.reshape(dyn['thrusters']['positions'], (4, 3)),
                                   np.reshape(dyn['thrusters']['directions'], (4, 3)))):
        ends[i] = np.concatenate([p, p - 0.35 * d / np.linalg.norm(d)])
    firing = quiet = 0
    for k, (stamp, msg) in enumerate(arrays):
        m = _by_ns(msg.markers)
        assert stamp == round(run.t_thrusters[k] * 1e9) and set(m) == {('wheel_momentum', 0), ('thrusters', 0)}
        head = m[('wheel_momentum', 0)].points[1]
        # h = Js * speed along the pitch axis (y), drawn at 1 m per the wheel's capacity Js * max_speed
        assert_allclose([head.x, head.y, head.z], [0.0, run.wheel_speed[k, 0] / max_speed, 0.0], atol=1e-12)
        on = np.flatnonzero(run.thruster_on_time[k] > 0)
        points = np.array([[q.x, q.y, q.z] for q in m[('thrusters', 0)].points]).reshape(-1, 6)
        assert_allclose(points, np.array([ends[i] for i in on]).reshape(-1, 6), atol=1e-12)
        # no firing: a DELETE of the plume (a LINE_LIST without points is an error to viewers)
        assert m[('thrusters', 0)].action == (ADD if len(on) else DELETE), k
        quiet += not len(on)
        firing += len(on)
    assert firing == 608   # seed 002's firings over the recording (test_seed002_reproduction)
    assert quiet == 2710   # steps without a firing: a DELETE each


# --- layouts -------------------------------------------------------------------------------------

TOKENS = re.compile(r'\.(\w+)|\[(\d+|:)\]|\{(\w+)=="([^"]*)"\}')


def _field(type_name: str, name: str):
    fields = dict(typestore().fielddefs[type_name][1])
    assert name in fields, f'{type_name} has no field {name!r}'
    return fields[name]


def _resolve_foxglove(path: str, types: dict, run: RunData) -> None:
    """A Foxglove message path names a topic of the bag and fields of its type (indices within
    the joints, filters on fields that exist and match a recorded status)."""
    topic = path[:min(i for i in (path.find('.'), len(path)) if i >= 0)]
    assert topic in types, f'{path}: no topic {topic} in the bag'
    node = (Nodetype.NAME, types[topic])
    rest = path[len(topic):]
    assert ''.join(m[0] for m in TOKENS.finditer(rest)) == rest, path
    for m in TOKENS.finditer(rest):
        name, index, fkey, fvalue = m.groups()
        if name:
            assert node[0] == Nodetype.NAME, f'{path}: {name} of a non-message'
            node = _field(node[1], name)
        elif index:
            assert node[0] in (Nodetype.SEQUENCE, Nodetype.ARRAY), f'{path}: [{index}] of a non-array'
            if index != ':':
                assert int(index) < max(len(run.wheel_names), len(run.thruster_names)), path
            node = node[1][0]
        else:
            _field(node[1], fkey)
            known = {n for _, n, _ in run.controller_status} | {k for _, _, v in run.controller_status for k in v}
            assert fvalue in known, f'{path}: no status or key {fvalue!r} recorded'


def _resolve_plotjuggler(name: str, types: dict, run: RunData) -> None:
    """A PlotJuggler series name = a bag topic + the fields PlotJuggler's ROS 2 parser names (every
    field by its full path, /state/twist/twist/angular/x; joints and status values by name)."""
    topic = max((t for t in types if name.startswith(t + '/')), key=len)
    parts = name[len(topic) + 1:].split('/')
    type_name = types[topic]
    if type_name == JOINT_STATE:
        joint, field_name = parts
        assert joint in run.wheel_names + run.thruster_names and field_name in ('position', 'velocity', 'effort')
        return
    if type_name == DIAGNOSTIC_ARRAY:
        status, key = parts
        assert any(n == status and key in v for _, n, v in run.controller_status), name
        return
    node = (Nodetype.NAME, type_name)
    for part in parts:
        node = _field(node[1], part)
    assert node[0] == Nodetype.BASE, name


@pytest.mark.slow
def test_committed_layouts_are_current_and_name_only_what_the_bag_has(run, tmp_path):
    with AnyReader([BAG / 'bag']) as reader:
        types = {c.topic: c.msgtype for c in reader.connections if c.msgcount}
    assert analyze([str(BAG / 'bag'), '--foxglove-layout', str(tmp_path / 'f.json'),
                    '--plotjuggler-layout', str(tmp_path / 'p.xml')]) == 0
    committed = BAG / 'layouts'
    assert (tmp_path / 'f.json').read_text() == (committed / 'foxglove.json').read_text()
    assert (tmp_path / 'p.xml').read_text() == (committed / 'plotjuggler.xml').read_text()
    fox = json.loads((committed / 'foxglove.json').read_text())
    panels = fox['configById']
    assert {k.split('!')[0] for k in panels} == {'3D', 'Plot', 'StateTransitions'}
    paths = [p['value'] for c in panels.values() for p in c.get('paths', [])]
    # eigenaxis 1, Euler 3, rates 3, the pitch wheel's speed and torque 2, applied torque 3, four
    # thrusters' on-times 4, the backstepping controller's mode 1
    assert len(paths) == 17
    for path in paths:
        _resolve_foxglove(path, types, run)
    scene = panels['3D!adcsscene']
    assert set(scene['topics']) == {'/markers', '/markers/static'} and scene['followTf'] == 'inertial'
    assert {'frame:body', 'frame:orbit'} <= set(scene['transforms'])
    leaves, todo = [], [fox['layout']]
    while todo:
        node = todo.pop()
        (leaves.append(node) if isinstance(node, str) else todo.extend([node['first'], node['second']]))
    assert sorted(leaves) == sorted(panels)   # every panel placed once
    curves = [c.get('name') for c in ET.parse(committed / 'plotjuggler.xml').getroot().iter('curve')]
    assert len(curves) == len(paths)
    for name in curves:
        _resolve_plotjuggler(name, types, run)


def test_a_bag_from_before_the_viewer_topics_gets_a_layout_without_the_3d_view(capsys):
    layout = load_layout(ROOT / 'bags' / 'microsat_pd_slew' / 'bag')
    assert not layout.scene_topics and any('3D view' in w for w in layout.left_out)
    fox = foxglove_layout(layout)
    assert not any(k.startswith('3D!') for k in fox['configById'])
    assert plotjuggler_layout(layout).getroot().find('tabbed_widget') is not None


def _one_line_error(argv, capsys, status=1) -> str:
    assert analyze(argv) == status
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err, err
    return err


def test_layout_writers_refuse_what_they_cannot_use_in_one_line(tmp_path, capsys):
    out = ['--foxglove-layout', str(tmp_path / 'f.json')]
    (tmp_path / 'junk.mcap').write_bytes(b'\x89MCAP0\r\n' + bytes(range(256)) * 4)
    _one_line_error([str(tmp_path / 'junk.mcap'), *out], capsys)
    _one_line_error([str(tmp_path / 'missing'), *out], capsys)
    clock_only = BagWriter(tmp_path / 'clock_only')
    clock_only.add_topic('/clock', 'rosgraph_msgs/msg/Clock', qos_dicts(QOS_CLOCK))
    clock_only.write('/clock', bytes([0, 1, 0, 0]) + bytes(8))
    clock_only.close()
    assert 'state' in _one_line_error([str(tmp_path / 'clock_only'), *out], capsys)
    bag = str(BAG / 'bag')
    _one_line_error([bag, bag, *out], capsys, status=2)
    assert 'cannot write' in _one_line_error([bag, '--plotjuggler-layout', str(tmp_path)], capsys)
    assert not (tmp_path / 'f.json').exists()


def test_a_hostile_status_name_stays_out_of_the_layouts_paths():
    """A foreign bag's status names go into Foxglove path filters: only ROS node names are used."""
    from types import SimpleNamespace

    from adcs_sim.app.graph.layouts import layout_for
    data = RunData(t=np.zeros(1), q=np.array([[0.0, 0.0, 0.0, 1.0]]), w=np.zeros((1, 3)))
    data.topic_counts = {'state': 1, 'controller/status': 2}
    data.controller_status = [(0.0, 'x"}.evil{key=="', {'mode': 'a'}), (0.0, 'pd_controller', {'mode': 'b'})]
    layout = layout_for(SimpleNamespace(name='foreign', data=data), {'/state': 'nav_msgs/msg/Odometry'})
    assert [s.path for s in layout.modes] == [('status', 'pd_controller', 'mode')]
    assert not layout.scene_topics and 'evil' not in json.dumps(foxglove_layout(layout))


def test_a_step_without_firing_deletes_the_plume_instead_of_an_empty_line_list():
    """Lichtblick flags a LINE_LIST without points on its topic; a DELETE of the same marker clears
    the last plume instead. The CDR bytes the dynamics node and the recorder send say the same."""
    from rclpy.serialization import deserialize_message
    from visualization_msgs.msg import MarkerArray

    from adcs_msgs_py.visual import VisualMessages
    visual = VisualMessages([0.0, 0.0, 0.0, 1.0], 1.0, np.eye(3), [0.01] * 3, [100.0] * 3,
                            [[1.0, 0.0, 0.0]] * 2, [[0.0, 1.0, 0.0]] * 2)
    for on_time, action, points in (([0.0, 0.0], DELETE, 0), ([0.1, 0.0], ADD, 2), ([0.0, 0.0], DELETE, 0),
                                    ([0.1, 0.1], ADD, 4)):
        data = visual.marker_array_cdr(5, [1.0, 2.0, 3.0], on_time)
        plume = _by_ns(deserialize_message(bytes(data), MarkerArray).markers)[('thrusters', 0)]
        assert (plume.action, len(plume.points)) == (action, points), on_time
        assert plume.type == plume.LINE_LIST and plume.points or plume.action == DELETE
