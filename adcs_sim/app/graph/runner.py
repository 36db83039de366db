"""``adcs-run [scenario.yaml] [--out DIR] [--duration S] [--explain]``: run one scenario on the ROS 2
node graph, end to end: check it, start every node as its own process, record the run to a bag and
print its metrics.

1. Validates every section of the scenario file with its node's schema (nothing starts if one
   is wrong; the message names the key). An unknown section is an error.
2. Leases a fresh ``ROS_DOMAIN_ID`` (1..99) and sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
   for every process it starts. Only ``--allow-network`` (discovery on the local subnet, for a
   graph spread over several hosts; give every host the same ``--domain-id``) widens that.
3. Starts the recorder (always: a run of the runner is always recorded; a ``recorder`` section
   only tunes it) and every other node of the file, each as its own process and at once, each
   told to wait for the recorder's subscriptions before its first message; then waits until the
   recorder says it is ready.
4. Shows a progress bar in simulated time (from ``/clock``) until the dynamics node finishes.
5. Stops the controllers, then the recorder (which closes the bag), and prints the metrics
   (:mod:`adcs_sim.app.analysis.metrics`, computed while the bag is read:
   :func:`~adcs_sim.app.analysis.stream_metrics.analyse_bag`), also written to ``<out>/metrics.json``.

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

import json
import shutil
import signal
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from adcs_msgs_py import names
from adcs_msgs_py.help_text import command_parser
from adcs_msgs_py.node import EXIT_DISK_FULL, EXIT_FLIGHT_SOFTWARE, EXIT_INTRUSION, INTRUSION_LOG
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import one_line_warnings
from adcs_sim.app.graph.processes import PROGRESS_NODE, Graph, Progress, graph_env, lease_domain, recorded_state
from adcs_sim.app.outputs import OutputError, check_folder, fresh_folder
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.checks import check_disk
from adcs_sim.app.scenario.files import DEFAULT_SCENARIO, RunError, config_dirs, resolve_scenario, validate_scenario

# Imported when first needed, not before the nodes start (the import of the analysis modules,
# ~0.7 s on the 2-core machine, was on the critical path of every run's start-up):
# adcs_sim.app.analysis.metrics, adcs_sim.app.analysis.stream_metrics (the metrics, read from the bag at the end;
# imported while the graph shuts down: warm_analysis), adcs_sim.app.analysis.run_data (the target),
# adcs_sim.app.scenario.parameters (--explain), adcs_sim.nodes.recorder (its ready line).

__all__ = ['DEFAULT_SCENARIO', 'RunError', 'config_dirs', 'resolve_scenario', 'validate_scenario',
           'graph_env', 'lease_domain', 'run_scenario', 'main']

READY_TIMEOUT_S = 60.0
# Wall seconds the recorder is given to find and record the intruder a node stopped the run on.
# The node that applies a topic sees the intruder when its own participant discovers it; the
# recorder's participant discovers it on its own, maybe later on a loaded machine.
INTRUSION_RECORD_S = 30.0


# --- intruders (issue 17): who may publish where, and what the bag says ---------------------------
# Every node is told which nodes of this scenario may publish on each topic it listens to
# (``startup.publishers``, adcs_msgs_py.guard.PublisherVetting); the recorder writes any other
# publisher into the bag (``intrusions``), and the run then ends non-zero naming it.

def allowed_publishers(sections, restarts: int = 0) -> list[str]:
    """``startup.publishers`` of every node of a run of ``sections`` (the scenario's node names);
    with ``restarts`` (``--restart N``), the controllers are restartable (a killed one's
    predecessor stays in the graph for a while beside it: adcs_msgs_py.guard)."""
    by_role: dict[str, list[str]] = {}
    for name in sorted({*sections, 'recorder'}):   # every run has a recorder, with a section or not
        by_role.setdefault(NODES[name].role, []).append(name)
    allowed = {topic: [n for role in roles for n in by_role.get(role, [])]
               for topic, roles in names.PUBLISHER_ROLES.items()}
    allowed[names.RUN_NODES] = sorted({*sections, 'recorder', PROGRESS_NODE})
    if restarts:
        allowed[names.RESTARTABLE] = by_role.get('controller', [])
    return names.format_publishers(allowed)


def publishers_arg(sections, restarts: int = 0) -> list[str]:
    return ['-p', f'startup.publishers:={json.dumps(allowed_publishers(sections, restarts))}']


def _compromised(found: list[str], bag_dir: Path) -> RunError | None:
    """The error of a run whose bag holds intruders (``found``: :func:`intrusion_lines`), or None."""
    if not found:
        return None
    return RunError('run compromised, its messages were not applied: ' + '; '.join(found)
                    + f'; bag kept in {bag_dir} (topic {names.INTRUSIONS})')


def _bag_intrusions(bag_dir: Path) -> list[str]:
    """:func:`adcs_sim.app.analysis.metrics.bag_intrusions` (imported on the way out of a failed run)."""
    # lazy: the analysis (0.4 s): only on the way out of a failed run
    from adcs_sim.app.analysis.metrics import bag_intrusions
    return bag_intrusions(bag_dir)


def _await_recorded_intrusion(run: _Run) -> None:
    """A node stopped the run on an intruder (exit EXIT_INTRUSION): give the recorder, still
    running, up to INTRUSION_RECORD_S to record it (its periodic sweep logs INTRUSION_LOG as it
    writes the ``intrusions`` record), so the bag says what the node saw before the graph stops."""
    graph = run.graph
    procs = graph.procs
    if not any(procs[n].poll() == EXIT_INTRUSION for n in ('dynamics', *run.others) if n in procs):
        return
    if 'recorder' not in procs or procs['recorder'].poll() is not None:
        return
    try:
        graph.wait_for_line('recorder', INTRUSION_LOG, INTRUSION_RECORD_S)
    except RunError:
        print(f'adcs-run: the recorder did not find the intruder within {INTRUSION_RECORD_S:g} s: '
              f'the bag has no {names.INTRUSIONS} record', file=sys.stderr, flush=True)


def run_target(validated: dict) -> list[float]:
    """The target of the dynamics node's error topics and target markers: the offline analysis'
    (:func:`~adcs_sim.app.analysis.metrics.target_attitude`: a controller section's ``target.attitude``),
    so that ``error/*`` in the bag are the errors ``adcs-analyze`` computes."""
    # lazy: the run data module (0.4 s): off adcs-run's path to starting the nodes
    from adcs_sim.app.analysis.run_data import target_attitude
    sections = {name: {'ros__parameters': {'target': {'attitude': list(values['target.attitude'])}}}
                for name, values in validated.items() if name != 'dynamics' and 'target.attitude' in values}
    return [float(v) for v in target_attitude(sections)]


# The dynamics node's parameter: matched subscribers of each fitted sensor topic to wait for before
# t = 0 (the estimators and the recorder); declared by the dynamics schema with the sensor models.
SENSOR_SUBSCRIBERS = 'startup.sensor_subscribers'


def startup_counts(sections) -> dict[str, int]:
    """The start-up handshake of a run of ``sections``: the matched subscribers the dynamics node
    waits for on ``state`` (the controllers flying on it, and the recorder) and on each sensor topic
    (the estimators and the recorder; 0: no estimator, nothing to wait for), and those each
    estimator waits for on ``estimate/state`` besides the recorder (the controllers flying on it)."""
    controllers = [s for s in sections if NODES[s].role == 'controller']
    on_estimate = sum(sections[s]['feedback'] == 'estimate' for s in controllers)
    estimators = sum(NODES[s].role == 'estimator' for s in sections)
    return {'state': len(controllers) - on_estimate + 1, 'estimate': on_estimate,
            'sensors': estimators + 1 if estimators else 0}


@dataclass
class _Run:
    """One run under way: its validated sections, files, graph and what has happened so far."""

    scenario: Path
    validated: dict
    bag_dir: Path
    graph: Graph
    duration: float | None
    restarts: int
    others: list[str] = field(default_factory=list)   # nodes other than the recorder and dynamics
    started: bool = False      # a state was published (the bag holds recorded data)
    restarts_done: int = 0
    progress: Progress | None = None   # the /clock progress bar (a terminal): the runner's participant


def _start_graph(run: _Run, show_progress: bool):
    """Start the recorder, the other nodes, then the dynamics node, which starts the clock once
    every expected subscriber is matched; then wait until the recorder is ready. The processes
    start together (their imports and DDS start-up overlap, ~2 s): the recorder need not be ready
    first, since every node that publishes what it records waits for its subscriptions
    (``startup.expect_recorder``; the fault injector publishes its schedule only once the recorder
    is matched) and the start-up waits count only the run's own subscribers (``startup.publishers``).
    (Undone once, when two intruder tests failed under load with it: their cause was the recorder
    discovering a rogue or the injector late, fixed since by the runner's and the injector's waits
    for the recorder.) Returns the dynamics process."""
    graph, validated = run.graph, run.validated
    common = ['--params-file', str(run.scenario), *publishers_arg(validated, run.restarts)]
    graph.start('recorder', NODES['recorder'].module,
                [*common, '-p', f'output:={run.bag_dir}', '-p', f'scenario_file:={run.scenario}'])
    # lazy: the recorder's module (0.75 s): its imports overlap the nodes' start
    from adcs_sim.nodes.recorder import READY_LINE
    run.others = [s for s in validated if s not in ('recorder', 'dynamics')]
    handshake = startup_counts(validated)
    # With a fault injector, the nodes that act on faults first collect its whole schedule.
    expect_faults = ['-p', 'startup.expect_faults:=true'] if 'fault_injector' in validated else []
    for name in run.others:
        graph.check()
        extra = expect_faults if NODES[name].role == 'controller' else []
        if NODES[name].role == 'estimator':
            extra = ['-p', f'startup.estimate_subscribers:={handshake["estimate"]}']
        graph.start(name, NODES[name].module, [*common, '-p', 'startup.expect_recorder:=true', *extra])
    dyn_args = [*common, '-p', 'startup.expect_recorder:=true', *expect_faults,
                '-p', f'startup.state_subscribers:={handshake["state"]}',
                '-p', f'visualization.target_attitude:={json.dumps(run_target(validated))}']
    if handshake['sensors']:   # the dynamics node waits for the estimator's sensor subscriptions
        dyn_args += ['-p', f'{SENSOR_SUBSCRIBERS}:={handshake["sensors"]}']
    if run.duration is not None:
        dyn_args += ['-p', f'duration:={float(run.duration)!r}']
    graph.check()
    dynamics = graph.start('dynamics', NODES['dynamics'].module, dyn_args)
    graph.wait_for_line('recorder', READY_LINE, READY_TIMEOUT_S)
    if show_progress:   # only then a participant of the runner's own, on /clock
        run.progress = Progress(validated['dynamics']['duration'], show_progress, graph.env)
    return dynamics


def warm_analysis() -> threading.Thread:
    """Import the end-of-run analysis (the bag reader, the metrics, and the compiled Euler-angle
    kernel their Euler angles use: numba and the kernel's cache, 0.5-2 s on the 2-core machine) in
    a thread, while the graph shuts down: the runner only waits then (for the nodes' exits; the
    recorder's drain is mostly a quiet period), so the imports are off the critical path. (Imported
    while the nodes ran, they took CPU from the lockstep loop's first steps instead.) A failed
    import is raised again where the module is used."""
    def imports() -> None:
        try:
            # lazy: the analysis, warmed in a thread while the graph shuts down (see warm_analysis)
            import numpy as np

            import adcs_sim.app.analysis.stream_metrics  # noqa: F401
            from adcs_core.attitude import SMALL_BATCH, euler_213
            euler_213(np.tile([0.0, 0.0, 0.0, 1.0], (SMALL_BATCH + 1, 1)))   # loads the kernel
        except Exception:  # noqa: BLE001, S110 - raised again by the import in run_scenario
            pass
    thread = threading.Thread(target=imports, name='warm-analysis', daemon=True)
    thread.start()
    return thread


def _supervise(run: _Run, dynamics) -> None:
    """Follow the run until the dynamics node exits: restart a dead controller (``--restart``) or
    stop with a RunError naming the node that died and how. Woken by any node's exit (pidfd) or
    every 0.2 s (the progress bar, a signal)."""
    graph, prog = run.graph, run.progress
    watched = ['recorder', *run.others]
    while dynamics.poll() is None:
        graph.check()
        if prog is not None:
            prog.spin(0.2, graph.wait_exit)
            run.started = run.started or prog.sim_time > 0
        else:
            graph.wait_exit(0.2)
        dead = graph.failed(watched)
        if not dead:
            continue
        name, code = dead
        run.started = run.started or recorded_state(run.bag_dir)   # /clock may not have reached us yet
        # A node that could not answer a step (started again, it would fail again), or the recorder
        # on a full disk (its one line names the bag and the error): the run stops, in one line.
        if code == EXIT_FLIGHT_SOFTWARE or (name == 'recorder' and code == EXIT_DISK_FULL):
            raise _flight_software_failed(run, name)
        if run.started and NODES[name].role == 'controller' and run.restarts_done < run.restarts:
            run.restarts_done += 1
            at = f' at t = {prog.sim_time:g} s' if prog is not None else ''
            print(f'adcs-run: {graph.describe_exit(name)}{at}; '
                  f'restarting it ({run.restarts_done} of {run.restarts})', file=sys.stderr, flush=True)
            graph.restart(name, run.restarts_done)
            continue
        raise RunError(f'{graph.describe_exit(name)} {"during" if run.started else "before"} the run; '
                       f'graph stopped{f", bag kept in {run.bag_dir}" if run.started else ""}:\n'
                       f'{graph.log_tail(name)}')
    if dynamics.returncode != 0:
        run.started = (run.started or (run.bag_dir / 'metadata.yaml').exists()
                       or (prog.sim_time > 0 if prog is not None else recorded_state(run.bag_dir)))
        raise RunError(f'{graph.describe_exit("dynamics")}:\n{graph.log_tail("dynamics")}')
    run.started = True


def _flight_software_failed(run: _Run, name: str) -> RunError:
    """The one line of a flight-software node that stopped the run (exit EXIT_FLIGHT_SOFTWARE): its
    error (node, time, error: adcs_controllers.laws.failure) and where the bag is."""
    prefix = f'[{name}] error: '
    lines = [line for line in run.graph.log_tail(name, 50).splitlines() if line.startswith(prefix)]
    reason = lines[-1][len(prefix):] if lines else f'{run.graph.describe_exit(name)}: {run.graph.log_tail(name, 1)}'
    if NODES[name].role in ('controller', 'estimator'):   # it answers states: the run had started
        run.started = True
    kept = f', bag kept in {run.bag_dir} (every step up to it)' if run.started else ''
    return RunError(f'{reason}; graph stopped{kept}')


def _stop_graph(run: _Run) -> None:
    """The run completed: stop the other nodes, then the recorder (which closes the bag)."""
    graph = run.graph
    if run.progress is not None:
        run.progress.complete()   # the last ticks it saw were a few steps short of the end
        run.progress.close()
        run.progress = None
    graph.stopping = True   # from here a signal cannot cut the shutdown short
    graph.stop_together(run.others)
    code = graph.stop('recorder')
    if code == EXIT_DISK_FULL:   # the bag's summary did not fit: said in one line, as mid-run
        raise _flight_software_failed(run, 'recorder')
    if code != 0:
        raise RunError(f'{graph.describe_exit("recorder")}:\n{graph.log_tail("recorder")}')
    if graph.signals:
        raise RunError(f'interrupted by {signal.Signals(graph.signals[0]).name} during shutdown; '
                       f'the run had completed, bag kept in {run.bag_dir}')


def _finish(run: _Run, tol_deg: float):
    """The run completed: stop the graph (the end-of-run analysis imported meanwhile: warm_analysis),
    then read the bag once, streaming: the intruders and the metrics (memory independent of the
    run's length). Raises the RunError of a compromised run."""
    warming = warm_analysis()
    _stop_graph(run)
    warming.join()
    # lazy: imported by warm_analysis while the graph shut down: here it is already loaded
    from adcs_sim.app.analysis.stream_metrics import analyse_bag
    analysed = analyse_bag(run.bag_dir, tol_deg)
    compromised = _compromised(analysed.intrusions, run.bag_dir)
    if compromised is not None:
        raise compromised
    for line in analysed.unmatchable:   # could never deliver: the run is the run's (adcs_msgs_py.guard)
        print(f'adcs-run: warning: {line}', file=sys.stderr, flush=True)
    return analysed


def _remove_unrecorded(out: Path, given: bool) -> None:
    """A run that recorded nothing leaves nothing: ``out``, or its content when the user gave
    it as an empty folder (the folder is theirs)."""
    for path in (out.iterdir() if given else [out]):
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


# What a run's output folder holds (the layout above): a folder holding only these, with its
# scenario copy, is an earlier run's output, which ``overwrite`` may replace.
RUN_OUTPUTS = frozenset({'bag', 'logs', 'metrics.json', 'scenario.yaml', 'report'})


def is_run_output(folder: Path) -> bool:
    """``folder`` holds an earlier run's output and nothing else (the runner's own files)."""
    held = {p.name for p in folder.iterdir()}
    return 'scenario.yaml' in held and held <= RUN_OUTPUTS


def _say(line: str) -> None:
    print(line, flush=True)


def _claim_output(out: Path, scenario: Path, domain_id: int | None, overwrite: bool):
    """Check ``out`` (absent or empty, or an earlier run's with ``overwrite``; writable, not a FIFO
    or a file, not the scenario's folder), lease the domain (before anything is written: a refused
    id leaves the folder as it was), then empty the earlier run's folder. Returns the lease."""
    try:
        replace = check_folder(out, inputs=[scenario], owned=is_run_output if overwrite else None)
    except OutputError as exc:
        raise RunError(f'output folder {exc}') from None
    lease = lease_domain(domain_id)
    if replace:
        _remove_unrecorded(out, given=True)   # the earlier run's files: the folder is kept
    return lease


def run_scenario(scenario: Path, out: Path, duration: float | None = None, progress: bool = True,
                 tol_deg: float = 0.5, allow_network: bool = False, domain_id: int | None = None,
                 restarts: int = 0, log: Callable[[str], None] = _say, overwrite: bool = False) -> dict:
    """Run one scenario end to end; return its metrics. Raises RunError / ParameterError.

    ``restarts``: how many times a controller that dies mid-run is started again (it rejoins the
    lockstep loop at the next state; the steps without it are missed steps under the dynamics
    node's timeout policy). 0: a dead node stops the graph. ``log``: where the informational lines
    go (stdout by default). ``overwrite``: ``out`` may be an earlier run's output
    (:func:`is_run_output`; anything else is refused), emptied before the run starts."""
    validated = validate_scenario(scenario, duration)
    check_disk(validated, out)   # the bag's size against the free disk at --out (issue #31)
    lease = _claim_output(out, scenario, domain_id, overwrite)
    given = out.exists()   # an empty folder of the user's: emptied, not removed, on a failed start
    log_dir = out / 'logs'
    log_dir.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(scenario, out / 'scenario.yaml')
    graph = Graph(graph_env(lease, allow_network), log_dir, keep_fds=lease.fds())
    run = _Run(scenario, validated, out / 'bag', graph, duration, restarts)
    log(f'adcs-run: ROS_DOMAIN_ID={lease.domain_id}, discovery {graph.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]}')
    old_handlers = {s: signal.signal(s, graph.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        _supervise(run, _start_graph(run, progress))
        analysed = _finish(run, tol_deg)
    except KeyboardInterrupt:
        graph.stop_all()
        run.started = run.started or recorded_state(run.bag_dir)   # /clock may not have reached us yet
        sig = signal.Signals(graph.signals[0]).name if graph.signals else 'SIGINT'
        kept = f'bag kept in {run.bag_dir}' if run.bag_dir.exists() else 'no bag was recorded yet'
        interrupted = f'interrupted by {sig} ({"during" if run.started else "before"} the run); {kept}'
        compromised = _compromised(_bag_intrusions(run.bag_dir), run.bag_dir)   # say both
        raise RunError(interrupted if compromised is None else f'{interrupted}; {compromised}') from None
    except BaseException as exc:
        if isinstance(exc, RunError):
            _await_recorded_intrusion(run)
        graph.stop_all()
        compromised = _compromised(_bag_intrusions(run.bag_dir), run.bag_dir) if isinstance(exc, RunError) else None
        if compromised is not None and compromised is not exc:
            raise compromised from exc   # a node that stopped on the intrusion: name the intruder
        if not (run.started or recorded_state(run.bag_dir)):   # never delete recorded data
            _remove_unrecorded(out, given)
        raise
    finally:
        if run.progress is not None:
            run.progress.close()
        graph.stop_all()
        graph.close()
        lease.release()
        for s, h in old_handlers.items():
            signal.signal(s, h)
    # lazy: the analysis: loaded by warm_analysis at the end of the run, not at start
    from adcs_sim.app.analysis.metrics import jsonable_metrics
    metrics = analysed.metrics
    (out / 'metrics.json').write_text(json.dumps(jsonable_metrics(metrics), indent=2))
    return metrics


@one_line_warnings('adcs-run')   # a section written twice, named once per line
def main(argv=None) -> int:
    parser = command_parser('adcs-run', __doc__)
    parser.add_argument('scenario', nargs='?', default=None,
                        help='scenario params file, or the name of a shipped one, from any folder (e.g. '
                             f'{Path(DEFAULT_SCENARIO).stem} or config/{DEFAULT_SCENARIO}; default {DEFAULT_SCENARIO})')
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
    parser.add_argument('--explain', action='store_true',
                        help="print the scenario's resolved parameters (defaults included) with units, "
                             'section by section, and exit without starting anything')
    args = parser.parse_args(argv)
    try:
        scenario = resolve_scenario(args.scenario)
        if args.explain:
            # lazy: the parameter tables (0.6 s): only for --explain
            from adcs_sim.app.scenario.parameters import explain
            print(explain(scenario, args.duration))
            return 0
        out = args.out or fresh_folder(scenario.stem)
        print(f'adcs-run: {scenario} -> {out}', flush=True)
        metrics = run_scenario(scenario, out, args.duration, not args.no_progress and sys.stderr.isatty(),
                               args.tolerance_deg, args.allow_network, args.domain_id, args.restart)
    except (ParameterError, RunError) as exc:
        print(f'adcs-run: error: {exc}', file=sys.stderr)
        return 1 if isinstance(exc, RunError) else 2
    # lazy: the analysis: loaded by warm_analysis at the end of the run, not at start
    from adcs_sim.app.analysis.metrics import format_metrics
    print(f'bag: {out / "bag"}')
    print('metrics:')
    print(format_metrics(metrics))
    if args.report:
        # lazy: the report (matplotlib, 1.3 s): only when a report is asked for
        from adcs_sim.app.report import loading, single_run
        run = loading.load_run(out / 'bag', scenario.stem)  # named after its scenario: the paper's values
        print(f'report: {single_run.write_report(run, out / "report", args.tolerance_deg)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
