"""The report tests' synthetic runs: a rotation about body x whose angle falls linearly from 30° to 0
at a known rate (linear between samples, so the interpolated settling times are exact), a piecewise
constant applied torque, linearly growing wheel speeds, a controller status with a mode switch, and
the final ``dynamics/status``, written as the graph records them (:func:`write_bag`). No ROS.
"""
from __future__ import annotations

import numpy as np
from rosbags.typesys import Stores, get_typestore

from adcs_sim.bag.writer import BagWriter

STORE = get_typestore(Stores.ROS2_JAZZY)
T = STORE.types
ODOM, JOINTS, VEC = 'nav_msgs/msg/Odometry', 'sensor_msgs/msg/JointState', 'geometry_msgs/msg/Vector3Stamped'
DIAG = 'diagnostic_msgs/msg/DiagnosticArray'
SCENARIO = """# synthetic run for the report tests
dynamics:
  ros__parameters:
    inertia: [12.0, 14.0, 10.0]
    wheels: {names: [rw_x, rw_y, rw_z]}
"""
N = 201              # samples at t = 0, 1, ..., 200 s
THETA0 = 30.0        # deg, rotation about x at t = 0
U_ON = 50            # the torque is applied for t < 50 s (50 control periods of 1 s)


def _header(t: float):
    sec, frac = divmod(t, 1.0)
    return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=int(sec), nanosec=int(round(frac * 1e9))),
                                    frame_id='')


def _odometry(t, q, w):
    g = T
    cov = np.zeros(36)
    pose = g['geometry_msgs/msg/Pose'](position=g['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
                                       orientation=g['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3]))
    zero = g['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
    twist = g['geometry_msgs/msg/Twist'](linear=zero, angular=g['geometry_msgs/msg/Vector3'](x=w[0], y=w[1], z=w[2]))
    return g[ODOM](header=_header(t), child_frame_id='body',
                   pose=g['geometry_msgs/msg/PoseWithCovariance'](pose=pose, covariance=cov),
                   twist=g['geometry_msgs/msg/TwistWithCovariance'](twist=twist, covariance=cov))


def _diag(t, statuses):
    """statuses: [(level, name, message, {key: value})]."""
    return T[DIAG](header=_header(t), status=[
        T['diagnostic_msgs/msg/DiagnosticStatus'](
            level=level, name=name, message=message, hardware_id='',
            values=[T['diagnostic_msgs/msg/KeyValue'](key=k, value=str(v)) for k, v in values.items()])
        for level, name, message, values in statuses])


def synthetic_signals(rate_deg_s: float, torque: np.ndarray, wheel_rate: np.ndarray):
    t = np.arange(N, dtype=float)
    theta = np.maximum(THETA0 - rate_deg_s * t, 0.0)              # deg, about body x
    half = np.radians(theta) / 2
    q = np.column_stack([np.sin(half), np.zeros(N), np.zeros(N), np.cos(half)])
    w = np.column_stack([np.where(theta > 0, -np.radians(rate_deg_s), 0.0), np.zeros(N), np.zeros(N)])
    u = np.where((t < U_ON)[:, None], torque[None, :], 0.0)        # applied torque, t = 0 .. N-2
    speed = t[:, None] * wheel_rate[None, :]
    return t, q, w, u, speed


def write_bag(path, rate_deg_s=0.3, torque=(1e-3, -2e-3, 0.5e-3), wheel_rate=(0.1, -0.2, 0.05),
              missed=0, faults=(), skip=(), chunk_size=4096, scenario=SCENARIO):
    """A bag as the graph records it (topic names, types, stamps), from known signals; ``scenario``: the
    scenario text it holds (a dynamics section with three wheels by default)."""
    torque, wheel_rate = np.asarray(torque), np.asarray(wheel_rate)
    t, q, w, u, speed = synthetic_signals(rate_deg_s, torque, wheel_rate)
    bag = BagWriter(path, chunk_size=chunk_size, metadata={'scenario': scenario})
    for name, type_name in [('/state', ODOM), ('/wheels/state', JOINTS), ('/actuators/torque', VEC),
                            ('/controller/status', DIAG), ('/dynamics/status', DIAG), ('/faults', DIAG)]:
        if name not in skip:
            bag.add_topic(name, type_name, [])

    def put(topic, msg, type_name):
        if topic not in skip:
            bag.write(topic, STORE.serialize_cdr(msg, type_name))

    faults = sorted(faults)
    for k in range(N):
        put('/state', _odometry(t[k], q[k], w[k]), ODOM)
        put('/wheels/state', T[JOINTS](header=_header(t[k]), name=['rw_x', 'rw_y', 'rw_z'],
                                       position=np.zeros(3), velocity=speed[k], effort=-torque * (t[k] < U_ON)),
            JOINTS)
        if k < N - 1:
            mode = 'slew' if t[k] < U_ON else 'coast'
            put('/controller/status', _diag(t[k], [(0, 'ctrl', '', {
                'mode': mode, 'u_x': repr(1.5 * float(u[k, 0])), 'u_y': repr(1.5 * float(u[k, 1])),
                'u_z': repr(1.5 * float(u[k, 2])),
                'lyapunov': repr(float(np.radians(max(THETA0 - rate_deg_s * t[k], 0)) ** 2)),
                'rejected_messages': 0})]), DIAG)
            put('/actuators/torque', T[VEC](header=_header(t[k]), vector=T['geometry_msgs/msg/Vector3'](
                x=u[k, 0], y=u[k, 1], z=u[k, 2])), VEC)
        for tf, level, name, message in faults:
            if tf == t[k]:
                put('/faults', _diag(t[k], [(level, name, message, {})]), DIAG)
        if k in (0, N - 1):
            put('/dynamics/status', _diag(t[k], [(0, 'dynamics', '', {
                'missed_steps': 0 if k == 0 else missed, 'mode': 'lockstep'})]), DIAG)
        if k % 20 == 0:
            bag.flush()
    bag.close()
    return path


RUNS = {  # run name -> write_bag arguments
    'run_a': dict(rate_deg_s=0.3, torque=(1e-3, -2e-3, 0.5e-3), wheel_rate=(0.1, -0.2, 0.05), missed=0,
                  faults=[(0.0, 0, 'rw_x', 'ok'), (50.0, 2, 'rw_x', 'wheel stuck'), (51.0, 2, 'rw_x', 'wheel stuck')]),
    'run_b': dict(rate_deg_s=0.15, torque=(-3e-3, 1e-3, 2e-3), wheel_rate=(0.3, 0.1, -0.1), missed=3),
}
