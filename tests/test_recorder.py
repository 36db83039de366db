"""The recorder node as a process: clean stop, crash tolerance, refusals, metadata, discovery.

Each test runs the recorder (``python -m adcs_sim.nodes.recorder``) on the test's own domain id and
publishes to it from an in-process rclpy node on a private context. Synchronisation is on graph
and DDS events only (matched subscriptions, acknowledgements, the ready line, what a flush made
readable on disk), each with a deadline; no sleeps.
"""
from __future__ import annotations

import fcntl
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import Float64
from support.processes import shm_segments
from support.recorder import (
    ACK_TIMEOUT,
    DEADLINE,
    STATE_TOPIC,
    STEP_NS,
    check_state,
    odom_fields,
    raw_states,
    ros_node,
    state_values,
    until,
)

from adcs_msgs_py import topics
from adcs_msgs_py.conversions import NS_PER_S, clock_msg, state_to_msg
from adcs_msgs_py.node import EXIT_BAD_PARAMETERS
from adcs_sim.bag.reader import is_complete, read_metadata, read_raw
from adcs_sim.bag.storage import mcap_file, typestore
from adcs_sim.nodes.recorder import READY_LINE

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = 'config/microsat_pd_slew.yaml'


# --- helpers --------------------------------------------------------------------------------


class Recorder:
    """One recorder process: stdout lines collected by a thread, stderr to a file."""

    def __init__(self, env: dict, tmp: Path, *params: str) -> None:
        args = [sys.executable, '-m', 'adcs_sim.nodes.recorder', '--ros-args']
        for p in params:
            args += ['-p', p]
        self.stderr_path = tmp / f'recorder-{len(list(tmp.glob("recorder-*.err")))}.err'
        self._stderr = open(self.stderr_path, 'wb')
        self.proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                     stderr=self._stderr, text=True)
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.shm: set[Path] = set()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line.rstrip('\n'))
        self.lines.put(None)

    def wait_ready(self, timeout: float = DEADLINE) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                pytest.fail(f'recorder not ready after {timeout:g} s; stderr:\n{self.stderr()}')
            if line is None:
                pytest.fail(f'recorder exited ({self.proc.wait()}) before ready; stderr:\n{self.stderr()}')
            if line == READY_LINE:
                return

    def stop(self, sig: int, timeout: float = DEADLINE) -> int:
        self.proc.send_signal(sig)
        return self.wait(timeout)

    def kill(self) -> int:
        """SIGKILL, noting the Fast DDS shared-memory segments the process had mapped (a killed
        process cannot remove them; see :meth:`cleanup`)."""
        self.shm = shm_segments(self.proc.pid)
        self.proc.kill()
        return self.wait()

    def wait(self, timeout: float = DEADLINE) -> int:
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f'recorder still running after {timeout:g} s; stderr:\n{self.stderr()}')

    def stderr(self) -> str:
        self._stderr.flush()
        return self.stderr_path.read_text(errors='replace')

    def cleanup(self) -> None:
        if self.proc.poll() is None:
            self.kill()
        self.proc.wait(timeout=DEADLINE)
        for seg in self.shm:
            remove_if_orphaned(seg)
        self._reader.join(timeout=DEADLINE)
        self.proc.stdout.close()
        self._stderr.close()


def remove_if_orphaned(segment: Path) -> None:
    """Remove a Fast DDS segment whose owner is dead.

    Fast DDS uses shared memory here even with FASTDDS_BUILTIN_TRANSPORTS=UDPv4 (set by conftest),
    so a SIGKILLed process leaves its ~0.5 MB segment in /dev/shm. The owner holds an exclusive
    flock on ``<segment>_el`` while alive (what ``fastdds shm clean`` checks): if we can take it,
    nobody owns the segment any more. The recorder also maps live peers' segments; those stay.
    """
    lock = segment.with_name(segment.name + '_el')
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return  # owner alive
    else:
        segment.unlink(missing_ok=True)
        lock.unlink(missing_ok=True)
    finally:
        os.close(fd)


