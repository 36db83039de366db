#!/usr/bin/env python3
"""How long does the analysis of a long run take, next to just reading its bag with rosbags?

Writes a synthetic 24-hour run at 10 Hz (864 000 control steps) into a temporary bag with
:class:`adcs_sim.bag.writer.BagWriter` (MCAP, zstd chunks of 64 KiB like the recorder), every message
serialised by rosbags from a message object. Per step, the topics and types of a run of the graph:
``/clock``, ``/state`` (nav_msgs/Odometry), ``/wheels/state`` and ``/wheels/cmd``
(sensor_msgs/JointState), ``/actuators/torque`` (geometry_msgs/Vector3Stamped) and
``/controller/status`` (diagnostic_msgs/DiagnosticArray, the PD controller's five values); and
``/dynamics/status`` at the start and the end. The attitude decays exponentially about a fixed
axis, so the settling time is known and checked.

Then it times, best of ``--repeat`` (default 1) each:

* **analysis**: ``RunData.from_bag(bag)`` + ``run_metrics(run)`` (everything ``adcs-analyze``
  computes, including the controller status records);
* **rosbags raw**: rosbags' ``AnyReader`` iterating over every message of the same bag and
  deserialising it (``reader.deserialize(raw, connection.msgtype)``), nothing else;

and prints both, their ratio (analysis / raw; the target is <= 2) and the analysis' throughput.

With ``--memory``, instead: the peak memory of ``adcs-run``'s end-of-run analysis on that bag,
each path in a fresh process that first imports what ``adcs-run`` imports (its resident set then is
the baseline): **in-memory** (``RunData.from_bag`` + ``run_metrics``, the path before issue #18
item 5, kept as the reference) and **streamed** (:func:`adcs_sim.app.analysis.stream_metrics.analyse_bag`,
what ``adcs-run`` does now), alternated ``--repeat`` times; peak RSS (``ru_maxrss``), its growth
over the baseline, wall time, and whether the two gave the same metrics (bit for bit).

Not a test (it takes minutes: most of it is writing the bag and the rosbags pass). Options:
``--hours``, ``--rate`` (Hz), ``--keep DIR`` (write the bag there and keep it), ``--bag DIR``
(time an existing bag instead of writing one; then the synthetic checks are skipped).
"""
from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adcs_sim.app.analysis.metrics import RunData, run_metrics  # noqa: E402
from adcs_sim.bag.storage import typestore  # noqa: E402
from adcs_sim.bag.writer import BagWriter  # noqa: E402

TAU = 3600.0          # s, time constant of the synthetic attitude error
ANGLE0 = math.radians(30.0)
AXIS = np.array([1.0, 2.0, 2.0]) / 3.0
_INF = {'sec': 2147483647, 'nsec': 4294967295}
QOS = [{'history': 'keep_last', 'depth': 10, 'reliability': 'reliable', 'durability': 'volatile',
        'deadline': _INF, 'lifespan': _INF, 'liveliness': 'automatic', 'liveliness_lease_duration': _INF,
        'avoid_ros_namespace_conventions': False}]


def synthetic(n: int, period: float):
    """(t, q, w, u, wheel speed) of an exponentially decaying eigenaxis rotation."""
    t = np.arange(n) * period
    angle = ANGLE0 * np.exp(-t / TAU)
    q = np.column_stack([np.outer(np.sin(angle / 2), AXIS), np.cos(angle / 2)])
    w = np.outer(-angle / TAU, AXIS)
    u = 0.01 * np.column_stack([np.sin(t / 500.0), np.cos(t / 700.0), np.sign(np.sin(t / 900.0))])
    speed = np.column_stack([100 * np.sin(t / 1000.0), 50 * np.cos(t / 800.0), 10.0 + 0 * t])
    return t, q, w, u, speed


TOPIC_TYPES = {'/clock': 'rosgraph_msgs/msg/Clock', '/state': 'nav_msgs/msg/Odometry',
               '/wheels/state': 'sensor_msgs/msg/JointState', '/wheels/cmd': 'sensor_msgs/msg/JointState',
               '/actuators/torque': 'geometry_msgs/msg/Vector3Stamped',
               '/controller/status': 'diagnostic_msgs/msg/DiagnosticArray',
               '/dynamics/status': 'diagnostic_msgs/msg/DiagnosticArray'}


