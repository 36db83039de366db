"""A recorder's writing loop without ROS, to be SIGKILLed at random moments (tests/test_bag_repair.py).

``python bag_writer_child.py OUT CHUNK_SIZE FLUSH_EVERY SCENARIO``: writes /clock and /state
(state k: stamp k * 0.1 s, content a function of k) through :class:`adcs_sim.bag.writer.BagWriter`, the
recorder's writer, flushing every FLUSH_EVERY states and printing ``flushed N`` (N states
written before that flush) once the flush has returned. Runs until killed (or 10**6 states).
"""
import math
import sys

import numpy as np

from adcs_sim.bag.storage import typestore
from adcs_sim.bag.writer import BagWriter

out, chunk, every, scenario = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
store = typestore()
Odometry = store.types['nav_msgs/msg/Odometry']
Clock = store.types['rosgraph_msgs/msg/Clock']
Time = store.types['builtin_interfaces/msg/Time']
Header = store.types['std_msgs/msg/Header']
Pose = store.types['geometry_msgs/msg/Pose']
PoseCov = store.types['geometry_msgs/msg/PoseWithCovariance']
Twist = store.types['geometry_msgs/msg/Twist']
TwistCov = store.types['geometry_msgs/msg/TwistWithCovariance']
Point = store.types['geometry_msgs/msg/Point']
Quat = store.types['geometry_msgs/msg/Quaternion']
Vec = store.types['geometry_msgs/msg/Vector3']
cov = np.zeros(36)
INFINITE = {'sec': 2147483647, 'nsec': 4294967295}
QOS = [{'history': 'keep_last', 'depth': 10, 'reliability': 'reliable', 'durability': 'volatile',
        'deadline': INFINITE, 'lifespan': INFINITE, 'liveliness': 'system_default',
        'liveliness_lease_duration': INFINITE, 'avoid_ros_namespace_conventions': False}]  # as the recorder

w = BagWriter(out, chunk_size=chunk, metadata={'scenario': open(scenario).read()})
w.add_topic('/clock', 'rosgraph_msgs/msg/Clock', QOS)
w.add_topic('/state', 'nav_msgs/msg/Odometry', QOS)
print('ready', flush=True)
for k in range(10**6):
    t = Time(sec=k // 10, nanosec=(k % 10) * 100_000_000)
    a = 1e-3 * k
    odom = Odometry(header=Header(stamp=t, frame_id='inertial'), child_frame_id='body',
                    pose=PoseCov(pose=Pose(position=Point(x=0.0, y=0.0, z=0.0),
                                           orientation=Quat(x=0.0, y=0.0, z=math.sin(a / 2), w=math.cos(a / 2))),
                                 covariance=cov),
                    twist=TwistCov(twist=Twist(linear=Vec(x=0.0, y=0.0, z=0.0), angular=Vec(x=float(k), y=0.0, z=1e-3)),
                                   covariance=cov))
    w.write('/clock', store.serialize_cdr(Clock(clock=t), 'rosgraph_msgs/msg/Clock'))
    w.write('/state', store.serialize_cdr(odom, 'nav_msgs/msg/Odometry'))
    if (k + 1) % every == 0:
        w.flush()
        print(f'flushed {k + 1}', flush=True)
