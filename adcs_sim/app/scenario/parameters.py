"""The parameter reference, generated from the schemas, and ``adcs-run --explain``.

``docs/parameters.md`` is :func:`reference_markdown`: every section of a scenario file
(:data:`adcs_sim.app.scenario.registry.NODES`), every key with its type, default, unit, check, whether the
batch engine accepts it dispersed across the runs of one batch (``batch=True``), and the scenarios
in ``config/`` that set it. Regenerate it with ``python -m adcs_sim.app.scenario.parameters --write``;
a test fails when it is out of date.

Units are read from the parameter's doc text (:func:`unit_of`): the schemas state them there, in
SI, e.g. ``'motor torque limit per wheel (N m, > 0; .inf for none)'``. A parameter whose doc
states no unit (a name, a flag, a mode, a quaternion, a gain whose unit follows from the cited
equation) has none in the reference.

:func:`explain` is ``adcs-run --explain``: a scenario's validated values (defaults included)
section by section, with units and where each value comes from.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any

from adcs_msgs_py.params import BUILTIN_PARAMETERS, REQUIRED, Param, Schema
from adcs_msgs_py.params_file import load_params_file
from adcs_msgs_py.sensor_interfaces import SENSORS
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

ROOT = Path(__file__).resolve().parents[3]
CONFIG = ROOT / 'config'
REFERENCE = ROOT / 'docs' / 'parameters.md'

# Units as the schemas write them (SI); matched as a whole piece of the doc text (see unit_of).
UNITS = ('N m s/rad', 'rad/(N m s)', 'N m s', 'N s', 'N m', 'N', 'kg m^2', 'rad/s^2', 'rad/s^0.5', 'rad/s^1.5',
         'rad/s', 'rad/sqrt(s)', 'rad', 'deg', '1/s^2', '1/s', 's', 'm', 'T', 'bytes')
# Phrases that give a unit in words.
UNIT_WORDS = {'wall seconds': 's (wall clock)', 'sim seconds': 's', 'fraction': '1 (fraction)'}

# What each check function refuses (by qualified name); a lambda by the parameter's name.
CHECKS = {
    'positive': '> 0',
    'non_negative': '>= 0',
    'all_positive': 'each > 0',
    'all_non_negative': 'each >= 0',
    'domain_id': '0..232',
    'check_unit_quaternion': 'unit norm (within 1e-3)',
    '_check_inertia_values': 'symmetric, positive definite, triangle inequality of the principal moments',
    '_fraction': 'in [0, 1]',
    '_known_sensors': 'distinct names among ' + ', '.join(f'`{name}`' for name in SENSORS),
    '_distinct_positive': 'three distinct values > 0',
    '_nonzero_vector': 'not the zero vector',
    '_scale_factor': 'each in (-1, 1]',
    '_rate_noise': 'in [0, 1]',
    '_angle_std': 'in [0, 1] rad',
    '_rate_bias': 'in [0, 10] rad/s',
    '_rate_biases': 'each within +-10 rad/s',
    '_field_std': 'in [0, 1e-3] T',
    '_field_biases': 'each within +-1e-3 T',
    '_angle_below_180': 'in [0, 180)',
    '_half_angle': 'in (0, 180]',
    '_fraction_below_1': 'in [0, 1)',
    '_check_publishers': 'entries `topic=node[,node...]` (empty after `=`: nobody may publish)',
    '_check_epoch': 'an ISO-8601 UTC date and time',
    '_control_period': 'in [1e-9, 2147483647] s (the time grid is in integer ns; stamps carry int32 seconds)',
}
LAMBDA_CHECKS = {
    'proposition': '1 or 2',
    'K_omega': 'in (0, 1)',
    'solution': '0, 1 or 2',
    'environment.tle.line1': 'empty, or a TLE line 1 (69 characters, checksum)',
    'environment.tle.line2': 'empty, or a TLE line 2 (69 characters, checksum)',
}


# --- one parameter ---------------------------------------------------------------------------

def _pieces(doc: str) -> list[str]:
    """The doc text cut at brackets and separators: parenthesised pieces first, then the rest."""
    inner = re.findall(r'\(([^()]*(?:\([^()]*\)[^()]*)*)\)', doc)
    outer = re.sub(r'\([^()]*(?:\([^()]*\)[^()]*)*\)', ',', doc)
    split = lambda text: [p.strip() for p in re.split(r'[,;:]', text)]  # noqa: E731
    return [p for text in inner for p in split(text)] + split(outer)


def unit_of(param: Param) -> str:
    """The unit the parameter's doc states, or '' if it states none.

    A unit is a whole piece of the doc (between brackets, commas, semicolons or colons), e.g.
    ``N m`` in ``'(N m, > 0; .inf for none)'`` or ``rad/s`` in ``'gyro noise, rad/s (1 sigma)'``;
    ``wall seconds ...`` is seconds of wall-clock time.
    """
    doc = param.doc.strip()
    for piece in _pieces(doc):
        if piece in UNITS:
            return piece
    for words, unit in UNIT_WORDS.items():
        if re.search(rf'(^|\()\s*{words}\b', doc):
            return unit
    return ''


def type_of(param: Param) -> str:
    """The parameter's kind, with the number of values an array must have."""
    if param.length is None:
        return param.kind
    lengths = param.length if isinstance(param.length, tuple) else (param.length,)
    return f'{param.kind} [{" or ".join(map(str, lengths))}]'