class _Messages:
    """One reusable message of each recorded type (rosbags types), re-stamped at each step."""

    def __init__(self, store) -> None:
        T = self.T = store.types
        self.ser = store.serialize_cdr
        Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
        zeros3, cov = np.zeros(3), np.zeros(36)
        vec = T['geometry_msgs/msg/Vector3']
        self.odom = T['nav_msgs/msg/Odometry'](
            header=Header(stamp=Time(sec=0, nanosec=0), frame_id='inertial'), child_frame_id='body',
            pose=T['geometry_msgs/msg/PoseWithCovariance'](
                pose=T['geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
                                                 orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0,
                                                                                               w=1.0)),
                covariance=cov),
            twist=T['geometry_msgs/msg/TwistWithCovariance'](
                twist=T['geometry_msgs/msg/Twist'](linear=vec(x=0.0, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0)),
                covariance=cov))
        names = ['rw_x', 'rw_y', 'rw_z']
        self.wheels = T['sensor_msgs/msg/JointState'](header=Header(stamp=Time(sec=0, nanosec=0), frame_id=''),
                                                      name=names, position=zeros3, velocity=zeros3, effort=zeros3)
        self.cmd = T['sensor_msgs/msg/JointState'](header=Header(stamp=Time(sec=0, nanosec=0), frame_id=''),
                                                   name=names, position=np.zeros(0), velocity=np.zeros(0),
                                                   effort=zeros3)
        self.torque = T['geometry_msgs/msg/Vector3Stamped'](
            header=Header(stamp=Time(sec=0, nanosec=0), frame_id='body'), vector=vec(x=0.0, y=0.0, z=0.0))
        self.clock = T['rosgraph_msgs/msg/Clock'](clock=Time(sec=0, nanosec=0))

    def status(self, name, values):
        T = self.T
        KV, Status = T['diagnostic_msgs/msg/KeyValue'], T['diagnostic_msgs/msg/DiagnosticStatus']
        Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
        return T['diagnostic_msgs/msg/DiagnosticArray'](
            header=Header(stamp=Time(sec=0, nanosec=0), frame_id=''), status=[Status(
                level=0, name=name, message='', hardware_id='',
                values=[KV(key=k, value=v) for k, v in values.items()])])

    def dyn_status(self, k, final, stamp=None):
        msg = self.status('dynamics', {'step': str(k), 'missed_steps': '0', 'final': final})
        if stamp is not None:
            msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
        return self.ser(msg, 'diagnostic_msgs/msg/DiagnosticArray')


def _write_step(writer, m: _Messages, k: int, n: int, stamp: tuple, q, w, u, speed) -> int:
    """Step ``k``'s messages; returns how many were written."""
    sec, nsec = stamp
    for msg in (m.odom.header, m.wheels.header, m.cmd.header, m.clock):
        st = msg.stamp if hasattr(msg, 'stamp') else msg.clock
        st.sec, st.nanosec = sec, nsec
    pose, twist = m.odom.pose.pose.orientation, m.odom.twist.twist.angular
    pose.x, pose.y, pose.z, pose.w = q[k]
    twist.x, twist.y, twist.z = w[k]
    m.wheels.velocity = speed[k]
    m.wheels.effort = -u[k]
    m.cmd.effort = -u[k]
    ser = m.ser
    writer.write('/clock', ser(m.clock, 'rosgraph_msgs/msg/Clock'))
    writer.write('/state', ser(m.odom, 'nav_msgs/msg/Odometry'))
    writer.write('/wheels/state', ser(m.wheels, 'sensor_msgs/msg/JointState'))
    ctrl = m.status('pd_controller', {'mode': 'pd', 'u_x': repr(float(u[k, 0])), 'u_y': repr(float(u[k, 1])),
                                      'u_z': repr(float(u[k, 2])), 'rejected_messages': '0'})
    ctrl.header.stamp.sec, ctrl.header.stamp.nanosec = sec, nsec
    writer.write('/controller/status', ser(ctrl, 'diagnostic_msgs/msg/DiagnosticArray'))
    writer.write('/wheels/cmd', ser(m.cmd, 'sensor_msgs/msg/JointState'))
    if k == n - 1:
        return 5
    # the torque applied over [t_k, t_k+1], stamped t_k
    m.torque.header.stamp.sec, m.torque.header.stamp.nanosec = sec, nsec
    m.torque.vector.x, m.torque.vector.y, m.torque.vector.z = u[k]
    writer.write('/actuators/torque', ser(m.torque, 'geometry_msgs/msg/Vector3Stamped'))
    return 6


