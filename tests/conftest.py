"""Shared fixtures: every ROS test runs on its own domain id, loopback discovery only."""
from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from adcs_sim.app.batch import BatchSimulation  # noqa: E402
from adcs_sim.app.domains import DomainLease  # noqa: E402
from adcs_sim.bag.reader import read_raw  # noqa: E402
from adcs_sim.truth.plant import Plant  # noqa: E402

# Asks Fast DDS for UDP only. rmw_fastrtps's LOCALHOST discovery range sets its own transports and
# adds shared memory anyway (test_recorder.remove_if_orphaned cleans what a SIGKILLed node leaves).
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
from adcs_msgs_py.conversions import InvalidMessage  # noqa: E402
from adcs_msgs_py.node import network_hygiene_defaults  # noqa: E402

network_hygiene_defaults()  # the same Fast DDS profile as the nodes, for in-process graphs
CONFIG = ROOT / 'config'


# --- processes, found through /proc (not ps, whose output is cut to the terminal's width) --------

def _stat(pid: int) -> tuple[str, int] | None:
    """(state letter, parent pid) of ``pid``, or None if there is no such process."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except (OSError, IndexError):
        return None
    return fields[0], int(fields[1])


def cmdline(pid: int) -> str:
    """The full command line of ``pid`` ('' for a zombie or a process gone)."""
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            return f.read().replace(b'\0', b' ').decode(errors='replace').strip()
    except OSError:
        return ''


def children(pid: int) -> dict[int, str]:
    """The direct children of ``pid``: {child pid: command line}."""
    kids = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            stat = _stat(int(entry))
            if stat is not None and stat[1] == pid:
                kids[int(entry)] = cmdline(int(entry))
    return kids


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie whose parent has not reaped it yet is gone for our purpose)."""
    stat = _stat(pid)
    return stat is not None and stat[0] not in 'ZX'


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


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (children, their children, ...)."""
    found, todo = set(), [pid]
    while todo:
        for child in children(todo.pop()):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def kill_tree(proc: subprocess.Popen) -> None:
    """SIGKILL ``proc``'s process group and every process below it, and reap ``proc``."""
    targets = descendants(proc.pid)
    for pgid in {proc.pid, *targets}:
        try:
            os.killpg(pgid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    for pid in targets:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait()


class Spawner:
    """``spawn(args, **popen_kwargs)``: a process in a session of its own. ``spawn.adopt(pids)``
    adds processes seen below it (they may outlive it). :meth:`cleanup` kills them all."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen] = []
        self.adopted: set[int] = set()

    def __call__(self, args, **kwargs) -> subprocess.Popen:
        kwargs.setdefault('start_new_session', True)
        proc = subprocess.Popen(args, **kwargs)
        self.procs.append(proc)
        return proc

    def adopt(self, pids) -> None:
        self.adopted |= set(pids)

    def cleanup(self) -> None:
        for pid in self.adopted:
            if alive(pid):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for proc in self.procs:
            kill_tree(proc)


@pytest.fixture
def spawn():
    """A :class:`Spawner`; at teardown, passed or failed, every process it started or adopted is
    killed with its process group and descendants (a failing test leaves no runner and no node
    behind for the rest of the suite)."""
    spawner = Spawner()
    try:
        yield spawner
    finally:
        spawner.cleanup()


def pytest_sessionstart(session):
    """Load the compiled plant kernel (on a fresh clone: compile it into its cache, once) before
    any test starts a node, so no graph test's start-up time includes a compilation."""
    Plant(np.eye(3))


_LEASES = itertools.count()   # leases taken by this process (ros_domain)


@pytest.fixture
def ros_domain(monkeypatch):
    """A leased ROS_DOMAIN_ID (in 100..232, away from the runner's default range), set in os.environ.

    Yields the lease; ``lease.env()`` is the environment for subprocesses of the test.
    """
    # Each lease of this process starts from another id (a step coprime with the 133 ids): a test
    # never meets in its domain a participant an earlier test of this process left alive (one still
    # waiting to be collected). With the default start every lease of a process began at the same
    # id, and a later test's writers once waited on an earlier test's recorder readers, 5 s a step.
    lease = DomainLease(100, 232, prefer=100 + (os.getpid() + 37 * next(_LEASES)) % 133)
    monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        yield lease
    finally:
        lease.release()


@pytest.fixture
def two_contexts(ros_domain):
    """Two rclpy contexts (two DDS participants, as two processes of the graph) on a leased
    domain, initialised; shut down at teardown."""
    import rclpy
    from rclpy.context import Context
    pair = (Context(), Context())
    for ctx in pair:
        rclpy.init(args=[], context=ctx)
    try:
        yield pair
    finally:
        for ctx in pair:
            close_graph(rclpy, ctx)


def _prune_empty(tree: dict) -> None:
    """Drop the mappings left empty by deletions (rcl refuses an empty mapping: ``wheels: {}``)."""
    for key in list(tree):
        if isinstance(tree[key], dict):
            _prune_empty(tree[key])
            if not tree[key]:
                del tree[key]


def make_scenario(tmp_path: Path, overrides: dict | None = None, base: str = 'microsat_pd_slew.yaml',
                  drop: tuple[str, ...] = ()) -> Path:
    """Copy of a config/ scenario with ``overrides`` ({section: {dotted.name: value}}) applied.

    A value of None deletes the parameter; sections named in ``drop`` are removed.
    """
    import yaml
    tree = yaml.safe_load((CONFIG / base).read_text())
    for section in drop:
        tree.pop(section, None)
    for section, params in (overrides or {}).items():
        node = tree.setdefault(section, {'ros__parameters': {}})['ros__parameters']
        for dotted, value in params.items():
            *parents, leaf = dotted.split('.')
            d = node
            for p in parents:
                d = d.setdefault(p, {})
            if value is None:
                d.pop(leaf, None)
            else:
                d[leaf] = value
        _prune_empty(node)
    path = tmp_path / f'scenario_{len(list(tmp_path.glob("scenario_*.yaml")))}.yaml'
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


def spin_until(executor, condition, timeout: float = 30.0, what: str = 'the expected messages') -> None:
    """Spin until ``condition()``; the deadline only turns a hang into a failure."""
    import time
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f'graph did not deliver {what} within {timeout} s'
        executor.spin_once(timeout_sec=0.1)


def refused(convert) -> bool:
    """Whether ``convert()`` (a message conversion of the interface) refuses its input
    (InvalidMessage): what a fuzzed node must then have counted instead of applied."""
    try:
        convert()
    except InvalidMessage:
        return True
    return False


def reference_comparison(bags, paper: Path, out: Path) -> str:
    """``comparison.md`` of ``adcs-analyze BAGS --compare --reference PAPER --out OUT`` (which must exit
    0): the published-vs-ours rows every seed's doc table is checked against."""
    from adcs_sim.app.analyze import main as analyze   # matplotlib behind it: only for these tests
    assert analyze([*map(str, bags), '--compare', '--reference', str(paper), '--out', str(out)]) == 0
    return (out / 'comparison.md').read_text()


_BATCH_RUNS: dict = {}


def batch_run_data(validated: dict):
    """The batch engine's run of one validated scenario, as RunData, computed once per test session
    for equal scenarios (several modules check the same long runs: a bag against its batch run,
    a reading study on the same scenario). Callers must not modify what it returns."""
    key = json.dumps(validated, sort_keys=True, default=repr)
    if key not in _BATCH_RUNS:
        _BATCH_RUNS[key] = BatchSimulation.from_runs([validated]).run().run_data(0)
    return _BATCH_RUNS[key]


class InProcessGraph:
    """Nodes of the graph in this process, on a private context, one executor.

    ``graph.add(NodeClass)`` builds an adcs_sim node from the scenario's parameters;
    ``graph.plain(name)`` a bare rclpy node for test publishers/subscribers. Everything is
    destroyed and the context shut down on exit.
    """

    def __init__(self, scenario: Path) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.rclpy = rclpy
        self.context = Context()
        rclpy.init(args=['--ros-args', '--params-file', str(scenario)], context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, node_class):
        return self._register(node_class(self.context))

    def plain(self, name: str):
        return self._register(self.rclpy.create_node(name, context=self.context))

    def _register(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def spin_until(self, condition, timeout: float = 30.0, what: str = 'the expected messages') -> None:
        spin_until(self.executor, condition, timeout, what)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        close_graph(self.rclpy, self.context, self.executor, self.nodes)


def close_graph(rclpy, context, executor=None, nodes=()) -> None:
    """Take a graph of this process down for good: its nodes out of the executor and destroyed, the
    executor shut down, the context shut down AND destroyed. A node still held by an executor is
    destroyed only when that lets go of it, and a context's DDS participant lives until the context
    is destroyed (rclpy: shutdown alone keeps it): a later graph of the same test on the same domain
    then met the earlier recorder's readers, which nobody takes from any more. Once full they
    acknowledged nothing, and every step of the later run waited out its 5 s acknowledgement wait
    (seen: test_measurement_noise_is_seeded_and_truth_is_recorded's second run at step ~300)."""
    for node in reversed(list(nodes)):
        if executor is not None:
            executor.remove_node(node)
        node.destroy_node()
    if executor is not None:
        executor.shutdown()
    rclpy.try_shutdown(context=context)
    context.destroy()


def record_pd_loop(tmp_path: Path, n: int, dynamics: dict | None = None, extra_counts: dict | None = None):
    """Dynamics + PD controller + recorder in this process, lockstep, ``n`` steps of the PD slew
    (``dynamics`` overrides its section); waits until the recorder has every message of the run.

    Returns ``(bag folder, dynamics node)``; ``extra_counts`` ({topic: count}) adds topics to wait for.
    """
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.recorder import RecorderNode

    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'startup.expect_recorder': True, **(dynamics or {})},
        'pd_controller': {'startup.expect_recorder': True},
        'recorder': {'output': str(bag_dir)}})
    expected = {'/state': n + 1, '/controller/status': n + 1, '/wheels/cmd': n + 1,
                '/dynamics/status': 2, **(extra_counts or {})}
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        dyn = graph.add(DynamicsNode)
        pd = graph.add(PdController)
        pd.connect()
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(counts[t].count == c for t, c in expected.items()))
        rec.close()
    return bag_dir, dyn


