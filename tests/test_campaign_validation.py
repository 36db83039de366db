"""Campaign.load validates the stacked draws at once (Schema.validate_stacked) with the refusals and
the error texts of validating run by run.

* every refusal (a negative or non-physical inertia, an inertia below the wheels' spin inertia, a
  negative torque limit, a too short duration, a kp draw of a schema without a batch check) gives
  the same CampaignError text as the run-by-run path (validate_stacked switched off);
* the reference campaigns take the stacked path (nothing validated run by run);
* the declarations it rests on (Param.cross: a parameter the whole-section check reads by length
  only, or not at all) hold for every schema: its check is run on a valid section with such a
  parameter replaced by a value that refuses any other use;
* each vectorised check (Param.coerce_many) agrees with Param.coerce row by row.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from support.paths import CONFIG
from support.scenarios import write_campaign

from adcs_msgs_py.params import ParameterError, Schema
from adcs_sim.app.campaign.plan import Campaign, CampaignError
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario


def error_of(path) -> str:
    with pytest.raises(CampaignError) as info:
        Campaign.load(path)
    return str(info.value)


@pytest.mark.parametrize('dispersions', [
    {'dynamics.inertia': {'distribution': 'normal', 'std': [6.0, 7.0, 5.0]}},
    {'dynamics.inertia': {'distribution': 'uniform', 'low': [0.02, 0.02, 0.02], 'high': [0.05, 14.0, 10.0]}},
    {'dynamics.initial.attitude': {'distribution': 'euler213_uniform', 'max_deg': 30},
     'dynamics.wheels.max_torque': {'distribution': 'uniform', 'low': -0.001, 'high': 0.01,
                                    'link': ['pd_controller.wheels.max_torque']}},
    {'dynamics.duration': {'distribution': 'uniform', 'low': 0.5, 'high': 30.0}},
    {'pd_controller.kp': {'distribution': 'normal', 'std': 0.003}},
])
def test_refusals_are_those_of_the_run_by_run_path(tmp_path, monkeypatch, dispersions):
    path = write_campaign(tmp_path, runs=60, dispersions=dispersions)
    stacked = error_of(path)
    monkeypatch.setattr(Schema, 'validate_stacked', lambda *args: False)
    assert stacked == error_of(path)
    assert stacked.startswith('run ')


@pytest.mark.parametrize('name', ['pd_slew_30deg.yaml', 'gsmn_slew_30deg.yaml', 'pointing_table1.yaml'])
def test_the_reference_campaigns_are_validated_at_once(monkeypatch, name):
    calls = []
    monkeypatch.setattr(Campaign, '_revalidate', lambda self, *args: calls.append(args))
    campaign = Campaign.load(CONFIG / 'campaigns' / name, runs=200)
    assert campaign.checked and calls == []


class LengthOnly:
    """A parameter value the check may only take the length of."""

    def __init__(self, n: int) -> None:
        self.n = n

    def __len__(self) -> int:
        return self.n

    def _refuse(self, *args, **kwargs):
        raise AssertionError('read by value')

    __iter__ = __getitem__ = __eq__ = __ne__ = __lt__ = __le__ = __gt__ = __ge__ = __bool__ = _refuse
    __array__ = __float__ = __int__ = __add__ = __sub__ = __mul__ = __hash__ = _refuse


class Unread(LengthOnly):
    """A parameter value the check may not use at all."""

    __len__ = LengthOnly._refuse


def _valid_sections() -> dict[str, dict]:
    """A validated section of every node that a config scenario has."""
    out = {}
    for path in sorted(CONFIG.glob('*.yaml')):
        try:
            sections = validate_scenario(path)
        except Exception:   # noqa: BLE001 - not a scenario (or one for another purpose): skip it
            continue
        for name, section in sections.items():
            out.setdefault(name, section)
    return out


def test_cross_declarations_hold_for_every_schema():
    sections = _valid_sections()
    checked = 0
    for name, node in NODES.items():
        schema = node.schema
        if schema.cross_check is None or name not in sections:
            continue
        for p in schema.params:
            if p.cross == 'value':
                continue
            v = dict(sections[name])
            v[p.name] = LengthOnly(len(v[p.name])) if p.cross == 'length' else Unread(0)
            schema.cross_check(v)   # AssertionError('read by value') if the declaration is wrong
            checked += 1
    assert checked >= 10


@pytest.mark.parametrize('name, rows', [
    ('inertia', [[12.0, 14.0, 10.0], [1.0, 1.0, 3.0], [-1.0, 2.0, 2.0], [12.0, 14.0, 1e-300]]),
    ('inertia', [[12.0, 1.0, 0, 1.0, 14.0, 0, 0, 0, 10.0], [12.0, 2.0, 0, 1.0, 14.0, 0, 0, 0, 10.0]]),
    ('initial.attitude', [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0011], [0.5, 0.5, 0.5, 0.5], [0.0, 0.0, 0.6, 0.6]]),
    ('wheels.max_torque', [[0.01, 0.01, 0.01], [0.01, math.inf, 0.01], [0.01, 0.0, 0.01], [0.01, -1.0, 0.01]]),
    ('wheels.viscous_friction', [[0.0, 0.0, 0.0], [0.0, -0.0, 1.0], [0.0, -1e-9, 1.0]]),
    ('duration', [[10.0], [0.0], [-1.0], [math.inf]]),
    ('noise.seed', [[3], [-4]]),
])
def test_coerce_many_agrees_with_coerce(name, rows):
    p = NODES['dynamics'].schema.by_name[name]

    def accepted(row) -> bool:
        try:
            p.coerce(row if p.kind.endswith('array') else row[0])
        except (TypeError, ValueError):
            return False
        return True
    for i in range(len(rows)):
        for group in ([rows[i]], rows[:i + 1]):
            values = np.array(group)
            values = values if p.kind.endswith('array') else values[:, 0]
            assert p.coerce_many(values) == all(accepted(r) for r in group), (name, group)


def test_a_refused_first_run_is_not_accepted_at_once():
    """validate_stacked revalidates the first run in full: a bad one makes it answer False."""
    schema = NODES['dynamics'].schema
    section = _valid_sections()['dynamics']
    with pytest.raises(ParameterError):
        schema.revalidate(section, {'duration': 0.1 * section['control_period']})
    durations = np.array([0.1 * section['control_period'], 100.0])
    assert not schema.validate_stacked(section, {'duration': durations}, {'duration': float(durations[0])})