def write_bag(path: Path, hours: float, rate: float) -> tuple[int, tuple]:
    m = _Messages(typestore())
    period = 1.0 / rate
    n = int(round(hours * 3600 * rate)) + 1
    t, q, w, u, speed = synthetic(n, period)
    writer = BagWriter(path, chunk_size=65536)
    for name, type_name in TOPIC_TYPES.items():
        writer.add_topic(name, type_name, QOS)
    writer.write('/dynamics/status', m.dyn_status(0, 'false'))
    count = 1
    for k in range(n):
        stamp = divmod(k * int(round(period * 1e9)), 1_000_000_000)
        count += _write_step(writer, m, k, n, stamp, q, w, u, speed)
        if k % 100_000 == 0:
            print(f'  writing: {k}/{n} steps', file=sys.stderr, flush=True)
    writer.write('/dynamics/status', m.dyn_status(n - 1, 'true', stamp))
    writer.close()
    return count + 1, (t, q, w, u, speed)


def time_analysis(bag: Path):
    t0 = time.perf_counter()
    run = RunData.from_bag(bag)
    metrics = run_metrics(run)
    return time.perf_counter() - t0, run, metrics


def time_rosbags(bag: Path):
    from rosbags.highlevel import AnyReader
    t0 = time.perf_counter()
    n = 0
    with AnyReader([bag], default_typestore=typestore()) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            n += 1
    return time.perf_counter() - t0, n


def _maxrss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure_one(kind: str, bag: Path) -> None:
    """(In a fresh process) one end-of-run analysis of ``bag``: prints a JSON line."""
    import adcs_sim.app.graph.runner  # noqa: F401  (what adcs-run has imported when it analyses)
    from adcs_sim.app.analysis.metrics import jsonable_metrics
    from adcs_sim.app.analysis.stream_metrics import analyse_bag
    base = _maxrss_mib()
    t0 = time.perf_counter()
    if kind == 'in-memory':
        run = RunData.from_bag(bag)
        metrics, intrusions = run_metrics(run), run.intrusions
    else:
        result = analyse_bag(bag)
        assert result.streamed, result.reason
        metrics, intrusions = result.metrics, result.intrusions
    dt = time.perf_counter() - t0
    print(json.dumps({'kind': kind, 'base_mib': base, 'peak_mib': _maxrss_mib(), 'seconds': dt,
                      'intrusions': intrusions, 'metrics': jsonable_metrics(metrics)}))


def compare_memory(bag: Path, repeat: int) -> None:
    """Both paths, alternated, each in its own process; prints peak RSS, growth and time."""
    rows = {'in-memory': [], 'streamed': []}
    for _ in range(repeat):
        for kind in rows:
            out = subprocess.run([sys.executable, __file__, '--measure', kind, '--bag', str(bag)],
                                 capture_output=True, text=True, check=True).stdout
            rows[kind].append(json.loads(out.strip().splitlines()[-1]))
    best = {}
    for kind, runs in rows.items():
        b = best[kind] = {**min(runs, key=lambda r: r['peak_mib']), 'seconds': min(r['seconds'] for r in runs)}
        print(f'{kind:<10} peak RSS {b["peak_mib"]:7.1f} MiB  (baseline after imports {b["base_mib"]:6.1f}, '
              f'growth {b["peak_mib"] - b["base_mib"]:7.1f})  {b["seconds"]:6.2f} s')
    a, b = best['in-memory'], best['streamed']
    grow = (a['peak_mib'] - a['base_mib']) / max(b['peak_mib'] - b['base_mib'], 1e-9)
    print(f'ratio in-memory / streamed (best of {repeat}): peak {a["peak_mib"] / b["peak_mib"]:.2f}, '
          f'growth {grow:.1f}; time {a["seconds"] / b["seconds"]:.2f}')
    a = rows['in-memory'][0]
    same = all(json.dumps(r['metrics']) == json.dumps(a['metrics']) and r['intrusions'] == a['intrusions']
               for runs in rows.values() for r in runs)
    print(f'metrics and intruders equal (bit for bit, key order): {same}')


