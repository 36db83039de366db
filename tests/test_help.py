"""Every executable answers ``--help`` with its usage and exits 0 (issue #17, first hour): a node
prints its parameters (the schema's, briefly) without starting, joining a graph or recording."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from support.packaging import NODES, TOOLS

from adcs_msgs_py.node import wants_help
from adcs_sim.app.scenario.registry import NODES as REGISTRY

VENV_BIN = Path(sys.prefix) / 'bin'
TIMEOUT = 120.0   # a hang guard only


def _help(name: str, flag: str, cwd: Path) -> subprocess.CompletedProcess:
    exe = VENV_BIN / name
    assert exe.exists(), f'{exe} is missing: the venv has no editable install of the package'
    return subprocess.run([str(exe), flag], capture_output=True, text=True, timeout=TIMEOUT, cwd=cwd,
                          stdin=subprocess.DEVNULL)


@pytest.mark.graph
@pytest.mark.parametrize('name', sorted(NODES))
def test_node_help_prints_its_parameters_and_starts_nothing(name, tmp_path):
    proc = _help(name, '--help', tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f'usage: {name} ')
    for param in REGISTRY[name].schema.params:
        assert f'  {param.name} ' in proc.stdout, f'{name} --help does not name {param.name}'
    assert list(tmp_path.iterdir()) == [], 'the --help run wrote files (a recording?)'


@pytest.mark.parametrize('name', [pytest.param(t, marks=pytest.mark.graph) if t == 'adcs-run' else t   # imports rclpy
                                  for t in sorted(TOOLS)])
def test_tool_help_prints_usage(name, tmp_path):
    proc = _help(name, '-h', tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('usage: ')
    assert list(tmp_path.iterdir()) == []


def test_help_after_ros_args_is_a_ros_argument_not_ours():
    """``--ros-args ... --help`` belongs to rcl, not to the node: not our usage."""
    assert wants_help(['dynamics', '--help'])
    assert wants_help(['dynamics', '-h', '--ros-args', '-p', 'x:=1'])
    assert not wants_help(['dynamics', '--ros-args', '-p', 'help:=1', '--help'])