def children_of(pid: int) -> list[int]:
    """Live (non-zombie) processes whose parent is ``pid``."""
    out = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(')') + 2:].split()
        if int(fields[1]) == pid and fields[0] != 'Z':
            out.append(int(entry.name))
    return out


@pytest.fixture
def recorders(ros_domain, tmp_path):
    """Factory of recorder processes on the test's domain; all killed and reaped at the end."""
    started: list[Recorder] = []
    before = set(children_of(os.getpid()))

    def start(*params: str) -> Recorder:
        rec = Recorder(ros_domain.env(), tmp_path, *params)
        started.append(rec)
        return rec

    try:
        yield start
    finally:
        for rec in started:
            rec.cleanup()
        orphans = set(children_of(os.getpid())) - before
        assert not orphans, f'processes left behind: {sorted(orphans)}'


def publishers(node):
    """(clock, state) publishers with the interface's QoS."""
    clock = node.create_publisher(topics.TOPICS[topics.CLOCK].msg_type, topics.CLOCK,
                                  topics.TOPICS[topics.CLOCK].qos)
    state = node.create_publisher(topics.TOPICS[topics.STATE].msg_type, topics.STATE,
                                  topics.TOPICS[topics.STATE].qos)
    return clock, state


def wait_matched(*pubs) -> None:
    for pub in pubs:
        until(f'a subscription on {pub.topic_name}', lambda p=pub: p.get_subscription_count() >= 1)


def wait_acked(*pubs) -> None:
    for pub in pubs:
        assert pub.wait_for_all_acked(ACK_TIMEOUT), f'{pub.topic_name}: not all messages acknowledged'


def publish_states(clock, state, ks, batch: int | None = None) -> None:
    """State then /clock for each k. With ``batch``, wait for the acks every ``batch`` steps: the
    publishers are KEEP_LAST depth 10, so a burst longer than that may overwrite samples not yet
    delivered (that is the publisher's QoS, not the recorder's doing).

    The state goes first so that "log time = latest /clock" (the rule for unstamped types) would
    give a state the previous step's time: the log time == header stamp checks can tell them apart.
    """
    for i, k in enumerate(ks, 1):
        t_ns = k * STEP_NS
        q, w = state_values(k)
        state.publish(state_to_msg(t_ns, q, w))
        clock.publish(clock_msg(t_ns))
        if batch and i % batch == 0:
            wait_acked(clock, state)


def state_prefix(stamps_and_content) -> int:
    """Check that the state messages are k = 0, 1, 2, ... in order with the right content."""
    n = 0
    for k, (stamp, log_time, q, w) in enumerate(stamps_and_content):
        check_state(k, stamp, q, w)
        assert log_time == stamp, f'message {k}: log time {log_time} != header stamp {stamp}'
        n += 1
    return n


def count_raw(bag, topic: str) -> int:
    try:
        return sum(1 for m in read_raw(bag) if m[0] == topic)
    except FileNotFoundError:
        return 0


# --- 1. clean stop -------------------------------------------------------------------------

