"""``adcs-run [scenario.yaml] [--out DIR] [--duration S]``: one scenario, end to end.

1. Validates every section of the scenario file with its node's schema (nothing starts if one
   is wrong; the message names the key). An unknown section is an error.
2. Leases a fresh ``ROS_DOMAIN_ID`` (1..99) and sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
   for every process it starts. Only ``--allow-network`` (discovery on the local subnet, for a
   graph spread over several hosts; give every host the same ``--domain-id``) widens that.
3. Starts the recorder first (always: a run of the runner is always recorded; a ``recorder``
   section only tunes it), waits until it is subscribed, then every other node of the file as
   its own process, each told to wait for the recorder before its first message.
4. Shows a progress bar in simulated time (from ``/clock``) until the dynamics node finishes.
5. Stops the controllers, then the recorder (which closes the bag), and prints the metrics
   (:mod:`adcs_sim.analysis`), also written to ``<out>/metrics.json``.

A node that fails at start stops the whole graph; the runner exits non-zero with that node's
error and removes the output folder (no partial bag claims to be a run). A node that dies
mid-run stops the graph too, but the bag of what was recorded is kept (a folder holding a
recorded state is never removed) and the error names the node and how it died. Ctrl-C /
SIGTERM at any moment — start-up, mid-run, shutdown, twice — stop everything cleanly (recorder
last, so the bag is complete) and leave no process behind: the handler only records the signal,
the run loop acts on it at safe points, and once stopping has begun nothing interrupts it.

Output folder layout: ``<out>/bag`` (the rosbag2 MCAP bag), ``<out>/logs/<node>.log``,
``<out>/metrics.json``, ``<out>/scenario.yaml`` (a copy).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

from adcs_msgs_py.params import ParameterError, load_params_file
from adcs_sim.domains import DomainLease
from adcs_sim.nodes.base import network_hygiene_defaults

DEFAULT_SCENARIO = 'uosat12_gsmn.yaml'  # seed 000: a wheel fails, two-wheel GSMN recovers (the showcase)
READY_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 20.0


class RunError(RuntimeError):
    """The run could not be started or did not complete."""


def config_dirs() -> list[Path]:
    """Where scenario files are looked up by bare name: installed share folder, then the source tree."""
    dirs = [Path(sys.prefix) / 'share' / 'adcs_sim' / 'config']
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        try:
            dirs.insert(0, Path(get_package_share_directory('adcs_sim')) / 'config')
        except (PackageNotFoundError, KeyError, ValueError, OSError):  # OSError: no AMENT_PREFIX_PATH
            pass
    except ImportError:
        pass
    dirs.append(Path(__file__).resolve().parents[1] / 'config')
    return dirs


def resolve_scenario(name: str | None) -> Path:
    """A scenario path, or a bare file name looked up in the config folders."""
    name = name or DEFAULT_SCENARIO
    path = Path(name)
    if path.exists():
        return path.resolve()
    if not path.is_absolute() and len(path.parts) == 1:
        for d in config_dirs():
            if (d / name).exists():
                return (d / name).resolve()
    raise RunError(f'scenario file {name!r} not found (looked in: {", ".join(map(str, config_dirs()))})')


def validate_scenario(path: Path, duration: float | None = None) -> dict:
    """Validate every section; return {section: validated params}. Raises ParameterError."""
    from adcs_sim.registry import NODES
    sections = load_params_file(str(path))
    unknown = [s for s in sections if s not in NODES]
    if unknown:
        raise ParameterError(unknown[0], f'unknown node section {unknown[0]!r} in {path}; '
                             f'known nodes: {sorted(NODES)}')
    if 'dynamics' not in sections:
        raise ParameterError('dynamics', f'{path} has no dynamics section: nothing would simulate')
    controllers = [s for s in sections if NODES[s].role == 'controller']
    if len(controllers) > 1:
        raise ParameterError(controllers[1], f'more than one controller section ({controllers}): '
                             'the dynamics node would receive competing commands')
    validated = {}
    for name, given in sections.items():
        if name == 'dynamics' and duration is not None:
            given = {**given, 'duration': float(duration)}
        validated[name] = NODES[name].schema.validate(given)
    faults = validated.get('fault_injector')
    if faults is not None:
        wheels = validated['dynamics']['wheels.names']
        unknown = sorted(set(faults['schedule.actuator']) - set(wheels))
        if unknown:
            raise ParameterError('schedule.actuator', f'fault on actuator(s) {unknown} that the '
                                 f'dynamics section does not have (dynamics.wheels.names: {list(wheels)})',
                                 'fault_injector')
    return validated


class Graph:
    """The node processes of one run, started and stopped in order."""

    def __init__(self, env: dict, log_dir: Path) -> None:
        self.env = env
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs: dict[str, Path] = {}
        self.commands: dict[str, tuple[str, list[str]]] = {}   # name -> (module, args), for restarts
        self.signals: list[int] = []   # SIGINT / SIGTERM received by the runner
        self.stopping = False          # shutdown under way: a signal no longer interrupts it

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
            proc = subprocess.Popen([sys.executable, '-m', module, '--ros-args', *args],
                                    stdout=f, stderr=subprocess.STDOUT, env=self.env,
                                    stdin=subprocess.DEVNULL, start_new_session=True)
        self.procs[name] = proc
        return proc

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
        proc = self.procs.get(name)
        if proc is None:
            return None
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        return proc.returncode

    def stop_all(self, recorder_last: str | None = 'recorder') -> None:
        self.stopping = True
        for name in list(self.procs):
            if name != recorder_last:
                self.stop(name)
        if recorder_last in self.procs:
            self.stop(recorder_last)


class _Progress:
    """/clock subscriber driving a tqdm bar in simulated seconds."""

    def __init__(self, duration: float, enabled: bool) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from tqdm import tqdm
        self.rclpy = rclpy
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.node = rclpy.create_node('adcs_run_progress', context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_time = 0.0
        self.bar = tqdm(total=duration, unit='sim s', disable=not enabled, dynamic_ncols=True,
                        bar_format='{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]')
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(Clock, '/clock', self._on_clock, qos)

    def _on_clock(self, msg) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        if t > self.sim_time:
            self.bar.update(t - self.sim_time)
            self.sim_time = t

    def spin(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

    def close(self) -> None:
        self.bar.close()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def graph_env(lease: DomainLease, allow_network: bool = False) -> dict:
    """The environment of every process of a run: the leased domain, loopback-only discovery
    unless ``allow_network``, our Fast DDS profile unless the user gave one."""
    network_hygiene_defaults()
    return lease.env(allow_network=allow_network)


def recorded_state(bag_dir: Path) -> bool:
    """Whether the bag (complete, or as flushed so far) holds at least one state message."""
    from adcs_sim import bag as bagio
    try:
        return any(topic.endswith('/state') for topic, *_ in bagio.read_raw(bag_dir))
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


def run_scenario(scenario: Path, out: Path, duration: float | None = None, progress: bool = True,
                 tol_deg: float = 0.5, allow_network: bool = False, domain_id: int | None = None,
                 restarts: int = 0) -> dict:
    """Run one scenario end to end; return its metrics. Raises RunError / ParameterError.

    ``restarts``: how many times a controller that dies mid-run is started again (it rejoins
    the lockstep loop at the next state; the steps without it are missed steps under the
    dynamics node's timeout policy). 0: a dead node stops the graph."""
    from adcs_sim.analysis import RunData, jsonable_metrics, run_metrics
    from adcs_sim.registry import NODES
    validated = validate_scenario(scenario, duration)
    if out.exists() and any(out.iterdir()):
        raise RunError(f'output folder {out} exists and is not empty')
    lease = lease_domain(domain_id)   # before anything is written: a refused id leaves no folder
    log_dir = out / 'logs'
    log_dir.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(scenario, out / 'scenario.yaml')
    bag_dir = out / 'bag'
    graph = Graph(graph_env(lease, allow_network), log_dir)
    print(f'adcs-run: ROS_DOMAIN_ID={lease.domain_id}, discovery '
          f'{graph.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]}', flush=True)
    started = False
    restarts_done = 0
    old_handlers = {s: signal.signal(s, graph.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    prog = None
    try:
        common = ['--params-file', str(scenario)]
        graph.start('recorder', NODES['recorder'].module,
                    [*common, '-p', f'output:={bag_dir}', '-p', f'scenario_file:={scenario}'])
        from adcs_sim.nodes.recorder import READY_LINE
        graph.wait_for_line('recorder', READY_LINE, READY_TIMEOUT_S)
        others = [s for s in validated if s not in ('recorder', 'dynamics')]
        n_state_subscribers = sum(NODES[s].role == 'controller' for s in others) + 1
        # With a fault injector, the nodes that act on faults first collect its whole schedule.
        expect_faults = ['-p', 'startup.expect_faults:=true'] if 'fault_injector' in validated else []
        for name in others:
            graph.check()
            extra = expect_faults if NODES[name].role == 'controller' else []
            graph.start(name, NODES[name].module, [*common, '-p', 'startup.expect_recorder:=true', *extra])
        dyn_args = [*common, '-p', 'startup.expect_recorder:=true', *expect_faults,
                    '-p', f'startup.state_subscribers:={n_state_subscribers}']
        if duration is not None:
            dyn_args += ['-p', f'duration:={float(duration)!r}']
        graph.check()
        dynamics = graph.start('dynamics', NODES['dynamics'].module, dyn_args)
        prog = _Progress(validated['dynamics']['duration'], progress)
        watched = ['recorder', *others]
        while dynamics.poll() is None:
            graph.check()
            prog.spin(0.2)
            if prog.sim_time > 0:
                started = True
            dead = graph.failed(watched)
            if dead:
                name, _ = dead
                started = started or recorded_state(bag_dir)   # /clock may not have reached us yet
                if started and NODES[name].role == 'controller' and restarts_done < restarts:
                    restarts_done += 1
                    print(f'adcs-run: {graph.describe_exit(name)} at t = {prog.sim_time:g} s; '
                          f'restarting it ({restarts_done} of {restarts})', file=sys.stderr, flush=True)
                    graph.restart(name, restarts_done)
                    continue
                raise RunError(f'{graph.describe_exit(name)} {"during" if started else "before"} the run; '
                               f'graph stopped{f", bag kept in {bag_dir}" if started else ""}:\n'
                               f'{graph.log_tail(name)}')
        if dynamics.returncode != 0:
            started = started or (bag_dir / 'metadata.yaml').exists() or prog.sim_time > 0
            raise RunError(f'{graph.describe_exit("dynamics")}:\n{graph.log_tail("dynamics")}')
        started = True
        prog.close()
        prog = None
        graph.stopping = True   # from here a signal cannot cut the shutdown short
        for name in others:
            graph.stop(name)
        code = graph.stop('recorder')
        if code != 0:
            raise RunError(f'{graph.describe_exit("recorder")}:\n{graph.log_tail("recorder")}')
        if graph.signals:
            raise RunError(f'interrupted by {signal.Signals(graph.signals[0]).name} during shutdown; '
                           f'the run had completed, bag kept in {bag_dir}')
    except KeyboardInterrupt:
        graph.stop_all()
        sig = signal.Signals(graph.signals[0]).name if graph.signals else 'SIGINT'
        kept = f'bag kept in {bag_dir}' if bag_dir.exists() else 'no bag was recorded yet'
        raise RunError(f'interrupted by {sig} ({"during" if started else "before"} the run); {kept}') from None
    except BaseException:
        graph.stop_all()
        if not (started or recorded_state(bag_dir)):   # never delete recorded data
            shutil.rmtree(out, ignore_errors=True)
        raise
    finally:
        if prog is not None:
            prog.close()
        graph.stop_all()
        lease.release()
        for s, h in old_handlers.items():
            signal.signal(s, h)
    metrics = run_metrics(RunData.from_bag(bag_dir), tol_deg)
    (out / 'metrics.json').write_text(json.dumps(jsonable_metrics(metrics), indent=2))
    return metrics


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='adcs-run', description=__doc__.splitlines()[0])
    parser.add_argument('scenario', nargs='?', default=None,
                        help=f'scenario params file, or the name of one in config/ (default {DEFAULT_SCENARIO})')
    parser.add_argument('--out', type=Path, default=None, help='output folder (default runs/<scenario>-<time>)')
    parser.add_argument('--duration', type=float, default=None, help='override the simulated duration (s)')
    parser.add_argument('--tolerance-deg', type=float, default=0.5,
                        help='settling band for the printed metrics (deg; default 0.5)')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--report', action='store_true',
                        help='also write the report (adcs-analyze: report.md + figures) to <out>/report')
    parser.add_argument('--allow-network', action='store_true',
                        help='let DDS discover nodes on the local subnet (multi-host graphs); by '
                             'default discovery is limited to this machine (localhost)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='use this ROS_DOMAIN_ID (0..232; e.g. the same on every host with '
                             '--allow-network) instead of a fresh free one')
    parser.add_argument('--restart', type=int, default=0, metavar='N',
                        help='start a controller that dies mid-run again, up to N times (it rejoins '
                             'the lockstep loop; the steps without it are missed steps); default 0: '
                             'a node that dies stops the run')
    args = parser.parse_args(argv)
    try:
        scenario = resolve_scenario(args.scenario)
        out = args.out or Path('runs') / f'{scenario.stem}-{datetime.now():%Y%m%d-%H%M%S}'
        print(f'adcs-run: {scenario} -> {out}', flush=True)
        metrics = run_scenario(scenario, out, args.duration, not args.no_progress and sys.stderr.isatty(),
                               args.tolerance_deg, args.allow_network, args.domain_id, args.restart)
    except (ParameterError, RunError) as exc:
        print(f'adcs-run: error: {exc}', file=sys.stderr)
        return 1 if isinstance(exc, RunError) else 2
    from adcs_sim.analysis import format_metrics
    print(f'bag: {out / "bag"}')
    print('metrics:')
    print(format_metrics(metrics))
    if args.report:
        from adcs_sim import report
        run = report.load_run(out / 'bag')
        print(f'report: {report.write_report(run, out / "report", args.tolerance_deg)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
