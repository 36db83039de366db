"""Bags for the tests: what a bag being written holds so far (:func:`states_on_disk`), and synthetic
runs written by independent writers (rosbags' rosbag2 Writer, MCAP and sqlite3; the mcap library
with other chunking/compression/index choices; adcs_sim.bag.writer.BagWriter), from messages
serialised by rosbags, with answers known in closed form (:data:`SYN`). No ROS.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from adcs_sim.bag.reader import read_raw
from adcs_sim.bag.writer import BagWriter
from support.paths import BAGS


def states_on_disk(bag: Path) -> int:
    """How many ``/state`` messages a bag being written holds: 0 until the recorder has created its
    file and written the MCAP magic (the file exists, empty, for a moment first). Any other fault of
    the file is raised: a poll must not hide a broken bag."""
    try:
        return sum(t == '/state' for t, *_ in read_raw(bag))
    except FileNotFoundError:
        return 0
    except ValueError:
        files = list(Path(bag).glob('*.mcap')) if Path(bag).is_dir() else [Path(bag)]
        if files and all(f.stat().st_size < 8 for f in files):   # 8: the MCAP magic's length
            return 0
        raise


STORE = get_typestore(Stores.ROS2_JAZZY)
T = STORE.types
ODOM, V3S, JS, DIAG = ('nav_msgs/msg/Odometry', 'geometry_msgs/msg/Vector3Stamped',
                       'sensor_msgs/msg/JointState', 'diagnostic_msgs/msg/DiagnosticArray')
REFERENCE = BAGS / 'microsat_pd_slew' / 'bag'

# --- synthetic messages (rosbags serialisation) ----------------------------------------------


def header(t_ns: int, frame: str):
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=sec, nanosec=nsec), frame_id=frame)


def odom(t_ns, q, w, frame='inertial', child='body'):
    v3, cov = T['geometry_msgs/msg/Vector3'], np.zeros(36)
    return T[ODOM](
        header=header(t_ns, frame), child_frame_id=child,
        pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=T['geometry_msgs/msg/Pose'](
            position=T['geometry_msgs/msg/Point'](x=1.0, y=2.0, z=3.0),
            orientation=T['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3])), covariance=cov),
        twist=T['geometry_msgs/msg/TwistWithCovariance'](twist=T['geometry_msgs/msg/Twist'](
            linear=v3(x=-1.0, y=-2.0, z=-3.0), angular=v3(x=w[0], y=w[1], z=w[2])), covariance=cov))


def vec3(t_ns, v, frame='body'):
    return T[V3S](header=header(t_ns, frame), vector=T['geometry_msgs/msg/Vector3'](x=v[0], y=v[1], z=v[2]))


def joints(t_ns, names, position, velocity, effort, frame=''):
    return T[JS](header=header(t_ns, frame), name=list(names), position=np.asarray(position, dtype=float),
                 velocity=np.asarray(velocity, dtype=float), effort=np.asarray(effort, dtype=float))


def diag(t_ns, name, values, level=0):
    kv = [T['diagnostic_msgs/msg/KeyValue'](key=k, value=v) for k, v in values.items()]
    return T[DIAG](header=header(t_ns, ''), status=[T['diagnostic_msgs/msg/DiagnosticStatus'](
        level=level, name=name, message='', hardware_id='', values=kv)])


def ser(msg, type_name, little_endian=True) -> bytes:
    return bytes(STORE.serialize_cdr(msg, type_name, little_endian=little_endian))


# --- a synthetic run with known metrics ------------------------------------------------------

N = 301                      # state samples at 1 s: t = 0 .. 300
ANGLE0_DEG, TAU = 20.0, 40.0
AXIS = np.array([2.0, -1.0, 2.0]) / 3.0
U = np.array([0.004, -0.003, 0.012])   # |U| = 0.013
WHEELS = ('rw_a', 'rw_b', 'rw_c')
FRAMES = ('inertial', '', 'f', 'a_much_longer_frame_name')   # layouts vary from message to message


class Synthetic:
    def __init__(self):
        self.t = np.arange(N, dtype=float)
        angle = np.radians(ANGLE0_DEG) * np.exp(-self.t / TAU)
        self.q = Rotation.from_rotvec(np.outer(angle, AXIS)).as_quat()
        self.w = np.outer(-angle / TAU, AXIS)
        t_u = self.t[:-1]
        self.u = np.where((t_u < 30)[:, None], U, np.where((t_u >= 70)[:, None], -U, 0.0))
        self.speed = np.column_stack([10 * np.sin(self.t / 20), -42.0 * np.exp(-((self.t - 150) / 9) ** 2),
                                      np.full(N, 5.0)])
        self.torque = np.vstack([-self.u, np.zeros(3)])   # wheel motor torque = -(applied body torque)

    # expected numbers, from the definitions (adcs_sim.app.analysis.metrics) in closed form
    settling_eigen = TAU * math.log(ANGLE0_DEG / 0.5)
    integrated = (30 + 230) * float(np.linalg.norm(U))
    energy = (30 + 230) * float(U @ U)

    def messages(self, topics=('state', 'torque', 'wheels', 'status'), prefix='/'):
        """(topic, type, log time ns, CDR) in the graph's order; every 5th message big-endian."""
        out = []

        def add(topic, type_name, t_ns, msg, i):
            out.append((prefix + topic, type_name, t_ns, ser(msg, type_name, little_endian=i % 5 != 3)))

        if 'status' in topics:
            add('dynamics/status', DIAG, 0, diag(0, 'dynamics', {'missed_steps': '0', 'final': 'false'}), 0)
        for k in range(N):
            t_ns = k * 1_000_000_000
            if 'state' in topics:
                add('state', ODOM, t_ns, odom(t_ns, self.q[k], self.w[k], FRAMES[k % 4], ('body', 'b_l')[k % 2]), k)
            if 'wheels' in topics:
                position = [] if k % 2 else [0.1, 0.2, 0.3]
                add('wheels/state', JS, t_ns, joints(t_ns, WHEELS, position, self.speed[k], self.torque[k],
                                                     FRAMES[(k + 1) % 4]), k)
            if 'torque' in topics and k < N - 1:
                add('actuators/torque', V3S, t_ns, vec3(t_ns, self.u[k], FRAMES[(k + 2) % 4]), k)
        if 'status' in topics:
            t_ns = (N - 1) * 1_000_000_000
            add('dynamics/status', DIAG, t_ns, diag(t_ns, 'dynamics', {'missed_steps': '2', 'final': 'true'}, 1), 1)
        return out


