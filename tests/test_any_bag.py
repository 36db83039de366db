"""RunData.from_bag on any rosbag2 bag with the graph's message types, not only our recorder's.

Bags are written here by independent writers (rosbags' rosbag2 Writer, MCAP and sqlite3; the mcap
library with other chunking/compression/index choices) and by adcs_sim.bag.writer.BagWriter, from
synthetic messages serialised by rosbags, with answers known in closed form. The reference
recording in bags/ stands for a real run (and, cut short, for a recorder that was killed). No ROS.
"""
from __future__ import annotations

import json
import math
import shutil
import sys

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin
from scipy.spatial.transform import Rotation
from support.bags import (
    DIAG,
    ODOM,
    REFERENCE,
    SYN,
    TAU,
    V3S,
    WHEELS,
    WRITERS,
    N,
    T,
    U,
    diag,
    header,
    odom,
    ser,
    truncated_copy,
    vec3,
    write,
    write_ours,
    write_rosbags,
)
from support.paths import BAGS, ROOT

from adcs_sim.app.analysis.metrics import REPORTED_TOPICS, RunData, jsonable_metrics, run_metrics
from adcs_sim.bag import columns
from adcs_sim.bag.batches import TopicBatch
from adcs_sim.bag.columns import _diagnostic_array, decode_batch, decode_diagnostics
from adcs_sim.bag.reader import read_messages, read_metadata, read_raw
from adcs_sim.bag.storage import MCAP_MAGIC


def one_line(exc) -> str:
    text = str(exc.value)
    assert text and '\n' not in text, repr(text)
    return text


# --- any writer, same numbers ----------------------------------------------------------------

@pytest.mark.parametrize('kind', WRITERS)
def test_independent_writers_give_the_synthetic_run(tmp_path, kind):
    messages = SYN.messages()
    bag = write(kind, tmp_path / 'bag', messages)
    run = RunData.from_bag(bag)
    np.testing.assert_array_equal(run.t, SYN.t)
    np.testing.assert_array_equal(run.q, SYN.q)
    np.testing.assert_array_equal(run.w, SYN.w)
    np.testing.assert_array_equal(run.t_u, SYN.t[:-1])
    np.testing.assert_array_equal(run.u, SYN.u)
    np.testing.assert_array_equal(run.t_wheels, SYN.t)
    assert run.wheel_names == list(WHEELS)
    np.testing.assert_array_equal(run.wheel_speed, SYN.speed)
    np.testing.assert_array_equal(run.wheel_torque, SYN.torque)
    assert run.missed_steps == 2
    assert not run.truncated
    assert run.message_count == len(messages)
    assert run.missing_topics == ['controller/status']
    assert run.topic_counts == {'state': N, 'actuators/torque': N - 1, 'wheels/state': N, 'dynamics/status': 2}
    m = run_metrics(run)
    assert m['settling_eigenaxis_0.5deg_s'] == pytest.approx(SYN.settling_eigen, abs=1 / (8 * TAU) * 1.01)
    assert m['integrated_torque_Nms'] == pytest.approx(SYN.integrated, rel=1e-12)
    assert m['control_energy_N2m2s'] == pytest.approx(SYN.energy, rel=1e-12)
    assert m['peak_torque_Nm'] == np.abs(U).tolist()
    assert m['peak_wheel_speed_rad_s'] == 42.0
    assert m['missed_steps'] == 2 and m['duration_s'] == 300.0


def test_sqlite3_bag_through_read_raw_and_by_its_db3_file(tmp_path):
    messages = SYN.messages(('state', 'torque'))
    bag = write_rosbags(tmp_path / 'bag', messages, StoragePlugin.SQLITE3)
    raw = list(read_raw(bag))
    assert sorted((t, ty, ts, d) for t, ty, ts, d in raw) == sorted(messages)
    assert read_metadata(bag) == {}
    db3 = next(bag.glob('*.db3'))
    np.testing.assert_array_equal(RunData.from_bag(db3).u, SYN.u)


# --- a real recording ------------------------------------------------------------------------

RECORDINGS = sorted(p.parent for p in BAGS.glob('*/metrics.json') if not p.parent.name.endswith('.tmp'))


