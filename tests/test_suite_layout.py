"""The suite's own layout (docs/testing.md): helpers in tests/support/, no test module importing another,
registered markers only, and a conftest that needs no ROS.

"Without ROS" is checked in fresh interpreters whose import system refuses the ROS wheels
(:class:`support.ros_wheels.RefuseRos`: rclpy, rcl*, rmw*, rosidl*, the message and interface
packages, the domain coordinator), as if they were not installed.
"""
from __future__ import annotations

import ast
import subprocess
import sys
import tomllib

import pytest
from support.paths import FASTDDS_PROFILE, ROOT, TESTS
from support.ros_wheels import installed_ros_modules, is_ros_module

TEST_MODULES = sorted(TESTS.glob('test_*.py'))
SUPPORT_MODULES = sorted(p for p in (TESTS / 'support').glob('*.py') if p.name != '__init__.py')
# support modules that need the ROS wheels at import (each says so in its docstring)
NEEDS_ROS = {'support.recorder', 'support.recorded_topics', 'support.rogue'}
PURE_SUPPORT = sorted(f'support.{p.stem}' for p in SUPPORT_MODULES if f'support.{p.stem}' not in NEEDS_ROS)
# marks of pytest and of the plugins in requirements-dev.txt
BUILTIN_MARKS = {'parametrize', 'skip', 'skipif', 'xfail', 'usefixtures', 'filterwarnings', 'timeout'}
INI = tomllib.loads((ROOT / 'pyproject.toml').read_text())['tool']['pytest']['ini_options']
REGISTERED = {m.split(':')[0].strip() for m in INI['markers']}


def _without_ros(code: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """``python -c code`` from the repository root, the ROS wheels refused from its first line on."""
    prologue = ('import sys; sys.path[:0] = ["tests", "."]\n'
                'from support.ros_wheels import refuse_ros; refuse_ros()\n'
                'before = {m for m in sys.modules}\n')
    return subprocess.run([sys.executable, '-c', prologue + code], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout, check=False)


def _imports(path) -> list[str]:
    """Every module ``path`` imports (module level and inside functions)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            out.append(node.module)
    return out


def test_the_ros_rule_names_every_module_of_the_ros_wheels():
    """is_ros_module (by name, usable where ROS is missing) covers what the ros-* wheels install here."""
    installed = installed_ros_modules()
    assert 'rclpy' in installed or not installed   # the wheels are installed here, or none at all
    assert not sorted(m for m in installed if not is_ros_module(m))
    assert not any(is_ros_module(m) for m in ('numpy', 'rosbags', 'mcap_ros2', 'adcs_msgs_py', 'support', 'yaml'))


def test_conftest_and_the_pure_support_modules_import_without_ros():
    code = (f'import conftest\nfor m in {PURE_SUPPORT!r}: __import__(m)\n'
            'from support.ros_wheels import is_ros_module\n'
            'print(sorted(m for m in set(sys.modules) - before if is_ros_module(m)))')
    out = _without_ros(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '[]'


@pytest.mark.parametrize('module', sorted(NEEDS_ROS))
def test_the_support_modules_said_to_need_ros_do(module):
    """Keeps NEEDS_ROS honest: a module that no longer needs ROS moves to the pure ones."""
    out = _without_ros(f'import {module}')
    assert out.returncode != 0 and 'the ROS wheels are refused' in out.stderr, out.stderr


@pytest.mark.slow
def test_the_suite_without_graph_tests_collects_without_ros():
    """``pytest -m "not graph" --collect-only`` works without the ROS wheels: the pure test modules import
    no ROS at module level; a module that does (message types, rcl's parser) is skipped, saying so."""
    code = ('import pytest\n'
            'sys.exit(pytest.main(["--collect-only", "-q", "-rs", "-m", "not graph", "-p", "no:cacheprovider",'
            ' "-p", "no:xdist", "tests"]))')
    out = _without_ros(code, timeout=300.0)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    last = out.stdout.strip().splitlines()[-1]
    assert ' tests collected' in last and 'error' not in last, last
    skipped = [line for line in out.stdout.splitlines() if line.startswith('SKIPPED')]
    assert all('needs the ROS wheels' in line for line in skipped), skipped


def test_no_test_module_imports_another():
    """Shared code lives in support/: no test module imports a test module or conftest, and support/
    imports no test module either."""
    local = {p.stem for p in TEST_MODULES} | {'conftest'}
    wrong = {str(path.relative_to(TESTS)): found for path in TEST_MODULES + SUPPORT_MODULES + [TESTS / 'conftest.py']
             if (found := [m for m in _imports(path) if m.split('.')[0] in local])}
    assert not wrong, f'move what they import to tests/support/: {wrong}'


def _marks(path) -> set[str]:
    """The names X of every ``pytest.mark.X`` in ``path``."""
    return {node.attr for node in ast.walk(ast.parse(path.read_text(), str(path)))
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute) and node.value.attr == 'mark'
            and isinstance(node.value.value, ast.Name) and node.value.value.id == 'pytest'}


def test_markers_are_registered_and_strict():
    assert {'graph', 'slow', 'paper'} <= REGISTERED
    assert '--strict-markers' in INI['addopts'].split()


def test_every_test_module_carries_registered_markers_only():
    unknown = {path.name: sorted(found) for path in TEST_MODULES + [TESTS / 'conftest.py']
               if (found := _marks(path) - REGISTERED - BUILTIN_MARKS)}
    assert not unknown, f'unregistered markers (pyproject.toml [tool.pytest.ini_options] markers): {unknown}'


def test_the_fast_dds_profile_set_for_in_process_graphs_is_the_nodes():
    """conftest sets FASTRTPS_DEFAULT_PROFILES_FILE without importing rclpy: the file the nodes use."""
    pytest.importorskip('rclpy')
    from adcs_msgs_py.node import FASTDDS_PROFILE as nodes_profile
    assert FASTDDS_PROFILE == nodes_profile and FASTDDS_PROFILE.is_file()
