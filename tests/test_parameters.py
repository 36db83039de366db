"""The parameter reference (docs/parameters.md, adcs_sim/app/scenario/parameters.py) and ``adcs-run --explain``.

* docs/parameters.md is what the schemas generate today (regenerate: ``python -m
  adcs_sim.app.scenario.parameters --write``), and it has a row for every key of every section;
* units are read from the schemas' doc text; every check has a description;
* ``--explain`` prints the validated values (defaults included) with units, exits 0 and starts
  nothing; a bad scenario stops it with the key named.
"""
from __future__ import annotations

import re

import pytest
from support.paths import CONFIG, ROOT
from support.scenarios import make_scenario

from adcs_msgs_py.params import REQUIRED
from adcs_sim.app.scenario import parameters
from adcs_sim.app.graph import runner
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario


def test_reference_is_up_to_date():
    text = (ROOT / 'docs' / 'parameters.md').read_text(encoding='utf-8')
    assert text == parameters.reference_markdown(), (
        'docs/parameters.md is out of date: run `python -m adcs_sim.app.scenario.parameters --write`')


def test_reference_has_every_section_and_key():
    text = (ROOT / 'docs' / 'parameters.md').read_text(encoding='utf-8')
    chunks = re.split(r'^## `([a-z0-9_]+)`$', text, flags=re.M)
    sections = dict(zip(chunks[1::2], chunks[2::2]))
    assert list(sections) == list(NODES)
    for name, info in NODES.items():
        rows = [line for line in sections[name].splitlines() if line.startswith('| `')]
        keys = [row.split('`')[1] for row in rows]
        assert keys == [p.name for p in info.schema.params], name
        for p, row in zip(info.schema.params, rows):
            cells = [c.strip() for c in re.split(r'(?<!\\)\|', row)[1:-1]]
            assert len(cells) == 8, row
            assert cells[5] == ('yes' if p.batch else 'no')
            assert cells[2] == ('`required`' if p.default is REQUIRED else f'`{parameters.format_value(p.default)}`'
                                .replace('|', '\\|'))


@pytest.mark.parametrize('section, key, unit', [
    ('dynamics', 'inertia', 'kg m^2'), ('dynamics', 'wheels.max_torque', 'N m'),
    ('dynamics', 'noise.rate_std', 'rad/s'), ('dynamics', 'noise.attitude_std', 'rad'),
    ('dynamics', 'orbit.raan_deg', 'deg'), ('dynamics', 'initial.momentum', 'N m s'),
    ('dynamics', 'wheels.viscous_friction', 'N m s/rad'), ('dynamics', 'lockstep.timeout', 's (wall clock)'),
    ('fault_injector', 'schedule.time', 's'), ('recorder', 'chunk_size', 'bytes'),
    ('pd_controller', 'kp', '1/s^2'), ('pd_controller', 'kd', '1/s'),
    ('pointing_a_controller', 'K_h', 'rad/(N m s)'), ('dynamics', 'initial.attitude', ''),
    ('dynamics', 'wheels.names', ''),
])
def test_units_are_read_from_the_docs(section, key, unit):
    assert parameters.unit_of(NODES[section].schema.by_name[key]) == unit


def test_every_check_is_described():
    for info in NODES.values():
        for p in info.schema.params:
            text = parameters.check_of(p)
            assert '<lambda>' not in text
            if p.check is not None:
                assert text.split('; ')[-1], p.name


def test_scenario_usage_names_the_files_that_set_a_key():
    usage = parameters.scenario_usage(CONFIG)
    assert 'microsat_pd_slew' in usage['pd_controller']['kp']
    assert 'uosat12_gsmn' in usage['snlc_gsmn_controller']['three_wheel.enabled']
    assert 'wheels.viscous_friction' not in usage['dynamics']   # no scenario sets it


def test_explain_prints_resolved_values_with_units(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scenario = CONFIG / 'microsat_pd_slew.yaml'
    assert runner.main(['--explain', str(scenario), '--duration', '30']) == 0
    out = capsys.readouterr().out
    assert not any(tmp_path.iterdir())             # nothing started, nothing written
    validated = validate_scenario(scenario, 30.0)
    blocks = re.split(r'^\[(\w+)\].*$', out, flags=re.M)
    assert blocks[1::2] == list(validated)
    for name, body in zip(blocks[1::2], blocks[2::2]):
        lines = {line.split()[0]: line for line in body.strip().splitlines()}
        assert list(lines) == list(validated[name]), name
    dyn = dict(zip(blocks[1::2], blocks[2::2]))['dynamics']
    line = {ln.split()[0]: ln.split() for ln in dyn.strip().splitlines()}
    assert line['inertia'][-3:] == ['kg', 'm^2', '(file)']
    assert line['duration'][1:] == ['30.0', 's', '(--duration)']
    assert line['noise.seed'][1:] == ['0', '-', '(default)']


def test_explain_refuses_a_bad_scenario_naming_the_key(tmp_path, capsys):
    bad = make_scenario(tmp_path, {'pd_controller': {'kp': -1.0}})
    assert runner.main(['--explain', str(bad)]) == 2
    assert "'pd_controller.ros__parameters.kp'" in capsys.readouterr().err