N_CLEAN = 500


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_closes_a_complete_bag(recorders, tmp_path, sig):
    out = tmp_path / 'bag'
    rec = recorders(f'output:={out}', 'flush_period:=0.2', 'chunk_size:=4096')
    rec.wait_ready()
    with ros_node('test_publisher') as node:
        clock, state = publishers(node)
        wait_matched(clock, state)
        publish_states(clock, state, range(N_CLEAN), batch=topics.QOS_LOCKSTEP.depth)
        wait_acked(clock, state)
        status = rec.stop(sig)
    assert status == 0, rec.stderr()
    assert (out / 'metadata.yaml').is_file()

    # metadata.yaml: counts per topic and in total
    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count'] for t in info['topics_with_message_count']}
    assert counts[STATE_TOPIC] == N_CLEAN
    assert counts[topics.CLOCK] == N_CLEAN
    assert info['message_count'] == sum(counts.values()) == 2 * N_CLEAN
    assert info['starting_time']['nanoseconds_since_epoch'] == 0
    assert info['duration']['nanoseconds'] == (N_CLEAN - 1) * STEP_NS

    # our own reader (indexed path)
    assert state_prefix(raw_states(out)) == N_CLEAN

    # rosbags
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        assert reader.message_count == 2 * N_CLEAN
        conns = [c for c in reader.connections if c.topic == STATE_TOPIC]
        assert [c.msgtype for c in conns] == ['nav_msgs/msg/Odometry']
        got = []
        for conn, timestamp, raw in reader.messages(connections=conns):
            stamp, q, w = odom_fields(reader.deserialize(raw, conn.msgtype))
            got.append((stamp, timestamp, q, w))
    assert state_prefix(got) == N_CLEAN

    # mcap_ros2 (file order, not re-sorted)
    got = []
    for m in read_ros2_messages(mcap_file(out), topics=[STATE_TOPIC], log_time_order=False):
        stamp, q, w = odom_fields(m.ros_msg)
        got.append((stamp, m.log_time_ns, q, w))
    assert state_prefix(got) == N_CLEAN
    clocks = [m.ros_msg.clock for m in read_ros2_messages(mcap_file(out), topics=[topics.CLOCK],
                                                          log_time_order=False)]
    assert [c.sec * NS_PER_S + c.nanosec for c in clocks] == [k * STEP_NS for k in range(N_CLEAN)]


def test_signal_right_after_ready_still_closes_the_bag(recorders, tmp_path):
    """SIGTERM as soon as the ready line is out: the recorder already handles it (no default
    action killing it with the bag unclosed)."""
    out = tmp_path / 'bag'
    rec = recorders(f'output:={out}')
    rec.wait_ready()
    status = rec.stop(signal.SIGTERM)
    assert status == 0, rec.stderr()
    assert (out / 'metadata.yaml').is_file()


# --- 2. crash tolerance ----------------------------------------------------------------------

N1 = 200


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_sigkill_keeps_everything_flushed(recorders, tmp_path, seed):
    n2 = int(np.random.default_rng(seed).integers(1, 400))
    out = tmp_path / 'bag'
    scenario_text = (ROOT / SCENARIO).read_text()
    rec = recorders(f'output:={out}', 'flush_period:=0.2', 'chunk_size:=4096',
                    f'scenario_file:={SCENARIO}')
    rec.wait_ready()
    with ros_node('test_publisher') as node:
        clock, state = publishers(node)
        wait_matched(clock, state)
        publish_states(clock, state, range(N1), batch=topics.QOS_LOCKSTEP.depth)
        wait_acked(clock, state)
        # a periodic flush has made all N1 readable from the live file
        until(f'{N1} state messages flushed to disk', lambda: count_raw(out, STATE_TOPIC) >= N1)
        publish_states(clock, state, range(N1, N1 + n2))
        assert rec.kill() == -signal.SIGKILL
    assert not (out / 'metadata.yaml').exists()

    # adcs_sim.bag.reader.read_raw: a prefix k = 0..M-1 with N1 <= M <= N1 + n2, all intact
    n = state_prefix(raw_states(out))
    assert N1 <= n <= N1 + n2
    # the metadata written at start is readable from the truncated file too
    assert read_metadata(out).get('scenario') == scenario_text

    # mcap's streaming reader with CRC checks, decoding with mcap_ros2, up to the truncated tail
    got = []
    with open(mcap_file(out), 'rb') as f:
        reader = NonSeekingReader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        try:
            for _schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
                if channel.topic == STATE_TOPIC:
                    stamp, q, w = odom_fields(msg)
                    got.append((stamp, message.log_time, q, w))
        except (McapError, EOFError):
            pass  # the truncated tail
    assert state_prefix(got) == n

    # adcs-bag-repair makes it a complete rosbag2 bag (summary, index, metadata.yaml) holding
    # exactly what was readable, which rosbags' AnyReader opens
    from adcs_sim.app.analysis.repair import main as repair_main
    assert repair_main([str(out)]) == 0
    assert (out / 'metadata.yaml').is_file() and is_complete(out)
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == STATE_TOPIC]
        got = [(*odom_fields(reader.deserialize(data, c.msgtype))[:1], t,
                *odom_fields(reader.deserialize(data, c.msgtype))[1:])
               for c, t, data in reader.messages(connections=conns)]
    assert state_prefix(got) == n
    assert read_metadata(out).get('scenario') == scenario_text