def run_lockstep_graph(scenario: Path, controller_class, expected: dict, faults: bool = False,
                       timeout: float = 120.0):
    """Recorder (+ fault injector when ``faults``) + dynamics + ``controller_class`` in this
    process, lockstep, the run of ``scenario`` (its recorder section names the bag); with
    ``faults`` the controller collects the fault schedule first. Waits until the recorder has
    ``expected`` ({topic: message count}). Returns ``(dynamics node, controller node)``."""
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.fault_injector import FaultInjectorNode
    from adcs_sim.nodes.recorder import RecorderNode
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        if faults:
            injector = graph.add(FaultInjectorNode)
            if injector.params['startup.expect_recorder']:   # what its run() does first, under the runner
                injector.publish_once_recorded()
        dyn = graph.add(DynamicsNode)
        ctrl = graph.add(controller_class)
        if faults:
            ctrl.wait_for_faults(graph.executor)
        ctrl.connect()
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(t in counts and counts[t].count == c for t, c in expected.items()),
                         timeout=timeout, what=f'{expected}')
        rec.close()
    return dyn, ctrl


def run_fault_graph(scenario: Path, controller_class, n: int, timeout: float = 120.0):
    """:func:`run_lockstep_graph` with the fault injector, ``n`` steps of a wheel controller."""
    expected = {'/state': n + 1, '/controller/status': n + 1, '/wheels/cmd': n + 1,
                '/wheels/state': n + 1, '/dynamics/status': 2, '/faults': 2}
    return run_lockstep_graph(scenario, controller_class, expected, faults=True, timeout=timeout)


