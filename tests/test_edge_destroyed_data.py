"""Issue #31, class "Destroyed or hidden data": a bag has one writer at a time.

``adcs-bag-repair`` run on the bag of a run still recording used to "repair" it: the run's bag
became a prefix, the complete recording was renamed aside, and the run exited 0 with the metrics of
the prefix. The writer of a bag (the recorder's ``BagWriter``) now holds a lock on it
(:mod:`adcs_sim.bag.lock`) that says who it is: repair refuses a bag whose writer is alive, naming it,
and leaves every file as it was; ``adcs-analyze`` says the bag is still being written; a lock left by a
killed writer blocks nothing (the kernel's lock dies with its process).
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.bags import states_on_disk
from support.paths import ROOT, SCRIPTS
from support.processes import alive, children
from support.scenarios import make_scenario

from adcs_sim.app.analysis.analyze import main as analyze_main
from adcs_sim.app.analysis.repair import main as repair_main
from adcs_sim.bag.lock import bag_writer
from adcs_sim.bag.reader import is_complete, read_metadata, read_raw
from adcs_sim.bag.writer import BagWriter

COMMITTED = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'
CHILD = SCRIPTS / 'bag_writer_child.py'
SCENARIO = ROOT / 'config' / 'microsat_pd_slew.yaml'


def run_tool(main, *args: str) -> tuple[int, list[str], list[str]]:
    """(exit status, stdout lines, stderr lines) of a tool's ``main`` called in-process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return code, out.getvalue().splitlines(), err.getvalue().splitlines()


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative name -> content)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob('*')) if p.is_file()}


def live_copy(dst: Path) -> BagWriter:
    """A bag being written: the committed PD slew's messages, flushed, the writer left open."""
    writer = BagWriter(dst, metadata=read_metadata(COMMITTED))
    for topic, type_name, t, data in read_raw(COMMITTED):
        writer.add_topic(topic, type_name, [])
        writer.write(topic, data, log_time_ns=t)
    writer.flush()
    return writer


def writer_named(line: str, pid: int) -> bool:
    return f'pid {pid} on {socket.gethostname()}' in line


