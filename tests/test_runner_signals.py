"""The runner under signals and crashes (issue #10 item 4), through ``adcs-run`` as a process.

SIGINT / SIGTERM during start-up (recorder starting; nodes starting), during shutdown (the
dynamics node has finished, the graph is being stopped) and twice in a row: the runner exits,
leaves no process behind, and any bag it leaves is complete (closed by the recorder). A node
killed mid-run: the runner stops the graph, keeps the bag and exits non-zero naming the node and
how it died. (Mid-run SIGINT/SIGTERM: tests/test_runner.py.) Each test waits on process states
and files, never on time.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from support.paths import ROOT
from support.processes import alive, children
from support.scenarios import make_scenario

from adcs_sim.app.analysis.metrics import RunData
from adcs_sim.bag.reader import is_complete, read_raw

DEADLINE = 120.0


class Run:
    """``adcs-run`` as a subprocess; remembers every child process it ever saw."""

    def __init__(self, tmp_path, duration: float, spawn) -> None:
        self.scenario = make_scenario(tmp_path, {'dynamics': {'duration': duration}})
        self.out = tmp_path / 'run'
        self.bag = self.out / 'bag'
        self.proc = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(self.scenario), '--out',
                           str(self.out), '--no-progress'], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, cwd=ROOT)
        self.seen: dict[int, str] = {}

    def wait_for(self, what: str, condition) -> bool:
        """Poll (process table, files) until ``condition()``; False if the runner exited first."""
        deadline = time.monotonic() + DEADLINE
        while True:
            for pid, args in children(self.proc.pid).items():
                if args or pid not in self.seen:   # keep the name of a zombie (no command line)
                    self.seen[pid] = args
            if condition():
                return True
            if self.proc.poll() is not None:
                return False
            assert time.monotonic() < deadline, f'{what}: not reached in {DEADLINE:g} s'
            try:
                self.proc.wait(timeout=0.01)
            except subprocess.TimeoutExpired:
                pass

    def node_pids(self, module: str) -> list[int]:
        return [pid for pid, args in self.seen.items() if module in args]

    def finish(self) -> tuple[int, str]:
        try:
            _, err = self.proc.communicate(timeout=DEADLINE)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.communicate()
        return self.proc.returncode, err

    def assert_clean(self) -> None:
        left = [f'{pid} {args}' for pid, args in self.seen.items() if alive(pid)]
        assert not left, f'processes left behind: {left}'
        if self.bag.exists():   # whatever was recorded is a complete, closed bag
            assert is_complete(self.bag), sorted(p.name for p in self.bag.iterdir())


def _state_recorded(bag, count: int = 1) -> bool:
    """At least ``count`` states are in the bag's flushed part (the run is under way)."""
    try:
        return sum(t == '/state' for t, *_ in read_raw(bag)) >= count
    except (FileNotFoundError, ValueError):
        return False


@pytest.mark.parametrize('phase, sig', [
    ('recorder_starting', signal.SIGINT),
    ('nodes_starting', signal.SIGTERM),
    ('shutdown', signal.SIGINT),
    ('twice', signal.SIGINT),
])
def test_signal_at_any_phase_leaves_no_orphan_and_a_complete_bag(tmp_path, phase, sig, spawn):
    run = Run(tmp_path, 30.0 if phase == 'shutdown' else 1.0e6, spawn)
    try:
        if phase == 'recorder_starting':
            reached = run.wait_for('recorder started', lambda: run.node_pids('adcs_sim.nodes.recorder'))
        elif phase == 'nodes_starting':
            reached = run.wait_for('dynamics started', lambda: run.node_pids('adcs_sim.nodes.dynamics'))
        elif phase == 'shutdown':   # the dynamics node has finished: the runner is stopping the graph
            reached = run.wait_for('dynamics finished', lambda: run.node_pids('adcs_sim.nodes.dynamics')
                                   and not any(map(alive, run.node_pids('adcs_sim.nodes.dynamics'))))
        else:                       # mid-run Ctrl-C, then a second signal while the graph is stopping
            reached = run.wait_for('run under way', lambda: _state_recorded(run.bag, 2))   # (as below)
        assert reached, f'runner exited before {phase}: {run.finish()}'
        run.proc.send_signal(sig)
        if phase == 'twice':
            assert run.wait_for('first node stopped',
                                lambda: not all(map(alive, run.seen))) or run.proc.poll() is not None
            if run.proc.poll() is None:
                run.proc.send_signal(signal.SIGTERM)
        code, err = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    if phase == 'shutdown' and code == 0:
        pass    # the signal landed after the runner had finished stopping: a normal, complete run
    else:
        assert code == 1, err
        assert 'interrupted by' in err, err
    run.assert_clean()
    if phase in ('shutdown', 'twice'):
        assert is_complete(run.bag)
        assert RunData.from_bag(run.bag).t.size > 1


def test_node_killed_mid_run_stops_graph_keeps_bag_and_names_it(tmp_path, spawn):
    run = Run(tmp_path, 1.0e6, spawn)
    try:
        # two states recorded: the controller has answered at least one step (the first state
        # alone can be flushed before the controller's first answer, under load)
        assert run.wait_for('run under way', lambda: _state_recorded(run.bag, 2)), run.finish()
        [controller] = run.node_pids('adcs_controllers.nodes.pd_controller')
        os.kill(controller, signal.SIGKILL)
        code, err = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    assert code == 1
    assert 'pd_controller was killed by SIGKILL during the run' in err, err
    assert f'bag kept in {run.bag}' in err
    run.assert_clean()
    assert is_complete(run.bag)
    assert RunData.from_bag(run.bag).t.size > 1
