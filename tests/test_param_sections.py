"""Typed parameter sections (``adcs_msgs_py.sections``): each schema's section type has exactly the
schema's parameters (names, types, defaults), a section is frozen, carries a batch's stacked
arrays, and the laws, estimators, actuations and builders read attributes, never a dotted key
with a default of their own (the defaults live in the schemas only)."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import yaml

from adcs_controllers.families import FAMILIES, MINNORM, PD, SNLC
from adcs_controllers.laws.inverse_optimal import LGV, MinNormLaw
from adcs_controllers.laws.underactuated import TWO_WHEEL_PARAMS, SnlcLaw
from adcs_msgs_py.params import REQUIRED, Param, ParameterError, Schema, flatten
from adcs_msgs_py.sections import (
    Field,
    FrozenSectionError,
    Section,
    as_section,
    field_type,
    fields,
    flat,
    section,
    section_type,
    validated,
)
from adcs_sim.app.scenario.registry import NODES

ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = {name: info.schema for name, info in NODES.items()}

# Where parameters are read: the laws, the actuations, the families, the estimators, the truth builders.
READERS = sorted([*(ROOT / 'adcs_controllers').rglob('*.py'),
                  ROOT / 'adcs_sim/truth/schema.py', ROOT / 'adcs_sim/truth/sensor_schema.py'])


def _fields(cls: type, prefix: str = '') -> dict[str, Field]:
    """Every leaf field of a generated section type, by its dotted name."""
    out = {}
    for f in fields(cls):
        if isinstance(f.type, type) and issubclass(f.type, Section):
            out.update(_fields(f.type, f'{prefix}{f.name}.'))
        else:
            out[f'{prefix}{f.name}'] = f
    return out


@pytest.mark.parametrize('node', sorted(SCHEMAS))
def test_the_section_type_has_exactly_the_schema_parameters(node):
    schema = SCHEMAS[node]
    fields = _fields(section_type(schema))
    assert sorted(fields) == sorted(p.name for p in schema.params)
    for p in schema.params:
        f = fields[p.name]
        assert f.type == field_type(p), p.name
        if p.default is REQUIRED:
            assert f.default is REQUIRED, p.name
        else:
            expected = tuple(p.default) if isinstance(p.default, list) else p.default
            assert f.default == expected and type(f.default) is type(expected), p.name
    assert section_type(schema) is section_type(schema)   # generated once


def test_the_types_follow_the_kinds():
    schema = Schema('kinds', [Param('a', 'double', default=1.0), Param('b.c', 'int', default=2),
                              Param('b.d', 'string_array', default=['x']), Param('e', 'double', batch=True)])
    fields = _fields(section_type(schema))
    assert fields['a'].type is float and fields['b.c'].type is int
    assert fields['b.d'].type == tuple[str, ...]
    assert fields['e'].type == float | np.ndarray


def test_a_name_that_is_also_a_group_is_refused():
    with pytest.raises(ValueError, match="'a.b' is inside the parameter 'a'"):
        section_type(Schema('clash', [Param('a', 'double', default=1.0), Param('a.b', 'double', default=1.0)]))


def test_a_section_holds_the_validated_values_and_is_frozen():
    values = PD.schema.validate({'inertia': [1.0, 2.0, 3.0], 'kp': 0.5, 'kd': 1.5,
                                 'wheels.names': ['a', 'b', 'c'], 'wheels.axes': np.eye(3).ravel().tolist(),
                                 'wheels.max_torque': [0.1, 0.1, 0.1]})
    sec = section(PD.schema, values)
    assert flat(sec) == {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
    assert sec.kp == 0.5 and sec.wheels.names == ('a', 'b', 'c') and sec.target.attitude == (0.0, 0.0, 0.0, 1.0)
    with pytest.raises(FrozenSectionError, match='frozen'):
        sec.kp = 1.0
    with pytest.raises(FrozenSectionError, match='frozen'):
        sec.wheels.names = ('x',)
    with pytest.raises(FrozenSectionError, match='frozen'):
        del sec.kd
    with pytest.raises(AttributeError):
        object.__setattr__(sec, 'not_a_parameter', 1)   # no room for another attribute (slots)
    assert sec == section(PD.schema, dict(values)) and sec != section(PD.schema, dict(values, kp=0.25))
    assert section(PD.schema, sec) is sec


def test_validated_refuses_what_validate_refuses():
    with pytest.raises(ParameterError, match=r"pd_controller\.ros__parameters\.kp': must be >= 0"):
        validated(PD.schema, {'inertia': [1.0, 2.0, 3.0], 'kp': -1.0, 'kd': 1.0})


def test_a_stacked_section_carries_the_runs_arrays_to_the_law():
    base = {'inertia': [1.0, 2.0, 3.0], 'kd': 1.5, 'wheels.names': ['a', 'b', 'c'],
            'wheels.axes': np.eye(3).ravel().tolist(), 'wheels.max_torque': [0.1, 0.1, 0.1]}
    runs = [PD.schema.validate(dict(base, kp=kp)) for kp in (0.5, 0.25, 2.0)]
    sec = section(PD.schema, PD.schema.stack(runs))
    assert isinstance(sec.kp, np.ndarray) and sec.kp.shape == (3,) and sec.kd == 1.5
    law, _ = PD.build(sec)
    q = np.tile([0.1, -0.2, 0.3, np.sqrt(0.86)], (3, 1))
    w = np.tile([0.01, 0.02, -0.03], (3, 1))
    together, _ = law.control(0.0, q, w)
    for i, run in enumerate(runs):
        alone, _ = PD.build(run)[0].control(0.0, q[i], w[i])
        np.testing.assert_array_equal(together[i], alone)


def test_a_law_built_from_a_plain_dict_gets_the_schema_default():
    p = {'inertia': [1.0, 2.0, 3.0], 'kp': 0.1, 'kd': 0.2, 'gamma': 0.01}
    assert MinNormLaw(p).lgv == LGV.default
    full = MINNORM.schema.validate(dict(p, **{'wheels.names': ['a'], 'wheels.axes': [1.0, 0.0, 0.0],
                                              'wheels.max_torque': [0.1]}))
    assert MINNORM.build(full)[0].lgv == LGV.default
    snlc = SnlcLaw({'inertia': [1.0, 2.0, 3.0], 'k': 0.02, 'g': 0.08, 'K': 10.0})
    by_name = {q.name: q.default for q in TWO_WHEEL_PARAMS}
    assert (snlc.a1, snlc.eps_den, snlc.unactuated_axis) == (by_name['a1'], by_name['eps_den'],
                                                             by_name['unactuated_axis'])
    assert SNLC.schema.by_name['a1'] is TWO_WHEEL_PARAMS[0]   # the schema lists the very Param
    assert as_section({'x.y': 1}).x.y == 1


def _scenario_sections() -> dict[str, dict]:
    """The first section of each node in the shipped scenarios (``config/``)."""
    out: dict[str, dict] = {}
    for path in sorted((ROOT / 'config').glob('*.yaml')):
        for node, body in yaml.safe_load(path.read_text()).items():
            if node in NODES and node not in out:
                out[node] = flatten(body['ros__parameters'])
    return out


SCENARIOS = _scenario_sections()


@pytest.mark.parametrize('name', sorted(set(FAMILIES) & set(SCENARIOS)))
def test_every_family_builds_from_its_typed_section(name):
    """The family reads a shipped scenario's section as the generated type, and the law it builds
    from that type computes what the law built from the plain dict computes."""
    family = FAMILIES[name]
    values = family.schema.validate(SCENARIOS[name])
    sec = family.section(values)
    assert type(sec) is section_type(family.schema) and flat(sec) == flat(as_section(values))
    typed, _ = family.build(sec)
    plain = family.law(values)
    q, w = np.array([0.1, -0.2, 0.3, np.sqrt(0.86)]), np.array([0.001, 0.002, -0.003])
    extra = (np.zeros(3),) if getattr(typed, 'needs_wheel_momentum', False) else ()
    np.testing.assert_array_equal(typed.control(1.0, q, w, *extra)[0], plain.control(1.0, q, w, *extra)[0])


# --- no defaults outside the schemas --------------------------------------------------------------

def _restated_defaults(source: str) -> list[int]:
    """Lines of ``source`` that read a parameter with a default of their own:
    ``x.get('key', default)`` (or an f-string key), the way parameter dicts were read."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == 'get'
                and len(node.args) + len(node.keywords) >= 2 and node.args
                and isinstance(node.args[0], (ast.Constant, ast.JoinedStr))):
            lines.append(node.lineno)
    return lines


def test_the_scan_finds_a_restated_default():
    assert _restated_defaults("a = p.get('orbit.raan_deg', 0.0)\nb = p.get(f'x.{n}', [])\n") == [1, 2]
    assert _restated_defaults("a = p.get('key')\nb = counts.get(key, 0)\nc = p.orbit.raan_deg\n") == []


def test_no_reader_restates_a_default():
    found = {str(path.relative_to(ROOT)): lines for path in READERS
             if (lines := _restated_defaults(path.read_text()))}
    assert not found, f'parameters read with a default outside their schema: {found}'