def test_reference_recordings_exist_for_every_scenario_and_are_small():
    sys.path.insert(0, str(BAGS))
    from regenerate import MAX_TOTAL_BYTES, NOT_RECORDED, has_report
    scenarios = sorted(p.stem for p in (ROOT / 'config').glob('*.yaml') if p.stem not in NOT_RECORDED)
    assert [p.name for p in RECORDINGS] == scenarios
    for folder in RECORDINGS:
        # recordings made since the viewer topics also keep their viewer layouts (layouts/)
        layouts = ['layouts'] if (folder / 'layouts').exists() else []
        if layouts:
            assert sorted(p.name for p in (folder / 'layouts').iterdir()) == ['foxglove.json', 'plotjuggler.xml']
        if not has_report(folder.name):
            assert sorted(p.name for p in folder.iterdir()) == sorted(['bag', 'metrics.json', 'scenario.yaml', *layouts])
            continue
        assert sorted(p.name for p in folder.iterdir()) == sorted(['bag', 'metrics.json', 'report', 'scenario.yaml',
                                                                   *layouts])
        assert (folder / 'report' / 'report.md').is_file()  # what the docs link to
    total = sum(f.stat().st_size for folder in RECORDINGS for f in folder.rglob('*') if f.is_file())
    assert total < MAX_TOTAL_BYTES <= 100_000_000


@pytest.mark.parametrize('folder', RECORDINGS, ids=lambda p: p.name)
def test_reference_recording_metrics_unchanged(folder):
    """The metrics computed now from each kept bag are the ones adcs-run printed when it was made,
    and the bag holds every step of the run (state, applied torque, controller status): nothing
    was lost on the way to the recorder."""
    from adcs_sim.app.scenario.files import validate_scenario
    from adcs_sim.truth.schema import step_timing
    kept = json.loads((folder / 'metrics.json').read_text())
    run = RunData.from_bag(folder / 'bag')
    now = json.loads(json.dumps(jsonable_metrics(run_metrics(run))))
    assert {k: now.get(k) for k in kept} == kept
    _, n = step_timing(validate_scenario(folder / 'scenario.yaml')['dynamics'])
    assert (len(run.t), len(run.t_u), len(run.controller_status)) == (n + 1, n, n + 1)


def test_fast_reader_equals_rosbags_deserialisation_on_recorded_bag():
    """The numpy CDR decoding against rosbags' deserialiser (read through the mcap library)."""
    run = RunData.from_bag(REFERENCE)
    msgs: dict[str, list] = {}
    for topic, _, msg in read_messages(REFERENCE):
        msgs.setdefault(topic, []).append(msg)
    stamp = lambda m: m.header.stamp.sec + m.header.stamp.nanosec * 1e-9  # noqa: E731
    state = msgs['/state']
    np.testing.assert_array_equal(run.t, [stamp(m) for m in state])
    o = [m.pose.pose.orientation for m in state]
    np.testing.assert_array_equal(run.q, [[x.x, x.y, x.z, x.w] for x in o])
    np.testing.assert_array_equal(run.w, [[m.twist.twist.angular.x, m.twist.twist.angular.y,
                                           m.twist.twist.angular.z] for m in state])
    np.testing.assert_array_equal(run.u, [[m.vector.x, m.vector.y, m.vector.z] for m in msgs['/actuators/torque']])
    np.testing.assert_array_equal(run.wheel_speed, [m.velocity for m in msgs['/wheels/state']])
    np.testing.assert_array_equal(run.wheel_torque, [m.effort for m in msgs['/wheels/state']])
    assert run.controller_status == [(stamp(m), s.name, {kv.key: kv.value for kv in s.values})
                                     for m in msgs['/controller/status'] for s in m.status]
    assert run.topic_counts == {k.lstrip('/'): len(v) for k, v in msgs.items()}
    assert run.message_count == sum(len(v) for v in msgs.values())
    assert not run.truncated and run.missing_topics == [] and run.namespace == '/'
    assert run.scenario is not None and run.missed_steps == 0


# --- truncated recordings --------------------------------------------------------------------



