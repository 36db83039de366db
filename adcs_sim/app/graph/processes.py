"""The node processes of one run: started, watched and stopped in order; the run's progress bar on
``/clock``; the run's environment and domain lease."""
from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from adcs_msgs_py.node import RUNNER_PID_ENV, network_hygiene_defaults
from adcs_sim.app.graph.domains import DomainLease
from adcs_sim.app.scenario.files import RunError

# rclpy's executor and message modules, tqdm and the bag reader are imported where they are used
# (Progress, recorded_state): `adcs-run` without a progress bar (not a terminal, tests,
# benchmarks) never creates a participant of its own, and starts its nodes sooner.

STOP_TIMEOUT_S = 20.0
PROGRESS_NODE = 'adcs_run_progress'   # the runner's own /clock subscriber (a node of the run)


# A folder in the runner's environment: every node runs under cProfile, writing <folder>/<node>.prof
# (benchmarks/showcase_graph.py --profile: where each process of the full graph spends its time).
PROFILE_ENV = 'ADCS_SIM_PROFILE_DIR'


def node_command(name: str, module: str) -> list[str]:
    """The interpreter arguments that run node ``module``: ``-m adcs_sim.app.graph.launch <module>``
    (:mod:`adcs_sim.app.graph.launch`: the process ends as soon as the node has shut down), or under
    cProfile (``-m cProfile -o <file> -m <module>``) when :data:`PROFILE_ENV` is set."""
    folder = os.environ.get(PROFILE_ENV)
    if folder:
        return ['-m', 'cProfile', '-o', str(Path(folder) / f'{name}.prof'), '-m', module]
    return ['-m', 'adcs_sim.app.graph.launch', module]