def check_of(param: Param) -> str:
    """What validation refuses, in words: choices, finiteness, the check function."""
    parts = []
    if param.choices is not None:
        parts.append('one of ' + ', '.join(f'`{c}`' for c in param.choices))
    if param.kind.startswith('double'):
        parts.append('finite' if param.finite else 'not NaN (.inf allowed)')
    if param.check is not None:
        name = param.check.__name__
        text = getattr(param.check, 'description', None) or (
            LAMBDA_CHECKS.get(param.name) if name == '<lambda>' else CHECKS.get(name))
        if text is None:
            raise KeyError(f'{param.name}: no description of its check {param.check.__qualname__} '
                           '(add it to CHECKS or LAMBDA_CHECKS in adcs_sim/app/scenario/parameters.py)')
        parts.append(text)
    return '; '.join(parts)


def format_value(value: Any) -> str:
    """A value as it is written in a scenario file (YAML flow style: ``.inf``, ``[1.0, 2.0]``)."""
    if value is REQUIRED:
        return 'required'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        if math.isinf(value):
            return '.inf' if value > 0 else '-.inf'
        return repr(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(format_value(v) for v in value) + ']'
    if hasattr(value, 'tolist'):
        return format_value(value.tolist())
    return str(value)


# --- the scenarios -----------------------------------------------------------------------------

def scenario_usage(config: Path = CONFIG) -> dict[str, dict[str, list[str]]]:
    """``{section: {key: [scenario names that set it]}}`` over the scenario files of ``config``."""
    usage: dict[str, dict[str, list[str]]] = {}
    for path in sorted(config.glob('*.yaml')):
        for section, given in load_params_file(str(path)).items():
            for key in given:
                if key not in BUILTIN_PARAMETERS:
                    usage.setdefault(section, {}).setdefault(key, []).append(path.stem)
    return usage


def _sections_in(config: Path = CONFIG) -> dict[str, list[str]]:
    """``{section: [scenario names that have it]}``."""
    out: dict[str, list[str]] = {}
    for path in sorted(config.glob('*.yaml')):
        for section in load_params_file(str(path)):
            out.setdefault(section, []).append(path.stem)
    return out


def _users(names: list[str], having: list[str]) -> str:
    if not names:
        return ''
    if len(having) > 3 and len(names) > len(having) / 2:   # most of them: name the others
        others = [n for n in having if n not in names]
        return f'all {len(having)} with this section' + (' but ' + ', '.join(f'`{n}`' for n in others)
                                                          if others else '')
    return ', '.join(f'`{n}`' for n in names)


# --- the reference -------------------------------------------------------------------------

def _cell(text: str) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def _section_markdown(name: str, schema: Schema, usage: dict[str, list[str]], having: list[str]) -> list[str]:
    info = NODES[name]
    lines = [f'## `{name}`', '', f'{schema.doc[:1].upper() + schema.doc[1:]}.' if schema.doc else '', '',
             f'Role: {info.role}; node module `{info.module}`; '
             + (f'in {len(having)} scenario(s) of `config/`.' if having else 'in no scenario of `config/`.')]
    if schema.cross_check is not None:
        check = schema.cross_check
        what = ' '.join((check.__doc__ or '').split()) or 'the checks that span several keys.'
        lines += ['', f'Whole-section check (`{check.__module__}.{check.__name__}`, after the keys\' own): {what}']
    lines += ['', '| key | type | default | unit | check | batch | meaning | set in |',
              '| --- | --- | --- | --- | --- | --- | --- | --- |']
    for p in schema.params:
        lines.append(f'| `{p.name}` | {type_of(p)} | `{_cell(format_value(p.default))}` | {_cell(unit_of(p))} | '
                     f'{_cell(check_of(p))} | {"yes" if p.batch else "no"} | {_cell(p.doc)} | '
                     f'{_users(usage.get(p.name, []), having)} |')
    return lines + ['']


def reference_markdown(config: Path = CONFIG) -> str:
    """The text of ``docs/parameters.md``: every section and key of :data:`NODES`' schemas."""
    usage = scenario_usage(config)
    having = _sections_in(config)
    n_keys = sum(len(info.schema.params) for info in NODES.values())
    lines = ['# Parameter reference', '',
             '<!-- Generated from the schemas by `python -m adcs_sim.app.scenario.parameters --write`; do not edit. '
             'tests/test_parameters.py fails when it is out of date. -->', '',
             f'A scenario file is a ROS 2 params file with one section per node (`<section>: ros__parameters: '
             f'{{...}}`); nested keys are the dotted names below. {len(NODES)} sections, {n_keys} keys. '
             '`adcs-run --explain <scenario>` prints the values a scenario resolves to, defaults included.', '',
             'Columns: **type** the ROS parameter kind (arrays: the number of values they must have); '
             '**default** `required` when the key must be given; **unit** as the key\'s doc states it (SI; '
             'blank where it states none: names, flags, modes, quaternions, dimensionless weights, or a gain whose '
             'unit follows from the cited equation); **check** what validation refuses besides a wrong type '
             '(doubles are finite unless `.inf` is allowed; NaN never); **batch** `yes` when the runs of one batch '
             '(a Monte Carlo campaign) may differ in it; **set in** the scenarios of `config/` that set it '
             '(blank: every scenario uses the default).', '',
             '## Sections', '']
    lines += [f'- [`{name}`](#{name}): {info.schema.doc}' for name, info in NODES.items()]
    lines.append('')
    for name, info in NODES.items():
        lines += _section_markdown(name, info.schema, usage.get(name, {}), having.get(name, []))
    return '\n'.join(lines).rstrip('\n') + '\n'


# --- adcs-run --explain ------------------------------------------------------------------------

def explain(scenario: Path, duration: float | None = None) -> str:
    """A scenario's resolved parameters, section by section: key, value, unit (``-``: none stated)
    and where the value comes from (``file``, ``default`` or ``--duration``). Validates the whole
    file first (raises ParameterError naming the key, as ``adcs-run`` does)."""
    return explain_sections(validate_scenario(scenario, duration), load_params_file(str(scenario)),
                            str(scenario), duration)


def explain_sections(validated: dict, given: dict, label: str, duration: float | None = None) -> str:
    """:func:`explain` of sections already validated (``given``: what the file set, per section)."""
    lines = [f'scenario {label}: {len(validated)} section(s), all valid']
    for name, values in validated.items():
        schema = NODES[name].schema
        lines += ['', f'[{name}]  {schema.doc}']
        rows = []
        for key, value in values.items():
            source = 'file' if key in given[name] else 'default'
            if name == 'dynamics' and key == 'duration' and duration is not None:
                source = '--duration'
            rows.append((key, format_value(value), unit_of(schema.by_name[key]) or '-', source))
        widths = [max(len(r[i]) for r in rows) for i in range(3)]
        lines += [f'  {k:<{widths[0]}}  {v:<{widths[1]}}  {u:<{widths[2]}}  ({src})' for k, v, u, src in rows]
    return '\n'.join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='python -m adcs_sim.app.scenario.parameters',
                                     description='print (or --write) docs/parameters.md from the schemas')
    parser.add_argument('--write', action='store_true', help=f'write {REFERENCE.relative_to(ROOT)}')
    args = parser.parse_args(argv)
    text = reference_markdown()
    if args.write:
        REFERENCE.write_text(text, encoding='utf-8')
        print(f'wrote {REFERENCE}')
    else:
        sys.stdout.write(text)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
