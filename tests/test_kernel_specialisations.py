"""The compiled kernels are compiled once each, ahead of use (adcs_sim/app/batch/kernels.py), and a
compilation is never silent (adcs_core/compile_log.py).

* every kernel that the runs call from Python is called with the one signature that
  ``kernels.SPECIALISATIONS`` lists (what ``make install``, the wheel's build and the tests' session
  start compile): a run then loads machine code and compiles nothing, also with per-run targets,
  inertias and limits (read-only views, which ``kernel_rows`` copies) and with faults;
* a compilation prints one line naming the kernel, its argument types and its time;
* the compiling processes share the kernels between them, each once.
"""
from __future__ import annotations

import importlib
import json
import subprocess
import sys

import numpy as np
import pytest
from numba import njit
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_core import compile_log
from adcs_core.attitude import euler_213
from adcs_sim.app.analysis.batch_metrics import batch_run_metrics, full_run_columns_numpy
from adcs_sim.app.batch import kernels
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import DEFAULT_SCENARIO, config_dirs, validate_scenario
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.truth.kernel import kernel_rows


def batch(scenario, runs: list[dict]) -> BatchSimulation:
    nominal = validate_scenario(scenario)
    return BatchSimulation.from_runs([{name: NODES[name].schema.validate({**params, **o.get(name, {})})
                                       for name, params in nominal.items()} for o in runs])


def dispersed(n: int) -> list[dict]:
    """PD slews with per-run targets, gains, controller inertias and wheel limits (the fused loop's
    per-run arguments)."""
    rng = np.random.default_rng(33)
    runs = []
    for _ in range(n):
        q_ref = rng.normal(size=4)
        runs.append({'dynamics': {'inertia': (np.array([12.0, 14.0, 10.0]) + rng.normal(0, 0.6, 3)).tolist()},
                     'pd_controller': {'kp': float(rng.uniform(0.0015, 0.004)),
                                       'target.attitude': (q_ref / np.linalg.norm(q_ref)).tolist(),
                                       'inertia': (np.array([12.0, 14.0, 10.0]) + rng.normal(0, 0.6, 3)).tolist(),
                                       'wheels.max_torque': rng.uniform(0.008, 0.012, 3).tolist()}})
    return runs


@pytest.mark.slow
def test_the_runs_call_each_kernel_with_its_listed_types_only(tmp_path):
    """The default scenario on the batch engine past its wheel failure (plant kernel, general path,
    the metrics of a run with a fault), PD slews on the fused loop with per-run arguments and their
    batch metrics (and the numpy reference's), a report's Euler angles: no kernel sees other types
    than those listed."""
    default = next(d / DEFAULT_SCENARIO for d in config_dirs() if (d / DEFAULT_SCENARIO).is_file())
    batch_run_metrics(batch(default, [{'dynamics': {'duration': 505.0}}] * 2).run())   # a wheel fails at 500 s
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 40.0}})
    for runs in (dispersed(3), dispersed(1)):
        result = batch(scenario, runs).run()
        batch_run_metrics(result)
        full_run_columns_numpy(result, np.arange(result.n_runs), 0.5)
    euler_213(np.tile([0.1, 0.2, 0.3, 0.9], (100, 1)))
    for name, codes, _ in kernels.SPECIALISATIONS:
        assert set(kernels.dispatcher(name).signatures) <= {kernels.argument_types(codes)}, name


def test_every_kernel_of_the_packages_is_listed():
    """Each dispatcher of the kernel modules that Python calls is listed (the inlined helpers are
    compiled inside their callers): a new kernel cannot be left out of the install's compilation."""
    from numba.core.registry import CPUDispatcher
    listed = {name for name, _, _ in kernels.SPECIALISATIONS}
    modules = {name.rsplit('.', 1)[0] for name in listed}
    found = set()
    for module in modules:
        for attr, value in vars(importlib.import_module(module)).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module \
                    and value.targetoptions.get('inline', 'never') == 'never':
                found.add(f'{module}.{attr}')
    assert found <= listed, found - listed


def _add(a, b):
    return a + b