def test_truncated_recording_loads_what_was_recovered(tmp_path):
    full = RunData.from_bag(REFERENCE)
    bag = truncated_copy(tmp_path, 0.6)
    run = RunData.from_bag(bag)
    assert run.truncated and not full.truncated
    n = run.t.size
    assert 0.3 * full.t.size < n < full.t.size
    np.testing.assert_array_equal(run.t, full.t[:n])
    np.testing.assert_array_equal(run.q, full.q[:n])
    np.testing.assert_array_equal(run.u, full.u[:run.u.shape[0]])
    # The count agrees with the mcap library's own streaming reader (read_raw) on the same file.
    assert run.message_count == sum(1 for _ in read_raw(bag)) < full.message_count
    assert run.scenario == full.scenario                      # the metadata record comes first
    m = run_metrics(run)
    assert m['duration_s'] == run.t[-1] < full.t_end
    assert m['missed_steps'] == 0                               # the first dynamics/status


def test_truncation_anywhere_loads_a_prefix_or_says_there_is_no_state(tmp_path):
    full = RunData.from_bag(REFERENCE)
    last = -1
    for fraction in np.linspace(0.0, 0.98, 25):
        bag = truncated_copy(tmp_path, fraction)
        try:
            run = RunData.from_bag(bag)
        except ValueError as exc:
            assert '\n' not in str(exc) and ('state' in str(exc) or 'not a bag' in str(exc))
            continue
        assert run.truncated
        assert run.message_count >= last
        last = run.message_count
        np.testing.assert_array_equal(run.t, full.t[:run.t.size])
    assert last > 0


def test_killed_writer_bag_has_every_flushed_message(tmp_path):
    messages = SYN.messages()
    bag = write_ours(tmp_path / 'bag', messages, close=False)
    assert not (bag / 'metadata.yaml').exists()
    run = RunData.from_bag(bag)
    assert run.truncated and run.message_count == len(messages)
    np.testing.assert_array_equal(run.q, SYN.q)


# --- missing topics, not a bag ---------------------------------------------------------------

def test_state_only_bag_loads_and_lists_missing_topics(tmp_path):
    bag = write_rosbags(tmp_path / 'bag', SYN.messages(('state',)), StoragePlugin.MCAP)
    run = RunData.from_bag(bag)
    np.testing.assert_array_equal(run.q, SYN.q)
    assert run.missing_topics == [t for t in REPORTED_TOPICS if t != 'state']
    assert run.u.shape == (0, 3) and run.wheel_speed.size == 0 and run.missed_steps is None
    m = run_metrics(run)
    assert math.isnan(m['integrated_torque_Nms']) and math.isnan(m['peak_wheel_speed_rad_s'])
    assert m['settling_eigenaxis_0.5deg_s'] == pytest.approx(SYN.settling_eigen, abs=0.01)