class Graph:
    """The node processes of one run, started and stopped in order.

    Each node dies with the runner (:data:`~adcs_msgs_py.node.RUNNER_PID_ENV`: the node sets the
    parent-death signal at start) and holds the domain lease's lock (``keep_fds``) until it exits."""

    def __init__(self, env: dict, log_dir: Path, keep_fds: tuple[int, ...] = ()) -> None:
        self.env = {**env, RUNNER_PID_ENV: str(os.getpid())}
        self.keep_fds = keep_fds
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs: dict[str, Path] = {}
        self.commands: dict[str, tuple[str, list[str]]] = {}   # name -> (module, args), for restarts
        self.signals: list[int] = []   # SIGINT / SIGTERM received by the runner
        self.stopping = False          # shutdown under way: a signal no longer interrupts it
        self._pidfds: dict[str, int] = {}

    def on_signal(self, signum, frame) -> None:  # noqa: ARG002
        """The runner's SIGINT/SIGTERM handler: only records the signal. The run loop notices it
        at its next safe point (:meth:`check`), never between starting a process and recording
        it, and never in the middle of stopping the graph (a second Ctrl-C does not abort the
        shutdown and leave processes behind)."""
        self.signals.append(signum)

    def check(self) -> None:
        """Raise KeyboardInterrupt if a signal came and the graph is not already stopping."""
        if self.signals and not self.stopping:
            raise KeyboardInterrupt

    def start(self, name: str, module: str, args: list[str]) -> subprocess.Popen:
        log = self.log_dir / f'{name}.log'
        self.logs[name] = log
        self.commands[name] = (module, args)
        with open(log, 'wb') as f:
            proc = subprocess.Popen([sys.executable, *node_command(name, module), '--ros-args', *args],
                                    stdout=f, stderr=subprocess.STDOUT, env=self.env,
                                    stdin=subprocess.DEVNULL, start_new_session=True, pass_fds=self.keep_fds)
        old_fd = self._pidfds.pop(name, None)   # a restarted node's: its old process's
        if old_fd is not None:
            os.close(old_fd)
        self.procs[name] = proc
        return proc

    def wait_exit(self, timeout: float) -> None:
        """Return as soon as a process of the graph exits (its pidfd becomes readable), or after
        ``timeout`` s: no polling. A signal to the runner does not cut the wait short (its handler
        only records it, :meth:`on_signal`); the caller's next :meth:`check` acts on it."""
        fds = [fd for fd in (self._pidfd(n) for n in self.procs) if fd is not None]
        if len(fds) < sum(p.returncode is None for p in self.procs.values()):
            time.sleep(timeout)   # no pidfd for a live process (kernel < 5.3): a plain wait
            return
        if fds:
            select.select(fds, [], [], timeout)
        else:
            time.sleep(timeout)

    def _pidfd(self, name: str) -> int | None:
        """A pidfd of process ``name`` while it has not been reaped, else None."""
        proc = self.procs[name]
        if proc.returncode is not None:
            fd = self._pidfds.pop(name, None)
            if fd is not None:
                os.close(fd)
            return None
        if name not in self._pidfds:
            try:
                self._pidfds[name] = os.pidfd_open(proc.pid)
            except (AttributeError, OSError):   # no pidfd_open here, or already reaped
                return None
        return self._pidfds[name]

    def close(self) -> None:
        """Close the pidfds (the processes are stopped: :meth:`stop_all`)."""
        for fd in self._pidfds.values():
            os.close(fd)
        self._pidfds.clear()

    def log_tail(self, name: str, lines: int = 15) -> str:
        try:
            text = self.logs[name].read_text(errors='replace').strip().splitlines()
        except OSError:
            return ''
        return '\n'.join(text[-lines:])

    def wait_for_line(self, name: str, line: str, timeout: float) -> None:
        """Wait until process ``name`` prints ``line`` (it is alive and ready)."""
        deadline = time.monotonic() + timeout
        proc = self.procs[name]
        while line not in self.logs[name].read_text(errors='replace'):
            self.check()
            if proc.poll() is not None:
                raise RunError(f'{name} exited with status {proc.returncode} at start:\n{self.log_tail(name)}')
            if time.monotonic() > deadline:
                raise RunError(f'{name} not ready after {timeout:g} s:\n{self.log_tail(name)}')
            time.sleep(0.02)

    def restart(self, name: str, attempt: int) -> subprocess.Popen:
        """Start a dead node again with the same command line; its old log is kept as
        ``<name>.<attempt>.log``."""
        self.logs[name].rename(self.log_dir / f'{name}.{attempt}.log')
        return self.start(name, *self.commands[name])

    def describe_exit(self, name: str) -> str:
        """``'<name> exited with status N'`` or ``'<name> was killed by SIGKILL'``."""
        code = self.procs[name].returncode
        if code is not None and code < 0:
            try:
                return f'{name} was killed by {signal.Signals(-code).name}'
            except ValueError:
                pass
        return f'{name} exited with status {code}'

    def failed(self, names) -> tuple[str, int] | None:
        """The first of ``names`` that has exited (name, status), or None."""
        for name in names:
            code = self.procs[name].poll()
            if code is not None:
                return name, code
        return None

    def stop(self, name: str, timeout: float = STOP_TIMEOUT_S) -> int | None:
        """SIGINT, then SIGKILL after ``timeout``; returns the exit status."""
        return self.stop_together([name], timeout).get(name)

    def stop_together(self, names, timeout: float = STOP_TIMEOUT_S) -> dict[str, int]:
        """SIGINT to every one of ``names`` at once, then SIGKILL to those still running after
        ``timeout``; returns their exit statuses (the nodes shut down side by side, not one
        after the other)."""
        procs = {n: self.procs[n] for n in names if n in self.procs}
        for proc in procs.values():
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + timeout
        for name, proc in procs.items():
            if not self._wait_one(name, deadline):
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        return {n: p.returncode for n, p in procs.items()}

    def _wait_one(self, name: str, deadline: float) -> bool:
        """Wait until process ``name`` exits (its pidfd; Popen.wait's own timeout polls), at most
        until ``deadline`` (monotonic); whether it exited (reaped)."""
        proc = self.procs[name]
        fd = self._pidfd(name)
        if fd is not None:
            select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        try:
            proc.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            return False
        self._pidfd(name)   # closes it
        return True

    def stop_all(self, recorder_last: str | None = 'recorder') -> None:
        self.stopping = True
        self.stop_together([n for n in self.procs if n != recorder_last])
        if recorder_last in self.procs:
            self.stop(recorder_last)


# What a participant of the run takes from the environment when it is created (rcl_init, rmw).
PARTICIPANT_ENV = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS', 'ROS_LOCALHOST_ONLY',
                   'FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_BUILTIN_TRANSPORTS')


