#!/usr/bin/env python3
"""CPU a recorded message costs the recorder's process, under each rclpy executor (issue #18 item 3).

One leased ROS domain (loopback discovery). A publisher process sends ``--messages`` raw-sized
``nav_msgs/Odometry`` on four reliable topics, waiting for every reader's acknowledgement every 50
(as the dynamics node paces the recorder); a subscriber process takes them through raw,
message-only subscriptions, as the recorder does, spun by rclpy's single-threaded executor and then
by its C++ events executor (what ``RecorderNode.executor_class`` picks). Prints the subscriber's CPU
time per message for each and their ratio, measured in the same run.

    .venv/bin/python benchmarks/recorder_executor.py [--messages 8000]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TOPICS = 4


def _qos():
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_ALL)


def publish(n: int) -> None:
    import rclpy
    from nav_msgs.msg import Odometry
    rclpy.init()
    node = rclpy.create_node('bench_publisher')
    pubs = [node.create_publisher(Odometry, f'bench_{i}', _qos()) for i in range(TOPICS)]
    while any(p.get_subscription_count() < 1 for p in pubs):
        rclpy.spin_once(node, timeout_sec=0.05)
    msg = Odometry()
    for k in range(n // TOPICS):
        for p in pubs:
            p.publish(msg)
        if k % 50 == 49:
            for p in pubs:
                p.wait_for_all_acked()
    for p in pubs:
        p.wait_for_all_acked()
    print('published', flush=True)
    sys.stdin.readline()   # until the subscriber is done


def subscribe(n: int, executor_name: str) -> None:
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    rclpy.init()
    node = rclpy.create_node('bench_subscriber')
    got = [0]

    def on_message(data) -> None:
        got[0] += 1
    subs = [node.create_subscription(Odometry, f'bench_{i}', on_message, _qos(), raw=True) for i in range(TOPICS)]
    executor = EventsExecutor() if executor_name == 'events' else SingleThreadedExecutor()
    executor.add_node(node)
    print('ready', flush=True)
    deadline = time.monotonic() + 120
    cpu0 = None
    while got[0] < n and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
        if cpu0 is None and got[0]:
            cpu0, first = time.process_time(), got[0]
    cpu = time.process_time() - cpu0
    print(f'{executor_name} {got[0]} {cpu / max(got[0] - first, 1) * 1e6:.1f}', flush=True)
    del subs


def measure(env: dict, n: int, executor_name: str) -> tuple[int, float]:
    sub = subprocess.Popen([sys.executable, __file__, '--role', 'subscribe', '--executor', executor_name,
                            '--messages', str(n)], env=env, stdout=subprocess.PIPE, text=True)
    assert sub.stdout.readline().strip() == 'ready'
    pub = subprocess.Popen([sys.executable, __file__, '--role', 'publish', '--messages', str(n)], env=env,
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        _, got, us = sub.stdout.readline().split()
    finally:
        pub.communicate('\n', timeout=60)
        sub.wait(timeout=60)
    return int(got), float(us)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--messages', type=int, default=8000)
    parser.add_argument('--role', choices=['publish', 'subscribe'], default=None, help=argparse.SUPPRESS)
    parser.add_argument('--executor', default='single', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == 'publish':
        publish(args.messages)
        return 0
    if args.role == 'subscribe':
        subscribe(args.messages, args.executor)
        return 0
    from adcs_sim.app.graph.domains import DomainLease
    lease = DomainLease()
    try:
        env = lease.env()
        print(f'ROS_DOMAIN_ID={lease.domain_id} (leased), ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, '
              f'{args.messages} Odometry messages on {TOPICS} topics')
        results = {name: measure(env, args.messages, name) for name in ('single', 'events')}
    finally:
        lease.release()
    for name, (got, us) in results.items():
        print(f'  {name:>6} executor: {us:7.1f} us CPU a message ({got} received)')
    print(f'  ratio single / events: {results["single"][1] / results["events"][1]:.2f}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