# --- 3. refusals -----------------------------------------------------------------------------

def test_refuses_existing_non_empty_output(recorders, tmp_path):
    out = tmp_path / 'bag'
    out.mkdir()
    (out / 'keep.txt').write_text('precious')
    rec = recorders(f'output:={out}')
    assert rec.wait() == EXIT_BAD_PARAMETERS
    err = rec.stderr()
    assert "output'" in err, err  # the key, e.g. 'recorder.ros__parameters.output'
    assert [p.name for p in out.iterdir()] == ['keep.txt']
    assert (out / 'keep.txt').read_text() == 'precious'
    assert rec.lines.get(timeout=DEADLINE) is None  # never announced ready


def test_refuses_unknown_parameter(recorders, tmp_path):
    out = tmp_path / 'bag'
    rec = recorders(f'output:={out}', 'flush_periode:=0.2')
    assert rec.wait() == EXIT_BAD_PARAMETERS
    err = rec.stderr()
    assert 'flush_periode' in err, err
    assert not out.exists()
    assert rec.lines.get(timeout=DEADLINE) is None


# --- 4. scenario embedding --------------------------------------------------------------------

def test_scenario_file_is_embedded(recorders, tmp_path):
    out = tmp_path / 'bag'
    rec = recorders(f'output:={out}', f'scenario_file:={SCENARIO}')
    rec.wait_ready()
    assert rec.stop(signal.SIGINT) == 0, rec.stderr()
    assert read_metadata(out)['scenario'] == (ROOT / SCENARIO).read_text()


# --- 5. discovery of topics outside the interface --------------------------------------------

def test_discovers_and_records_extra_topic(recorders, tmp_path):
    out = tmp_path / 'bag'
    rec = recorders(f'output:={out}', 'discovery_period:=0.1', 'flush_period:=0.1')
    rec.wait_ready()
    values = [20.0 + 0.25 * i for i in range(20)]
    clock_ns = 7 * NS_PER_S
    with ros_node('test_publisher') as node:
        clock, _ = publishers(node)
        wait_matched(clock)
        clock.publish(clock_msg(clock_ns))
        wait_acked(clock)
        # unstamped messages are logged at the latest /clock: wait until that clock is on disk
        until('/clock recorded', lambda: count_raw(out, topics.CLOCK) >= 1)
        temp = node.create_publisher(Float64, 'extra/temperature', 10)
        wait_matched(temp)  # the recorder found the topic and subscribed
        for v in values:
            temp.publish(Float64(data=v))
        wait_acked(temp)
        assert rec.stop(signal.SIGINT) == 0, rec.stderr()

    got = [(t, typestore().deserialize_cdr(data, type_name).data)
           for topic, type_name, t, data in read_raw(out) if topic == '/extra/temperature']
    assert [v for _, v in got] == values
    assert all(t == clock_ns for t, _ in got)
    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    extra = [t for t in info['topics_with_message_count']
             if t['topic_metadata']['name'] == '/extra/temperature']
    assert len(extra) == 1
    assert extra[0]['topic_metadata']['type'] == 'std_msgs/msg/Float64'
    assert extra[0]['message_count'] == len(values)
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == '/extra/temperature']
        assert [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages(connections=conns)] \
            == values