@contextmanager
def run_environment(env: dict):
    """``os.environ`` as a node of the run sees it (``env``: :func:`graph_env`) while the runner
    creates its own participant, restored afterwards (the runner may run several scenarios)."""
    saved = {k: os.environ.get(k) for k in PARTICIPANT_ENV}
    try:
        for k in PARTICIPANT_ENV:
            if k in env:
                os.environ[k] = env[k]
            else:
                os.environ.pop(k, None)
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class SimTimeBar:
    """The progress bar in simulated seconds (tqdm, on stderr): :meth:`advance` to the latest
    simulated time seen, :meth:`complete` when the run reached its end. The runner sees only some
    ``/clock`` ticks (the latest one, a few times a second), so the last it sees is a step or a
    few before the end: a completed run is shown at 100 %, an interrupted one where it stopped."""

    def __init__(self, duration: float, enabled: bool = True, file=None) -> None:
        # lazy: tqdm (0.1 s): only when a progress bar is shown
        from tqdm import tqdm
        self.total = float(duration)
        self.sim_time = 0.0
        self.bar = tqdm(total=self.total, unit='sim s', disable=not enabled, dynamic_ncols=True, file=file,
                        bar_format='{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]')

    def advance(self, t: float) -> None:
        """The run has reached simulated time ``t`` (s): the bar moves forward to it, never back."""
        if t > self.sim_time:
            self.bar.update(t - self.sim_time)
            self.sim_time = t

    def complete(self) -> None:
        """The run reached its end: the bar shows the whole duration (100 %)."""
        self.advance(self.total)
        self.bar.n = self.total   # exactly: the updates' float sum may fall an ulp short
        self.bar.refresh()

    def close(self) -> None:
        self.bar.close()


class Progress:
    """/clock subscriber driving a :class:`SimTimeBar`. Its participant is one of the run's: the
    run's domain and discovery range (``env``), not the shell's."""

    def __init__(self, duration: float, enabled: bool, env: dict) -> None:
        # lazy: rclpy (0.3 s): only when a progress bar is shown
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock
        self.context = Context()
        with run_environment(env):
            rclpy.init(context=self.context, domain_id=int(env['ROS_DOMAIN_ID']),
                       signal_handler_options=SignalHandlerOptions.NO)
            self.node = rclpy.create_node(PROGRESS_NODE, context=self.context,
                                          start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.bar = SimTimeBar(duration, enabled)
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(Clock, '/clock', self._on_clock, qos)

    @property
    def sim_time(self) -> float:
        return self.bar.sim_time

    def _on_clock(self, msg) -> None:
        self.bar.advance(msg.clock.sec + msg.clock.nanosec * 1e-9)

    def spin(self, seconds: float, wait=time.sleep) -> None:
        """Take at most one ``/clock`` message and return after ``seconds``: the bar moves at most
        1/seconds times a second, and this process does not wake at every step of the lockstep loop
        (its reader keeps only the latest tick, best effort: the ones in between are dropped by DDS,
        never seen by Python). ``wait(remaining)`` passes the rest of the time (the runner's:
        :meth:`Graph.wait_exit`, which returns early when a node exits)."""
        deadline = time.monotonic() + seconds
        self.executor.spin_once(timeout_sec=seconds)
        remaining = deadline - time.monotonic()
        if remaining > 0:
            wait(remaining)

    def complete(self) -> None:
        """The run completed (the dynamics node ended it): the bar at 100 %."""
        self.bar.complete()

    def close(self) -> None:
        # lazy: rclpy: only with the progress bar that imported it
        import rclpy
        self.bar.close()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def graph_env(lease: DomainLease, allow_network: bool = False) -> dict:
    """The environment of every process of a run: the leased domain, loopback-only discovery
    unless ``allow_network``, our Fast DDS profile unless the user gave one."""
    network_hygiene_defaults()
    return lease.env(allow_network=allow_network)


def recorded_state(bag_dir: Path) -> bool:
    """Whether the bag (complete, or as flushed so far) holds at least one state message (a
    quarantined one is not the run's)."""
    # lazy: the bag reader (0.4 s): only while a run is being watched
    from adcs_msgs_py.names import quarantined
    from adcs_sim.bag.reader import read_raw
    try:
        return any(topic.endswith('/state') and not quarantined(topic) for topic, *_ in read_raw(bag_dir))
    except (OSError, ValueError):
        return False


def lease_domain(domain_id: int | None = None) -> DomainLease:
    """A fresh domain id in 1..99, or exactly ``domain_id`` (refused if a run here holds it)."""
    if domain_id is None:
        return DomainLease(1, 99)
    try:
        return DomainLease(domain_id, domain_id)
    except (RuntimeError, ValueError) as exc:
        raise RunError(f'--domain-id {domain_id}: {exc}') from None
