"""Actuation as one class per kind (``adcs_controllers.laws.allocation``: wheels, ideal torquers;
``adcs_controllers.laws.backstepping``: thrusters with a wheel): what differs between kinds is in
the classes' methods, so that the controller node, the batch engine and the scenario checks never
compare the kind's name."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from adcs_controllers.families import FAMILIES
from adcs_controllers.laws.allocation import ACTUATION_KINDS, Actuation, TorquerActuation, WheelActuation
from adcs_controllers.laws.backstepping import ThrusterActuation
from adcs_core.faults import FaultState
from adcs_msgs_py.topics import TOPICS

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('adcs_core', 'adcs_msgs_py', 'adcs_controllers', 'adcs_sim')
KINDS = (WheelActuation, TorquerActuation, ThrusterActuation)
KIND_NAMES = {c.kind for c in KINDS}


def _names_the_kind(node: ast.AST) -> bool:
    """``<x>.kind`` or ``<x>['actuator']`` / ``<x>.get('actuator', ...)``."""
    if isinstance(node, ast.Attribute) and node.attr in ('kind', 'actuator'):
        return True
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value == 'actuator':
        return True
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == 'get'
            and node.args and isinstance(node.args[0], ast.Constant) and node.args[0].value == 'actuator')


def kind_comparisons(source: str) -> list[int]:
    """Lines of ``source`` comparing an actuation kind's name (``== 'wheels'``, ``in ('wheels', ...)``)."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Compare):
            continue
        operands = [node.left, *node.comparators]
        constants = {c.value for o in operands for c in ast.walk(o) if isinstance(c, ast.Constant)}
        if constants & KIND_NAMES and any(_names_the_kind(o) for o in operands):
            lines.append(node.lineno)
    return lines


def test_the_scan_finds_a_kind_comparison():
    assert kind_comparisons("if act.kind == 'wheels':\n    pass\n") == [1]
    assert kind_comparisons("x = p['actuator'] != 'torquers'\n") == [1]
    assert kind_comparisons("y = p.get('actuator', 'wheels') in ('wheels', 'thrusters')\n") == [1]
    assert kind_comparisons("if name == 'wheels':\n    pass\n") == []     # a plant actuator's name


def test_no_code_compares_an_actuation_kind_name():
    found = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob('*.py')):
            lines = kind_comparisons(path.read_text())
            if lines:
                found[str(path.relative_to(ROOT))] = lines
    assert not found, f'actuation kinds compared by name (use the Actuation classes\' methods): {found}'


def test_every_kind_declares_its_topics_and_plant_actuators():
    assert set(ACTUATION_KINDS.values()) == {WheelActuation, TorquerActuation}
    for cls in KINDS:
        assert issubclass(cls, Actuation) and cls.kind and cls.command_topics and cls.plant_actuators
        assert all(t in TOPICS for t in cls.command_topics), cls
    # every controller family builds an actuation of one of the kinds: its own, or its section's
    # `actuator`, whose every choice is a kind
    for name, family in FAMILIES.items():
        actuator = next((p for p in family.schema.params if p.name == 'actuator'), None)
        if family.actuation is not None:
            assert family.actuation in KINDS and actuator is None, name
        else:
            assert set(actuator.choices) <= set(ACTUATION_KINDS), name


WHEELS = {'actuator': 'wheels', 'saturation': 'clip', 'wheels.names': ['w1', 'w2', 'w3', 'w4'],
          'wheels.axes': [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0, 1.0, 1.0, 1.0], 'wheels.max_torque': [0.01] * 4}


def test_wheel_faults_are_followed_and_told_to_the_law_torquers_follow_nothing():
    act = WheelActuation(WHEELS)
    told = []

    class Law:
        def on_wheels(self, axes, available):
            told.append(available.copy())
            return 'replanned'

    assert act.inform(Law()) == 'replanned' and told[-1].all()
    assert act.follow_faults({'w2': FaultState('failed')}) and act.usable() == 'w1,w3,w4'
    assert not act.follow_faults({'w2': FaultState('failed')})          # no change: nothing to tell
    values, applied = act.command(np.array([0.001, 0.002, -0.001]))
    assert values[1] == 0.0
    (topic, joints, field, sent), = act.command_messages(values)
    assert (topic, joints, field) == ('wheels/cmd', ['w1', 'w2', 'w3', 'w4'], 'effort') and sent is values
    torquers = TorquerActuation({'actuator': 'torquers', 'saturation': 'clip', 'torquers.max_torque': 0.1})
    assert not torquers.follow_faults({'w2': FaultState('failed')}) and torquers.inform(Law()) is None
    assert torquers.usable_status() == {'available_wheels': 'none'}
    values, applied = torquers.command(np.array([0.2, -0.05, 0.0]))
    assert np.array_equal(values, [0.1, -0.05, 0.0]) and torquers.plant_commands(values) == {'torquers': (values,)}
    with pytest.raises(ValueError, match='spin inertia'):
        torquers.wheel_momentum(np.zeros(3))
