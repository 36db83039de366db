"""Network and input safety (issue #10 item 7). No ROS graph; a few seconds.

* Every process a run starts discovers on localhost only and on its own leased domain id;
  ``adcs-run --allow-network`` is the one, explicit way to discover on the subnet.
* YAML is only ever read with safe loaders; no source calls eval/exec/compile/__import__ or
  unpickles anything (checked on the AST of every module we ship, tools and tests included);
  and a scenario whose values are code stays data: it is refused, never run.
"""
from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest
from support.paths import ROOT

from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.graph import runner

SOURCE_DIRS = ['adcs_sim', 'adcs_controllers', 'adcs_msgs_py', 'benchmarks', 'tests']
SOURCES = sorted(p for d in SOURCE_DIRS for p in (ROOT / d).rglob('*.py')) + [ROOT / 'setup.py']

FORBIDDEN_CALLS = {'eval', 'exec', 'compile', '__import__', 'execfile'}
UNSAFE_YAML = {'load', 'load_all', 'full_load', 'full_load_all', 'unsafe_load', 'unsafe_load_all',
               'Loader', 'FullLoader', 'UnsafeLoader'}
FORBIDDEN_MODULES = {'pickle', 'cPickle', 'marshal', 'shelve', 'dill', 'cloudpickle'}


def _violations(path: Path, root: Path = ROOT) -> list[str]:
    tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
    out = []
    for node in ast.walk(tree):
        where = f'{path.relative_to(root)}:{getattr(node, "lineno", "?")}'
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name) and f.id in FORBIDDEN_CALLS:
                out.append(f'{where}: {f.id}()')
            if isinstance(f, ast.Attribute) and f.attr in FORBIDDEN_CALLS and \
                    isinstance(f.value, ast.Name) and f.value.id == 'builtins':
                out.append(f'{where}: builtins.{f.attr}()')
            if any(k.arg == 'shell' and not (isinstance(k.value, ast.Constant) and k.value.value is False)
                   for k in node.keywords):
                out.append(f'{where}: subprocess with shell=')
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and \
                node.value.id == 'yaml' and node.attr in UNSAFE_YAML:
            out.append(f'{where}: yaml.{node.attr}')
        if isinstance(node, ast.ImportFrom) and node.module == 'yaml' and \
                any(a.name in UNSAFE_YAML for a in node.names):
            out.append(f'{where}: from yaml import {[a.name for a in node.names]}')
        if isinstance(node, ast.Import) and any(a.name.split('.')[0] in FORBIDDEN_MODULES for a in node.names):
            out.append(f'{where}: import {[a.name for a in node.names]}')
        if isinstance(node, ast.ImportFrom) and (node.module or '').split('.')[0] in FORBIDDEN_MODULES:
            out.append(f'{where}: from {node.module} import')
    return out


def test_the_checker_sees_what_it_forbids(tmp_path):
    """The AST check itself: each forbidden pattern is caught (so a pass below means something)."""
    bad = tmp_path / 'bad.py'
    bad.write_text('import yaml, pickle, subprocess, builtins\n'
                   'yaml.load(open("x"), Loader=yaml.Loader)\nyaml.unsafe_load("a")\n'
                   'eval("1")\nexec("x = 1")\nbuiltins.eval("2")\n__import__("os")\n'
                   'subprocess.run("ls", shell=True)\nfrom yaml import FullLoader\n')
    found = '\n'.join(_violations(bad, tmp_path))
    for needle in ('yaml.load', 'yaml.Loader', 'yaml.unsafe_load', 'eval()', 'exec()', 'builtins.eval()',
                   '__import__()', 'shell=', 'FullLoader', "import ['yaml', 'pickle'"):
        assert needle in found, (needle, found)
    ok = tmp_path / 'ok.py'
    ok.write_text('import ast, yaml\nyaml.safe_load("a: 1")\nast.literal_eval("1")\n'
                  'import subprocess\nsubprocess.run(["ls"], shell=False)\n')
    assert _violations(ok, tmp_path) == []