@pytest.mark.parametrize('storage', [StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_bag_without_state_is_a_value_error(tmp_path, storage):
    bag = write_rosbags(tmp_path / 'bag', SYN.messages(('torque', 'wheels')), storage)
    with pytest.raises(ValueError) as exc:
        RunData.from_bag(bag)
    assert 'state' in one_line(exc)


def test_state_of_another_type_is_a_value_error(tmp_path):
    bag = write_rosbags(tmp_path / 'bag', [('/state', V3S, 0, ser(vec3(0, U), V3S))], StoragePlugin.MCAP)
    with pytest.raises(ValueError) as exc:
        RunData.from_bag(bag)
    assert V3S in one_line(exc)


def test_things_that_are_not_bags(tmp_path):
    text = tmp_path / 'notes.txt'
    text.write_text('not a bag\nat all\n')
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    junk = tmp_path / 'junk.mcap'
    junk.write_bytes(MCAP_MAGIC + bytes(range(256)) * 10)
    bad_meta = tmp_path / 'bad_meta'
    bad_meta.mkdir()
    (bad_meta / 'metadata.yaml').write_text('rosbag2_bagfile_information: [1, 2\n')
    (tmp_path / 'empty_dir').mkdir()
    for path in (text, empty, junk, bad_meta):
        with pytest.raises(ValueError) as exc:
            RunData.from_bag(path)
        assert str(path) in one_line(exc)
    for path in (tmp_path / 'empty_dir', tmp_path / 'missing'):
        with pytest.raises(OSError) as exc:
            RunData.from_bag(path)
        assert str(path) in one_line(exc)


# --- namespaces, truth, split files ----------------------------------------------------------

def test_truth_state_preferred_and_wheels_or_truth_prefix_not_taken_for_a_namespace(tmp_path):
    noisy = [(topic, ty, t, ser(odom(t, [0.0, 0.0, 0.6, 0.8], [0.0, 0.0, 0.0]), ODOM)) if topic == '/state'
             else (topic, ty, t, d) for topic, ty, t, d in SYN.messages(('state',))]
    truth = [('/truth/state', ty, t, d) for _, ty, t, d in SYN.messages(('state',))]
    wheels = SYN.messages(('wheels',))
    bag = write_rosbags(tmp_path / 'bag', wheels + truth + noisy, StoragePlugin.MCAP)
    run = RunData.from_bag(bag)
    assert run.namespace == '/'
    np.testing.assert_array_equal(run.q, SYN.q)        # the truth, not the measured state
    assert run.topic_counts['truth/state'] == N and run.topic_counts['wheels/state'] == N


def test_namespaced_runs(tmp_path):
    sat1 = SYN.messages(prefix='/sat1/')
    sat2 = [(topic.replace('/sat1/', '/sat2/'), ty, t, ser(odom(t, [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0]), ODOM))
            for topic, ty, t, _ in sat1 if topic == '/sat1/state']
    bag = write_rosbags(tmp_path / 'bag', sat2 + sat1, StoragePlugin.MCAP)
    run = RunData.from_bag(bag)                        # the namespace with the most of the graph
    assert run.namespace == '/sat1/' and run.missing_topics == ['controller/status']
    np.testing.assert_array_equal(run.q, SYN.q)
    assert run.topic_counts['state'] == N and run.topic_counts['sat2/state'] == N
    other = RunData.from_bag(bag, namespace='sat2')
    assert other.namespace == '/sat2/'
    np.testing.assert_array_equal(other.q, np.tile([0.0, 0.0, 0.0, 1.0], (N, 1)))
    assert other.missing_topics == [t for t in REPORTED_TOPICS if t != 'state']


def test_split_bag_files_are_read_in_order(tmp_path):
    messages = SYN.messages()
    half = len(messages) // 2
    first = write_ours(tmp_path / 'a', messages[:half])
    second = write_ours(tmp_path / 'b', messages[half:])
    folder = tmp_path / 'split'
    folder.mkdir()
    shutil.copy(next(first.glob('*.mcap')), folder / 'split_0.mcap')
    shutil.copy(next(second.glob('*.mcap')), folder / 'split_1.mcap')
    run = RunData.from_bag(folder)
    np.testing.assert_array_equal(run.t, SYN.t)
    np.testing.assert_array_equal(run.u, SYN.u)
    assert run.message_count == len(messages) and run.missed_steps == 2


# --- the column decoder on its own -----------------------------------------------------------

def test_decoder_layout_templates_and_many_distinct_layouts():
    """Every message its own frame_id length: more layouts than templates, still exact."""
    rng = np.random.default_rng(7)
    n = 200
    q = Rotation.random(n, random_state=3).as_quat()
    datas = [ser(odom(i, q[i], [i, -i, 0.5 * i], 'x' * i, 'y' * (i % 7)), ODOM, little_endian=bool(rng.integers(2)))
             for i in range(n)]
    sizes = np.array([len(d) for d in datas])
    batch = TopicBatch('/state', ODOM, np.frombuffer(b''.join(datas), np.uint8),
                             np.r_[0, np.cumsum(sizes)[:-1]], sizes)
    groups = decode_batch(batch)
    rows = np.concatenate([g.rows for g in groups])
    assert sorted(rows.tolist()) == list(range(n))
    order = np.argsort(rows)
    got_q = np.concatenate([g.fields['orientation'] for g in groups])[order]
    got_ns = np.concatenate([g.stamp_ns for g in groups])[order]
    np.testing.assert_array_equal(got_q, q)
    np.testing.assert_array_equal(got_ns, np.arange(n))
    # A message cut short parses as nothing, not as garbage.
    short = TopicBatch('/state', ODOM, np.frombuffer(datas[5][:-8], np.uint8), np.array([0]),
                             np.array([len(datas[5]) - 8]))
    assert sum(g.rows.size for g in decode_batch(short)) == 0


def test_diagnostics_decoder_against_rosbags(monkeypatch):
    """Repeated structures (walked with numpy), one-off ones, big-endian and cut messages."""
    import random
    rnd = random.Random(11)

    def text(k=7):
        return ''.join(rnd.choice('abé_0') for _ in range(rnd.randrange(k)))

    def structure():
        return [(text(), [text() + str(i) for i in range(rnd.randrange(4))]) for _ in range(rnd.randrange(3))]

    common = [structure() for _ in range(4)]
    messages, datas = [], []
    odd = 0
    for i in range(1500):
        shape = common[rnd.randrange(4)] if rnd.random() < 0.9 else structure()
        odd += shape not in common
        msg = T[DIAG](header=header(rnd.randrange(10 ** 15), text()), status=[
            T['diagnostic_msgs/msg/DiagnosticStatus'](
                level=rnd.randrange(4), name=name, message=text(), hardware_id=text(),
                values=[T['diagnostic_msgs/msg/KeyValue'](key=k, value=text(15)) for k in keys])
            for name, keys in shape])
        data = ser(msg, DIAG, little_endian=rnd.random() < 0.8)
        if rnd.random() < 0.03:
            data, msg = data[:rnd.randrange(len(data))], None
            odd += 1
        messages.append(msg)
        datas.append(data)
    sizes = np.array([len(d) for d in datas])
    batch = TopicBatch('/s', DIAG, np.frombuffer(b''.join(datas), np.uint8), np.r_[0, np.cumsum(sizes)[:-1]],
                             sizes)
    scalar = []
    parse_one = _diagnostic_array
    monkeypatch.setattr(columns, '_diagnostic_array', lambda *a: scalar.append(1) or parse_one(*a))
    stamps, statuses = decode_diagnostics(batch)
    # Only the first message of each structure and byte order (and the odd ones) is parsed alone.
    assert len(scalar) <= odd + 2 * len(common)
    intact = [m for m in messages if m is not None]
    assert len(statuses) == len(intact) < len(messages)
    np.testing.assert_array_equal(stamps, [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in intact])
    assert statuses == [[(s.level, s.name, s.message, s.hardware_id, {kv.key: kv.value for kv in s.values})
                         for s in m.status] for m in intact]


def test_a_quarantine_is_never_taken_for_the_runs_namespace(tmp_path):
    """A compromised run whose recorder took every state after it had seen the intruder keeps them
    all under quarantine/state (tests/test_intruders.py, on a loaded machine): the analysis finds no
    state of the run, rather than analysing the quarantine (maybe the intruder's) as a namespace of
    it; beside the run's own states, the quarantine is never chosen either, however full."""
    Q = np.array([0.0, 0.0, 0.0, 1.0])
    W = np.zeros(3)
    rogue = [('/quarantine/state', 'nav_msgs/msg/Odometry', k * 10**9, ser(odom(k * 10**9, Q, W), 'nav_msgs/msg/Odometry'))
             for k in range(5)]
    rogue += [('/quarantine/actuators/torque', 'geometry_msgs/msg/Vector3Stamped', k * 10**9,
               ser(vec3(k * 10**9, [1.0, 2.0, 3.0]), 'geometry_msgs/msg/Vector3Stamped')) for k in range(5)]
    applied = [('/actuators/torque', 'geometry_msgs/msg/Vector3Stamped', k * 10**9,
                ser(vec3(k * 10**9, [0.1, 0.0, 0.0]), 'geometry_msgs/msg/Vector3Stamped')) for k in range(2)]
    only_quarantined = write_ours(tmp_path / 'only', rogue + applied)
    with pytest.raises(ValueError, match=r'no /state \(nav_msgs/msg/Odometry\) messages: not a run of the graph'):
        RunData.from_bag(only_quarantined)
    intrusion = [('/intrusions', DIAG, 3 * 10**9, ser(diag(3 * 10**9, '/state', {
        'topic': '/state', 'node': '/rogue', 'gid': '01.0f', 'allowed': '/dynamics'}), DIAG))]
    with pytest.raises(ValueError, match=r'no /state .* of the run \(those recorded are under /quarantine/state, not '
                                         r'analysed\): nothing to analyse; run compromised: intruder node /rogue '):
        RunData.from_bag(write_ours(tmp_path / 'compromised', rogue + applied + intrusion))
    own = [('/state', 'nav_msgs/msg/Odometry', k * 10**9, ser(odom(k * 10**9, Q, 0.01 * np.ones(3)), 'nav_msgs/msg/Odometry'))
           for k in range(2)]
    both = RunData.from_bag(write_ours(tmp_path / 'both', rogue + applied + own))
    assert len(both.t) == 2 and np.all(both.w == 0.01)
    np.testing.assert_array_equal(both.u, [[0.1, 0.0, 0.0]] * 2)