SYN = Synthetic()

# --- writers ---------------------------------------------------------------------------------

QOS = [{'history': 'keep_last', 'depth': 10, 'reliability': 'reliable', 'durability': 'volatile',
        'deadline': {'sec': 2147483647, 'nsec': 4294967295}, 'lifespan': {'sec': 2147483647, 'nsec': 4294967295},
        'liveliness': 'automatic', 'liveliness_lease_duration': {'sec': 2147483647, 'nsec': 4294967295},
        'avoid_ros_namespace_conventions': False}]


def write_rosbags(path: Path, messages, storage) -> Path:
    with Writer(path, version=9, storage_plugin=storage) as writer:
        conns = {}
        for topic, type_name, t_ns, data in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, type_name, typestore=STORE)
            writer.write(conns[topic], t_ns, data)
    return path


def write_ours(path: Path, messages, close=True, chunk_size=4096) -> Path:
    writer = BagWriter(path, chunk_size=chunk_size)
    for topic, type_name, t_ns, data in messages:
        writer.add_topic(topic, type_name, QOS)
        writer.write(topic, data, t_ns)
    if close:
        writer.close()
    else:  # the process was killed after its last flush: no summary, no metadata.yaml
        writer.flush()
        writer._file.close()
    return path


def write_mcap(path: Path, messages, **options) -> Path:
    """The mcap library directly, with the given Writer options; a folder without metadata.yaml."""
    from mcap.writer import Writer as McapWriter
    path.mkdir()
    with open(path / 'run.mcap', 'wb') as f:
        writer = McapWriter(f, **options)
        writer.start(profile='ros2', library='test')
        schemas, channels = {}, {}
        for topic, type_name, t_ns, data in messages:
            if type_name not in schemas:
                text, _ = STORE.generate_msgdef(type_name, ros_version=2)
                schemas[type_name] = writer.register_schema(type_name, 'ros2msg', text.encode())
            if topic not in channels:
                channels[topic] = writer.register_channel(topic, 'cdr', schemas[type_name])
            writer.add_message(channels[topic], t_ns, data, t_ns)
        writer.finish()
    return path


def _mcap_variants():
    from mcap.writer import CompressionType, IndexType
    return {
        'mcap-lz4-no-message-index': dict(compression=CompressionType.LZ4, index_types=IndexType.CHUNK,
                                          chunk_size=2000),
        'mcap-uncompressed': dict(compression=CompressionType.NONE, chunk_size=100_000),
        'mcap-unchunked': dict(use_chunking=False),
    }


WRITERS = ['rosbags-mcap', 'rosbags-sqlite3', 'adcs-bagwriter', *_mcap_variants()]


def write(kind: str, path: Path, messages) -> Path:
    if kind == 'rosbags-mcap':
        return write_rosbags(path, messages, StoragePlugin.MCAP)
    if kind == 'rosbags-sqlite3':
        return write_rosbags(path, messages, StoragePlugin.SQLITE3)
    if kind == 'adcs-bagwriter':
        return write_ours(path, messages)
    return write_mcap(path, messages, **_mcap_variants()[kind])


# --- a recording cut short --------------------------------------------------------------------

def truncated_copy(tmp_path: Path, fraction: float) -> Path:
    """The reference bag's .mcap cut to ``fraction`` of its bytes, without metadata.yaml."""
    folder = tmp_path / f'cut_{fraction:.3f}'
    folder.mkdir()
    data = next(REFERENCE.glob('*.mcap')).read_bytes()
    (folder / 'bag_0.mcap').write_bytes(data[:int(len(data) * fraction)])
    return folder

