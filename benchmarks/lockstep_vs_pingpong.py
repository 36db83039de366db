#!/usr/bin/env python3
"""How close does the lockstep loop come to the transport's own round-trip rate?

One run measures, on one leased ROS domain (loopback discovery, Fast DDS default transports, i.e.
shared memory allowed):

(i)  **ping-pong**: two separate processes; A publishes a ``nav_msgs/Odometry`` (the ``state``
     message type), B echoes it back, A waits for the echo before sending the next. Same QoS as
     the lockstep topics (:data:`adcs_msgs_py.topics.QOS_LOCKSTEP`), ``SingleThreadedExecutor``
     driven by ``spin_once`` as the dynamics node does. Round trips per wall second over
     ``--round-trips`` after ``--warmup`` (default 2000 after 200).
(ii) **lockstep**: ``dynamics`` and ``pd_controller`` as separate processes on
     ``config/microsat_pd_slew.yaml`` with ``-p duration:=<--duration>`` (default 3000 s = 3000
     steps). The stepping loop is timed without touching it, by a passive observer process
     subscribed to ``dynamics/status`` only. The dynamics node publishes that status right before
     step 0 (after the graph is connected: process start-up and DDS discovery are over), on a
     missed step, and right after the last step; so the observer adds no work to the loop, and
     the loop time is (receipt of the final status) - (receipt of the first one), on one clock,
     with the same delivery latency at both ends. Start order: observer, dynamics, then - once
     the observer has discovered the dynamics' status publisher - the controller; the dynamics
     node starts stepping only when the controller is connected, so the observer sees both.
     Not the ``done at`` log line: it comes after ``wait_for_all_acked`` on the publishers, which
     with Fast DDS' default 3 s heartbeat period adds up to 3 s (measured 3.006 s after 3000
     steps). Fallbacks, flagged in the output: the ``lockstep run:`` / ``done at`` INFO lines'
     rcutils timestamps.
(iii) the default scenario (600 simulated s) the same way: its real-time factor is
     600 s / wall seconds of the stepping loop.

Ping-pong and lockstep are measured ``--repeat`` times (default 3), alternating, and their
medians compared: on a shared machine the load changes from one second to the next.

It prints both rates and ``ratio = lockstep steps/s / ping-pong round trips/s``: a lockstep step
is at least one round trip (state out, command back), so 1.0 is the ceiling and the gap is what
the nodes spend besides the transport (conversions, validation, plant, extra publications).

``--profile DIR`` also runs the lockstep pair under cProfile (``DIR/dynamics.prof``,
``DIR/pd_controller.prof``) and prints the top functions of each.

Every child runs in its own session and is stopped by its pid on the way out (SIGINT, then
SIGTERM, then SIGKILL), also on Ctrl-C or SIGTERM of this script.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SCENARIO = ROOT / 'config' / 'microsat_pd_slew.yaml'
LOG_FORMAT = '[{severity}] [{time}] [{name}]: {message}'
LOG_LINE = re.compile(r'^\[(?P<sev>\w+)\] \[(?P<time>[\d.]+)\] \[(?P<name>[^\]]+)\]: (?P<msg>.*)$')
PING, PONG = 'bench/ping', 'bench/pong'

_children: list[subprocess.Popen] = []


# --- process handling ---------------------------------------------------------------------------

def _spawn(cmd: list[str], env: dict, **kwargs) -> subprocess.Popen:
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, start_new_session=True, text=True, **kwargs)
    _children.append(proc)
    return proc


def _stop(proc: subprocess.Popen, grace: float = 5.0) -> None:
    """SIGINT (clean rclpy shutdown, no shm leftovers), then SIGTERM, then SIGKILL — by pid."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            return
        try:
            os.kill(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            continue


def _stop_all() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the clean-up short
    for proc in reversed(_children):
        _stop(proc)
    for proc in _children:  # close pipes
        try:
            proc.communicate(timeout=1.0)
        except (subprocess.TimeoutExpired, ValueError, OSError):
            pass


def _on_sigterm(signum, frame):
    raise KeyboardInterrupt


EXECUTOR_ENV = 'PINGPONG_EXECUTOR'   # the roles' executor: 'rclpy' (default) or 'lockstep'


# --- (i) ping-pong roles (run in child processes) --------------------------------------------------

@contextlib.contextmanager
def _role_node(name: str, interruptible: bool = True):
    """(node, executor) on a private context; Ctrl-C / SIGTERM end the role quietly when
    ``interruptible``; the node and context are always cleaned up. ``PINGPONG_EXECUTOR=lockstep``
    in the environment: the nodes' own executor (adcs_msgs_py.executor.LockstepExecutor) on a node
    made as AdcsNode makes them (no parameter or type-description services); otherwise rclpy's
    ``SingleThreadedExecutor`` on a default node."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions

    from adcs_msgs_py.executor import LockstepExecutor
    lockstep = os.environ.get(EXECUTOR_ENV) == 'lockstep'

    context = Context()
    # A non-default context gets no signal handlers by default: SIGINT would then wait for
    # spin() to wake up. Install them, as adcs_msgs_py.node.main_for does.
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.ALL)
    lean = {'start_parameter_services': False,
            'parameter_overrides': [Parameter('start_type_description_service', value=False)]} if lockstep else {}
    node = rclpy.create_node(name, context=context, **lean)
    executor = (LockstepExecutor if lockstep else SingleThreadedExecutor)(context=context)
    executor.add_node(node)
    quiet = (KeyboardInterrupt, ExternalShutdownException) if interruptible else ()
    try:
        yield node, executor
    except quiet:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _wait(ready, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        if time.monotonic() > deadline:
            raise SystemExit(f'timed out after {timeout:g} s waiting for {what}')
        time.sleep(0.005)


def role_echo() -> int:
    """B: echo every ping back; subscribe only once the pong publisher is matched (as controllers)."""
    from nav_msgs.msg import Odometry

    from adcs_msgs_py.topics import QOS_LOCKSTEP

    with _role_node('bench_echo') as (node, executor):
        pub = node.create_publisher(Odometry, PONG, QOS_LOCKSTEP)
        _wait(lambda: pub.get_subscription_count() >= 1, 30.0, 'the pinger to subscribe')
        node.create_subscription(Odometry, PING, pub.publish, QOS_LOCKSTEP)
        executor.spin()
    return 0


def role_ping(round_trips: int, warmup: int) -> int:
    """A: publish, spin_once until the echo of that message is back, repeat; print JSON result."""
    from nav_msgs.msg import Odometry

    from adcs_msgs_py.topics import QOS_LOCKSTEP

    got = {'seq': -1}

    def on_pong(msg):
        got['seq'] = msg.header.stamp.nanosec

    with _role_node('bench_ping', interruptible=False) as (node, executor):
        pub = node.create_publisher(Odometry, PING, QOS_LOCKSTEP)
        node.create_subscription(Odometry, PONG, on_pong, QOS_LOCKSTEP)
        _wait(lambda: pub.get_subscription_count() >= 1, 30.0, 'the echo to subscribe')
        msg = Odometry()
        msg.header.frame_id = 'inertial'
        msg.child_frame_id = 'body'
        msg.pose.pose.orientation.w = 1.0
        t0 = None
        for i in range(warmup + round_trips):
            if i == warmup:
                t0 = time.perf_counter()
            msg.header.stamp.nanosec = i
            pub.publish(msg)
            deadline = time.monotonic() + 5.0
            while got['seq'] != i:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise SystemExit(f'echo {i} did not come back within 5 s')
                executor.spin_once(timeout_sec=remaining)
        elapsed = time.perf_counter() - t0
        print(json.dumps({'round_trips': round_trips, 'seconds': elapsed}), flush=True)
    return 0


def role_status_observer() -> int:
    """Print (JSON lines) 'ready', 'matched' once a dynamics/status publisher is discovered, then the
    wall-clock receipt time of every ``dynamics/status`` message."""
    from adcs_msgs_py import topics
    from adcs_msgs_py.conversions import status_values

    s = topics.spec(topics.DYNAMICS_STATUS)

    def on_status(msg):
        now = time.time()  # CLOCK_REALTIME, the clock of rcutils' log timestamps
        final = any(status_values(st).get('final') == 'true' for st in msg.status)
        print(json.dumps({'wall': now, 'final': final}), flush=True)

    with _role_node('bench_status_observer') as (node, executor):
        sub = node.create_subscription(s.msg_type, s.name, on_status, s.qos)
        print(json.dumps({'ready': True}), flush=True)
        while sub.get_publisher_count() < 1:
            executor.spin_once(timeout_sec=0.01)
        print(json.dumps({'matched': True}), flush=True)
        executor.spin()
    return 0


class _Lines:
    """Lines of a child's stdout, read by a thread, so the parent can wait with a timeout."""

    def __init__(self, stream) -> None:
        self.queue: queue.Queue = queue.Queue()
        self.lines: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self.thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.queue.put(line)
        self.queue.put(None)

    def wait_for(self, key: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.queue.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise RuntimeError(f'status observer: no {key!r} within {timeout:g} s') from None
            if line is None:
                raise RuntimeError(f'status observer exited before {key!r}')
            self.lines.append(line)
            if key in line:
                return

    def rest(self) -> list[dict]:
        self.thread.join(timeout=5.0)
        while not self.queue.empty():
            line = self.queue.get()
            if line is not None:
                self.lines.append(line)
        return [json.loads(line) for line in self.lines if line.strip()]


def run_pingpong(env: dict, round_trips: int, warmup: int, executor: str = 'rclpy') -> dict:
    """Round trips/s of the ping-pong; ``executor`` 'rclpy' (rclpy's SingleThreadedExecutor, the
    issue's "raw rclpy ping-pong") or 'lockstep' (the graph nodes' LockstepExecutor)."""
    me = [sys.executable, str(Path(__file__).resolve())]
    env = {**env, EXECUTOR_ENV: executor}
    echo = _spawn(me + ['--role', 'echo'], env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ping = _spawn(me + ['--role', 'ping', '--round-trips', str(round_trips), '--warmup', str(warmup)],
                  env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = ping.communicate(timeout=300)
    _stop(echo)
    if ping.returncode != 0:
        raise RuntimeError(f'ping process failed ({ping.returncode}):\n{err}')
    result = json.loads(out.strip().splitlines()[-1])
    result['rate'] = result['round_trips'] / result['seconds']
    return result


# --- (ii)/(iii) lockstep dynamics <-> pd_controller -------------------------------------------------

def _node_cmd(module: str, overrides: list[str], profile: Path | None) -> list[str]:
    cmd = [sys.executable]
    if profile is not None:
        cmd += ['-m', 'cProfile', '-o', str(profile)]
    cmd += ['-m', module, '--ros-args', '--params-file', str(SCENARIO)]
    for o in overrides:
        cmd += ['-p', o]
    return cmd


def _parse_dynamics_log(text: str) -> dict:
    start = done = None
    steps = missed = None
    for line in text.splitlines():
        m = LOG_LINE.match(line.strip())
        if not m or m['name'] != 'dynamics':
            continue
        if m['msg'].startswith('lockstep run:'):
            start = float(m['time'])
            steps = int(re.search(r'run: (\d+) steps', m['msg'])[1])
        elif m['msg'].startswith('done at'):
            done = float(m['time'])
            missed = int(re.search(r'missed steps: (\d+)', m['msg'])[1])
    if start is None or done is None:
        raise RuntimeError(f"no 'lockstep run:' / 'done at' lines in the dynamics log:\n{text[-2000:]}")
    return {'steps': steps, 'start': start, 'done': done, 'missed_steps': missed}


def run_lockstep(env: dict, duration: float, profile_dir: Path | None = None) -> dict:
    """Start order: observer, dynamics, then — once the observer has discovered the dynamics'
    status publisher — the controller. Dynamics starts stepping only when the controller is
    connected, so by then the observer is matched too and sees the first and the final status."""
    prof = (lambda name: profile_dir / f'{name}.prof') if profile_dir else (lambda name: None)
    me = [sys.executable, str(Path(__file__).resolve())]
    observer_log = tempfile.TemporaryFile('w+')
    observer = _spawn(me + ['--role', 'observer'], env, stdout=subprocess.PIPE, stderr=observer_log)
    lines = _Lines(observer.stdout)
    lines.wait_for('ready', 60.0)
    wall0 = time.monotonic()
    dynamics = _spawn(_node_cmd('adcs_sim.nodes.dynamics', [f'duration:={duration!r}'], prof('dynamics')),
                      env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    lines.wait_for('matched', 60.0)
    controller_log = tempfile.TemporaryFile('w+')  # a file, not a pipe: a full pipe would block it
    controller = _spawn(_node_cmd('adcs_controllers.nodes.pd_controller', [], prof('pd_controller')),
                        env, stdout=subprocess.DEVNULL, stderr=controller_log)
    log, _ = dynamics.communicate(timeout=max(120.0, duration))
    process_wall = time.monotonic() - wall0
    _stop(controller)
    _stop(observer)
    seen = lines.rest()
    controller_log.seek(0)
    controller_err = controller_log.read()
    controller_log.close()
    if dynamics.returncode != 0:
        raise RuntimeError(f'dynamics exited {dynamics.returncode}:\n{log[-2000:]}\n'
                           f'controller:\n{controller_err[-2000:]}')
    result = _parse_dynamics_log(log)
    statuses = [e for e in seen if 'wall' in e]
    final = [e['wall'] for e in statuses if e['final']]
    first = [e['wall'] for e in statuses if not e['final']]
    result['start_source'] = 'first dynamics/status' if first else "'lockstep run:' log line"
    result['end_source'] = 'final dynamics/status' if final else "'done at' log line (observer missed it)"
    if not final:
        observer_log.seek(0)
        print(f'warning: status observer did not see the final status (saw {seen}); '
              f'{observer_log.read()[-1500:]}', file=sys.stderr)
    observer_log.close()
    start = first[0] if first else result['start']
    end = final[-1] if final else result['done']
    result['seconds'] = end - start
    result['drain'] = result['done'] - end
    result['log_vs_status_start'] = (first[0] - result['start']) if first else float('nan')
    result['rate'] = result['steps'] / result['seconds']
    result['process_wall'] = process_wall
    return result


def print_profile(path: Path, top: int = 25) -> None:
    import pstats
    print(f'\n--- {path.name}: top {top} by own time ---')
    stats = pstats.Stats(str(path))
    stats.sort_stats('tottime').print_stats(top)


# --- main -------------------------------------------------------------------------------------------

def _parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--role', choices=['echo', 'ping', 'observer'], help=argparse.SUPPRESS)
    ap.add_argument('--round-trips', type=int, default=2000)
    ap.add_argument('--warmup', type=int, default=200)
    ap.add_argument('--duration', type=float, default=3000.0,
                    help='simulated seconds of the long lockstep run (1 step per s)')
    ap.add_argument('--repeat', type=int, default=3,
                    help='alternating ping-pong / lockstep measurements; medians are compared')
    ap.add_argument('--profile', type=Path, metavar='DIR',
                    help='also run the lockstep pair under cProfile, writing DIR/<node>.prof')
    return ap.parse_args()


def _measure(env: dict, args) -> None:
    """The alternating ping-pong / lockstep repeats, the default run, the medians and the ratio."""
    pps, lss = [], []
    for i in range(args.repeat):  # alternate, so that a change of machine load hits both
        tag = f'[{i + 1}/{args.repeat}]'
        pp = run_pingpong(env, args.round_trips, args.warmup)
        pps.append(pp['rate'])
        print(f'{tag} ping-pong : {pp["round_trips"]} round trips of nav_msgs/Odometry in '
              f'{pp["seconds"]:.3f} s -> {pp["rate"]:.0f} round trips/s ({1e6 / pp["rate"]:.0f} us each)',
              flush=True)
        ls = run_lockstep(env, args.duration)
        lss.append(ls['rate'])
        print(f'{tag} lockstep  : {ls["steps"]} steps in {ls["seconds"]:.3f} s of stepping loop '
              f'-> {ls["rate"]:.0f} steps/s ({1e6 / ls["rate"]:.0f} us each); missed steps '
              f'{ls["missed_steps"]}; timed from {ls["start_source"]} to {ls["end_source"]}; '
              f'then {ls["drain"]:.3f} s until \'done at\' (ack wait); '
              f'dynamics process {ls["process_wall"]:.2f} s in all', flush=True)
    dflt = run_lockstep(env, 600.0)
    print(f'default run : {dflt["steps"]} steps (600 simulated s) in {dflt["seconds"]:.3f} s of stepping '
          f'loop -> real-time factor {600.0 / dflt["seconds"]:.0f}x (missed steps '
          f'{dflt["missed_steps"]}; dynamics process incl. start-up and ack wait '
          f'{dflt["process_wall"]:.2f} s -> {600.0 / dflt["process_wall"]:.0f}x end to end)', flush=True)
    pp_rate, ls_rate = statistics.median(pps), statistics.median(lss)
    print(f'median      : ping-pong {pp_rate:.0f} round trips/s, lockstep {ls_rate:.0f} steps/s '
          f'(of {args.repeat})')
    print(f'ratio       : lockstep steps/s / ping-pong round trips/s = {ls_rate / pp_rate:.3f} '
          f'(per repeat: {", ".join(f"{b / a:.3f}" for a, b in zip(pps, lss))})', flush=True)
    if args.profile:
        args.profile.mkdir(parents=True, exist_ok=True)
        prof = run_lockstep(env, args.duration, args.profile)
        print(f'\nprofiled lockstep: {prof["rate"]:.0f} steps/s under cProfile')
        for name in ('dynamics', 'pd_controller'):
            print_profile(args.profile / f'{name}.prof')


def main() -> int:
    args = _parse_args()
    if args.role == 'echo':
        return role_echo()
    if args.role == 'ping':
        return role_ping(args.round_trips, args.warmup)
    if args.role == 'observer':
        return role_status_observer()

    from adcs_sim.app.graph.domains import DomainLease

    signal.signal(signal.SIGINT, signal.default_int_handler)  # even if started with SIGINT ignored
    signal.signal(signal.SIGTERM, _on_sigterm)
    lease = DomainLease()
    env = lease.env()
    env.pop('FASTDDS_BUILTIN_TRANSPORTS', None)  # Fast DDS defaults: SHM + UDPv4 (loopback)
    env['RCUTILS_CONSOLE_OUTPUT_FORMAT'] = LOG_FORMAT
    env['PYTHONUNBUFFERED'] = '1'
    load = ' '.join(f'{x:.2f}' for x in os.getloadavg())
    print(f'ROS_DOMAIN_ID={lease.domain_id} (leased), ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, '
          f'Fast DDS default transports; python {sys.version.split()[0]}; {os.cpu_count()} CPUs, '
          f'load average {load}', flush=True)
    try:
        _measure(env, args)
    except KeyboardInterrupt:
        print('interrupted; stopping child processes', file=sys.stderr)
        return 130
    finally:
        _stop_all()
        lease.release()
    return 0


if __name__ == '__main__':
    sys.exit(main())