@pytest.mark.slow
def test_sources_use_safe_yaml_and_never_evaluate_code():
    assert len(SOURCES) > 50
    problems = [v for p in SOURCES for v in _violations(p)]
    assert not problems, 'unsafe constructs:\n' + '\n'.join(problems)


def test_yaml_code_tags_in_a_scenario_are_refused_not_run(tmp_path):
    """rcl's parser ignores tags: the tagged value is data (a string array), which the schema
    refuses where a number is due; nothing is constructed or run."""
    from adcs_sim.app.scenario.registry import NODES
    marker = tmp_path / 'pwned'
    path = tmp_path / 'evil.yaml'
    path.write_text('dynamics:\n  ros__parameters:\n'
                    f'    duration: !!python/object/apply:os.system ["touch {marker}"]\n')
    value = load_params_file(str(path))['dynamics']['duration']
    assert value == [f'touch {marker}']
    nominal = load_params_file(str(ROOT / 'config' / 'microsat_pd_slew.yaml'))['dynamics']
    with pytest.raises(ParameterError, match='duration'):
        NODES['dynamics'].schema.validate({**nominal, 'duration': value})
    assert not marker.exists()


def test_parameter_strings_are_data_not_code(tmp_path):
    """A string where a number is due is a type error naming the key, never evaluated; a string
    parameter keeps the text verbatim."""
    from adcs_sim.app.scenario.registry import NODES
    marker = tmp_path / 'pwned'
    code = f"__import__('os').system('touch {marker}')"
    section = load_params_file(str(ROOT / 'config' / 'microsat_pd_slew.yaml'))['pd_controller']
    with pytest.raises(ParameterError, match='kp'):
        NODES['pd_controller'].schema.validate({**section, 'kp': code})
    rec = NODES['recorder'].schema.validate({'output': code})
    assert rec['output'] == code
    assert not marker.exists()


def test_run_processes_discover_on_localhost_only_on_a_leased_domain(monkeypatch):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SUBNET')   # the caller's shell says SUBNET
    monkeypatch.setenv('ROS_LOCALHOST_ONLY', '0')
    monkeypatch.setenv('ROS_DOMAIN_ID', '7')
    a, b = runner.lease_domain(), runner.lease_domain()
    try:
        env_a, env_b = runner.graph_env(a), runner.graph_env(b)
        assert env_a['ROS_AUTOMATIC_DISCOVERY_RANGE'] == env_b['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
        assert 'ROS_LOCALHOST_ONLY' not in env_a
        ids = {int(env_a['ROS_DOMAIN_ID']), int(env_b['ROS_DOMAIN_ID'])}
        assert len(ids) == 2 and all(1 <= i <= 99 for i in ids)   # fresh, and not the caller's 7 twice
        net = runner.graph_env(a, allow_network=True)
        assert net['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SUBNET'
        assert net['ROS_DOMAIN_ID'] == env_a['ROS_DOMAIN_ID']
        with pytest.raises(runner.RunError, match='--domain-id'):   # held by this run already
            runner.lease_domain(int(env_a['ROS_DOMAIN_ID']))
        with pytest.raises(runner.RunError, match='--domain-id'):
            runner.lease_domain(500)
    finally:
        a.release()
        b.release()


def test_nodes_default_to_localhost_discovery(monkeypatch):
    from adcs_msgs_py.node import network_hygiene_defaults
    monkeypatch.delenv('ROS_AUTOMATIC_DISCOVERY_RANGE', raising=False)
    network_hygiene_defaults()
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'


def test_allow_network_is_an_explicit_documented_option(capsys):
    with pytest.raises(SystemExit):
        runner.main(['--help'])
    text = capsys.readouterr().out
    assert '--allow-network' in text and '--domain-id' in text
    readme = (ROOT / 'README.md').read_text()
    assert '--allow-network' in readme
