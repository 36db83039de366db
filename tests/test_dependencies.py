"""Runtime dependencies declared once and everywhere (issue #17, first hour of a new user).

requirements.txt is the one list of pinned runtime dependencies: setup.py reads it for
``install_requires`` (so ``pip install .`` gives a working tool), package.xml names each of them
for a ROS workspace (rosdep keys), and every third-party module the package imports comes from
one of them. Read without building anything (the wheel's metadata: tests/test_packaging.py).
"""
from __future__ import annotations

import ast
import importlib.metadata
import re
import runpy
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import setuptools
from support.packaging import normal_name, requirements

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('adcs_core', 'adcs_msgs_py', 'adcs_controllers', 'adcs_sim')
ROSDEP_ALIASES = {'pyyaml': 'yaml'}   # rosdep's key for PyYAML is python3-yaml
# Optional imports, each inside the one function that needs it with a clear ImportError otherwise:
# (pandas was one, for adcs_sim.app.api's RunResult.dataframe(); it is a pinned runtime requirement
# since ppigrf, adcs_core/environment's IGRF coefficient reader, imports it. None now.)
OPTIONAL: set[str] = set()


def _rosdep_key(dist: str) -> set[str]:
    """The package.xml keys that name the distribution ``dist``."""
    if dist.startswith('ros-'):
        return {dist[len('ros-'):].replace('-', '_')}
    base = ROSDEP_ALIASES.get(dist, dist)
    return {f'python3-{base}', f'python3-{base}-pip'}


def test_every_requirement_is_pinned_and_ros_names_are_jazzy_pins():
    reqs = requirements()
    assert reqs, 'requirements.txt lists nothing'
    assert any(d.startswith('ros-rclpy') for d in reqs)


def test_setup_py_installs_exactly_the_requirements(monkeypatch):
    """setup.py run with setuptools.setup replaced by a recorder: its install_requires."""
    calls = []
    monkeypatch.setattr(setuptools, 'setup', lambda **kw: calls.append(kw))
    monkeypatch.setattr(sys, 'argv', ['setup.py', '--version'])
    runpy.run_path(str(ROOT / 'setup.py'), run_name='__main__')
    [kwargs] = calls
    assert sorted(kwargs['install_requires']) == sorted(requirements().values())


def test_package_xml_lists_every_runtime_dependency():
    root = ET.parse(ROOT / 'package.xml').getroot()
    exec_deps = {e.text.strip() for tag in ('exec_depend', 'depend') for e in root.iter(tag)}
    missing = {d for d in requirements() if not _rosdep_key(d) & exec_deps}
    assert not missing, f'package.xml has no exec_depend for {sorted(missing)}'
    named = {k for d in requirements() for k in _rosdep_key(d)}
    extra = exec_deps - named
    assert not extra, f'package.xml depends on {sorted(extra)}, which requirements.txt does not pin'


def _imported_top_modules() -> set[str]:
    mods = set()
    for package in PACKAGES:
        for path in (ROOT / package).rglob('*.py'):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    mods |= {a.name.split('.')[0] for a in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    mods.add(node.module.split('.')[0])
    return mods - set(sys.stdlib_module_names) - set(PACKAGES) - {'__future__'}


def _requires(dist: str) -> set[str]:
    try:
        lines = importlib.metadata.requires(dist) or ()
    except importlib.metadata.PackageNotFoundError:
        pytest.fail(f'{dist} is pinned but not installed in the test venv')
    return {normal_name(re.split(r'[\s;\[<>=!~]', line, maxsplit=1)[0]) for line in lines}


def test_every_imported_third_party_module_is_a_requirement():
    """A module of a direct requirement, or a ROS module (message packages, rclpy's own) that a
    pinned ros-* wheel brings with it at its pinned version."""
    provided = importlib.metadata.packages_distributions()
    reqs = set(requirements())
    ros_closure = {d for req in reqs if req.startswith('ros-') for d in _requires(req.split('[')[0])}
    undeclared = {}
    for module in sorted(_imported_top_modules() - OPTIONAL):
        dists = {normal_name(d) for d in provided.get(module, ())}
        ros_only = dists and all(d.startswith('ros-') for d in dists)
        if not (dists & reqs or (ros_only and dists & ros_closure)):
            undeclared[module] = sorted(dists)
    assert not undeclared, f'imported but not declared in requirements.txt: {undeclared}'