def plain_message(value):
    """A deserialised message as nested tuples (numpy arrays as dtype + bytes), comparable with
    ==: message content, not CDR bytes (Fast DDS leaves a serialised message's alignment padding
    uninitialised, so equal messages can differ there)."""
    if hasattr(value, '__dataclass_fields__'):
        return tuple(plain_message(getattr(value, f)) for f in value.__dataclass_fields__)
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(plain_message(v) for v in value)
    return value


# A committed bag recorded on one CPU, compared with the batch engine on another: numpy dispatches
# sin, cos, arccos, arctan2 ... to SIMD kernels chosen for the CPU (AVX-512 vs AVX2 vs baseline),
# which may differ by an ulp; a closed-loop run carries that to ~1e-11 relative (seen: 3.2e-11 on
# the seed 002 slew). On one machine the graph and the batch engine are equal bit for bit (the
# node-pair tests check that in the same run); across machines, to this tolerance.
CROSS_CPU_RTOL = 1e-9


def assert_recorded_run_equal(actual, recorded) -> None:
    """``actual`` (computed here) equals ``recorded`` (a committed bag's): bit for bit on the CPU
    that recorded it, to :data:`CROSS_CPU_RTOL` on another (see there)."""
    actual, recorded = np.asarray(actual), np.asarray(recorded)
    if not np.array_equal(actual, recorded):
        np.testing.assert_allclose(actual, recorded, rtol=CROSS_CPU_RTOL, atol=1e-15)