def test_a_compilation_prints_its_kernel_types_and_time(monkeypatch, capsys):
    monkeypatch.setattr(compile_log, 'PACKAGES', compile_log.PACKAGES + (__name__ + '.',))
    monkeypatch.setattr(compile_log, 'PRINT', True)
    add = njit(_add)   # a new dispatcher: compiled at its first call
    before = len(compile_log.COMPILED)
    assert add(np.ones(3), 2.0)[0] == 3.0
    assert [entry[:2] for entry in compile_log.COMPILED[before:]] == [(f'{__name__}._add', 'f8[1d C], float64')]
    line, = [text for text in capsys.readouterr().err.splitlines() if '._add(' in text]
    assert line.startswith(f'numba: compiled {__name__}._add(f8[1d C], float64) in ') and line.endswith(' s)')


def test_types_are_named_briefly():
    from numba import types
    assert compile_log.type_text(types.Array(types.float64, 2, 'C', readonly=True)) == 'f8[2d C ro]'
    assert compile_log.type_text(types.Array(types.int64, 1, 'A')) == 'i8[1d A]'
    assert kernels.argument_types('F3 I1 B1 f i b') == (
        types.Array(types.float64, 3, 'C'), types.Array(types.int64, 1, 'C'), types.Array(types.boolean, 1, 'C'),
        types.float64, types.int64, types.boolean)


@pytest.mark.parametrize('jobs', [1, 2, 3])
def test_the_processes_share_the_kernels_each_once(jobs):
    parts = kernels.plan(jobs)
    assert len(parts) == min(jobs, len(kernels.SPECIALISATIONS))
    assert sorted(name for part in parts for name in part) == sorted(name for name, _, _ in kernels.SPECIALISATIONS)
    assert parts[0][0] == 'adcs_sim.app.batch.fused.closed_loop'   # the longest starts first


def test_an_unknown_kernel_is_refused_in_one_line(capsys):
    assert kernels.main(['--only', 'adcs_sim.truth.kernel.rk4_runs,adcs_sim.truth.kernel.nothing']) == 2
    assert capsys.readouterr().err == 'kernels: --only: not a listed kernel: adcs_sim.truth.kernel.nothing\n'


def test_kernel_rows_copies_a_read_only_view_only():
    a = np.arange(6.0).reshape(2, 3)
    assert kernel_rows(a) is a
    view = np.broadcast_to(np.arange(3.0), (1, 3))
    rows = kernel_rows(view)
    assert rows.flags.writeable and rows.flags.c_contiguous and rows is not view
    assert np.array_equal(rows, view) and rows.dtype == np.float64


PROBE = r"""
import importlib, json, sys
from adcs_sim.app.analysis.analyze import main
from adcs_sim.app.batch import kernels
from adcs_sim.app.scenario.files import DEFAULT_SCENARIO, resolve_scenario, validate_scenario
from adcs_sim.truth.step import TruthStep
sections = validate_scenario(resolve_scenario(DEFAULT_SCENARIO))
TruthStep(sections['dynamics'])   # what the dynamics node builds (its plant warms the kernel)
assert main([sys.argv[1], '--out', sys.argv[2]]) == 0         # the report of the default scenario's bag
used = [name for name, _, _ in kernels.SPECIALISATIONS
        if importlib.import_module(name.rsplit('.', 1)[0]).__dict__[name.rsplit('.', 1)[1]].signatures]
print(json.dumps(used))
"""


@pytest.mark.slow
def test_a_graph_run_and_its_report_use_only_the_run_kernels(tmp_path):
    """What ``make run`` compiles before its run (``RUN_KERNELS``) is what the dynamics node's plant
    and the report of the default scenario call (in a fresh interpreter: nothing else loaded)."""
    bag = ROOT / 'bags' / DEFAULT_SCENARIO.removesuffix('.yaml') / 'bag'
    proc = subprocess.run([sys.executable, '-c', PROBE, str(bag), str(tmp_path / 'report')], capture_output=True,
                          text=True, cwd=tmp_path, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(json.loads(proc.stdout.splitlines()[-1])) == sorted(kernels.RUN_KERNELS)