class TestDestroyedOrHiddenData:
    def test_repair_refuses_a_bag_being_written_naming_its_writer(self, tmp_path):
        bag = tmp_path / 'bag'
        writer = live_copy(bag)
        before = snapshot(tmp_path)
        code, out, err = run_tool(repair_main, str(bag))
        assert code == 1 and out == [] and len(err) == 1, (code, out, err)
        assert err[0].startswith(f'adcs-bag-repair: {bag}: being written by ') and writer_named(err[0], os.getpid())
        assert snapshot(tmp_path) == before                    # nothing renamed, rewritten or added
        writer.close()
        assert is_complete(bag) and not list(bag.glob('.*'))    # closed: complete, the lock file gone
        assert run_tool(repair_main, str(bag))[1] == [f'{bag}: complete, nothing to repair '
                                                      f'({sum(1 for _ in read_raw(bag))} messages)']

    def test_analyze_says_a_bag_is_still_being_written_naming_its_writer(self, tmp_path):
        writer = live_copy(tmp_path / 'bag')
        code, out, err = run_tool(analyze_main, str(writer.path), '--json', '--no-report')
        assert code == 0 and len(err) == 1, err
        assert err[0].startswith(f'adcs-analyze: warning: {writer.path}: still being written by ')
        assert writer_named(err[0], os.getpid()) and 'analysed the' in err[0]
        writer.close()
        code, out, err = run_tool(analyze_main, str(writer.path), '--json', '--no-report')
        assert code == 0 and err == []

    def test_a_lock_left_by_a_killed_writer_does_not_block_repair(self, tmp_path, spawn):
        bag = tmp_path / 'bag'
        proc = spawn([sys.executable, str(CHILD), str(bag), '4096', '20', str(SCENARIO)],
                     stdout=subprocess.PIPE, text=True, cwd=ROOT)
        assert proc.stdout.readline().strip() == 'ready'
        assert proc.stdout.readline().startswith('flushed ')
        code, _, err = run_tool(repair_main, str(bag))          # alive: refused, naming it
        assert code == 1 and len(err) == 1 and writer_named(err[0], proc.pid), err
        assert 'bag_writer_child.py' in err[0]
        assert sorted(p.name for p in bag.iterdir()) == ['.writer.lock', 'bag_0.mcap']
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=60) == -signal.SIGKILL
        assert (bag / '.writer.lock').exists()                  # left behind, its lock gone with the process
        code, out, err = run_tool(repair_main, str(bag))
        assert code == 0 and err == [] and 'repaired' in out[0], (out, err)
        assert is_complete(bag) and sorted(p.name for p in bag.iterdir()) == [
            'bag_0.mcap', 'bag_0.mcap.truncated', 'metadata.yaml']

    def test_repair_of_a_live_runs_bag_is_refused_and_the_run_keeps_its_bag_and_metrics(self, tmp_path, spawn):
        """The issue's must-show: ``adcs-bag-repair`` on the bag of a run under way. The run is frozen
        (its dynamics node stopped with SIGSTOP as soon as it exists, a lockstep timeout longer than
        any stop) so the attempt is certain to meet a live recorder; afterwards the run completes with every step
        in its bag and the metrics of the whole run."""
        steps = 600
        scenario = make_scenario(tmp_path, {'dynamics': {'duration': float(steps), 'lockstep.timeout': 600.0},
                                            'recorder': {'flush_period': 0.1}})
        out = tmp_path / 'run'
        bag = out / 'bag'
        proc = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                      '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
        deadline = time.monotonic() + 120
        dynamics = None   # stopped as soon as it exists: the run cannot have ended, however fast the machine
        while dynamics is None:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, 'the run did not start its dynamics node'
            dynamics = next((pid for pid, cmd in children(proc.pid).items() if 'adcs_sim.nodes.dynamics' in cmd), None)
            if dynamics is None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=0.01)
        os.kill(dynamics, signal.SIGSTOP)
        try:
            while bag_writer(bag) is None:   # the recorder has taken its bag (its lock held)
                assert proc.poll() is None, proc.communicate()
                assert time.monotonic() < deadline, 'the recorder did not take its bag'
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=0.05)
            nodes = children(proc.pid)
            spawn.adopt(nodes)
            recorder = next(pid for pid, cmd in nodes.items() if 'adcs_sim.nodes.recorder' in cmd)
            assert alive(dynamics), 'the run ended before it could be stopped'
            assert states_on_disk(bag) < steps + 1
            before = sorted(p.name for p in bag.iterdir())
            code, _, err = run_tool(repair_main, str(bag))
            assert code == 1 and len(err) == 1 and writer_named(err[0], recorder), err
            assert 'recorder' in err[0]
            assert sorted(p.name for p in bag.iterdir()) == before and not list(out.glob('.bag.repair-*'))
        finally:
            os.kill(dynamics, signal.SIGCONT)
        stdout, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, stderr
        assert is_complete(bag) and sorted(p.name for p in bag.iterdir()) == ['bag_0.mcap', 'metadata.yaml']
        assert states_on_disk(bag) == steps + 1                 # every step, not the prefix of the attempt
        metrics = json.loads((out / 'metrics.json').read_text())
        assert metrics['duration_s'] == steps and metrics['missed_steps'] == 0
        code, analysed, err = run_tool(analyze_main, str(bag), '--json', '--no-report')
        assert code == 0 and err == [] and json.loads('\n'.join(analysed))[str(bag)] == metrics


@pytest.mark.slow
def test_reanalysis_replaces_its_own_report_and_keeps_a_file_it_did_not_write(tmp_path):
    """A report folder given again to ``adcs-analyze --out``: the old report's files (its Markdown
    and what it links) are replaced; a file the report does not name, though of a report's kind
    (the user's notes.md), is not the tool's and stays as it was."""
    out = tmp_path / 'report'
    assert run_tool(analyze_main, str(COMMITTED), '--out', str(out))[0] == 0
    figure = out / 'attitude_error.png'
    first = figure.stat().st_mtime_ns
    (out / 'notes.md').write_text('mine\n')
    code, _, err = run_tool(analyze_main, str(COMMITTED), '--out', str(out))
    assert code == 0, err
    assert (out / 'notes.md').read_text() == 'mine\n'
    assert figure.is_file() and (out / 'report.md').is_file() and figure.stat().st_mtime_ns >= first