def check_synthetic(run, metrics: dict, truth: tuple, n_raw: int, rate: float) -> None:
    """Assert that the analysis read the synthetic series back and found its settling time."""
    t, q, w, u, speed = truth
    assert np.allclose(run.t, t, rtol=0, atol=1e-9)  # stamps are integer ns
    assert np.array_equal(run.q, q) and np.array_equal(run.w, w)
    assert np.array_equal(run.u, u[:-1]) and np.array_equal(run.wheel_speed, speed)
    assert n_raw == run.message_count and len(run.controller_status) == len(t)
    assert run.controller_status[-1][2]['u_z'] == repr(float(u[-1, 2]))
    expected = TAU * math.log(30.0 / 0.5)   # eigenaxis error 30 deg * exp(-t / TAU) = 0.5 deg
    got = metrics['settling_eigenaxis_0.5deg_s']
    period = 1.0 / rate
    if expected < t[-1]:
        assert 0 <= got - expected <= period ** 2 / (8 * TAU) + 1e-6, (got, expected)
    else:
        assert got == math.inf, got
    print(f'checked: RunData equals the synthetic series; settling {got:.4f} s '
          f'(exact {expected:.4f} s)')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--memory', action='store_true', help='peak memory: in-memory vs streamed analysis')
    parser.add_argument('--measure', choices=('in-memory', 'streamed'), help=argparse.SUPPRESS)
    parser.add_argument('--hours', type=float, default=24.0)
    parser.add_argument('--rate', type=float, default=10.0, help='control rate, Hz')
    parser.add_argument('--repeat', type=int, default=1)
    parser.add_argument('--keep', type=Path, default=None, help='write the bag here and keep it')
    parser.add_argument('--bag', type=Path, default=None, help='time an existing bag')
    args = parser.parse_args(argv)
    if args.measure:
        measure_one(args.measure, args.bag)
        return 0
    tmp = None
    truth = None
    try:
        if args.bag:
            bag = args.bag
        else:
            if args.keep:
                bag = args.keep
            else:
                tmp = Path(tempfile.mkdtemp(prefix='adcs_analysis_speed_'))
                bag = tmp / 'bag'
            t0 = time.perf_counter()
            written, truth = write_bag(bag, args.hours, args.rate)
            size = sum(f.stat().st_size for f in bag.iterdir())
            print(f'bag: {bag} ({args.hours:g} h at {args.rate:g} Hz: {len(truth[0])} state messages, '
                  f'{written} messages, {size / 1e6:.0f} MB; written in {time.perf_counter() - t0:.0f} s)')
        if args.memory:
            compare_memory(bag, args.repeat)
            return 0
        analysis, raw = [], []
        for _ in range(args.repeat):
            dt, run, metrics = time_analysis(bag)
            analysis.append(dt)
            dt_raw, n_raw = time_rosbags(bag)
            raw.append(dt_raw)
        if truth is not None:
            check_synthetic(run, metrics, truth, n_raw, args.rate)
        a, r = min(analysis), min(raw)
        print(f'messages: {run.message_count} ({run.t.size} state)')
        print(f'analysis (RunData.from_bag + run_metrics): {a:8.2f} s   '
              f'({run.message_count / a / 1e6:.2f} M messages/s)')
        print(f'rosbags raw (AnyReader + deserialize):     {r:8.2f} s   '
              f'({n_raw / r / 1e6:.2f} M messages/s)')
        print(f'ratio analysis / raw: {a / r:.3f}  (target <= 2)')
        if args.repeat > 1:
            print('  per repeat: analysis ' + ', '.join(f'{x:.2f}' for x in analysis)
                  + ' s; raw ' + ', '.join(f'{x:.2f}' for x in raw) + ' s')
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
