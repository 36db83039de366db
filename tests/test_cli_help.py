"""Every console script's ``--help`` (the tools and the node executables setup.py installs) exits
0 and reads as plain text: no reST role, no literal markup, a description in full sentences (and,
for the nodes, every parameter's description too). Built by adcs_msgs_py/help_text.py."""
from __future__ import annotations

import importlib
import re

import pytest
from support.packaging import NODES, TOOLS

from adcs_msgs_py.help_text import description, plain, sentence

ROLE = re.compile(r':[a-z]+:`')


def _help(name: str, target: str, capsys) -> str:
    module, func = target.split(':')
    main = getattr(importlib.import_module(module), func)
    with pytest.raises(SystemExit) as done:
        main([name, '--help'] if name in NODES else ['--help'])
    assert done.value.code in (0, None), f'{name} --help exited {done.value.code}'
    return capsys.readouterr().out


def _plain(text: str, name: str) -> None:
    assert not ROLE.search(text), f'{name}: a reST role in its help'
    assert '``' not in text, f'{name}: double backticks in its help'
    assert not re.search(r'`[^`\s][^`]*`', text), f'{name}: interpreted text in its help'


@pytest.mark.parametrize('name', sorted(TOOLS))
def test_a_tools_help_is_plain_sentences(name, capsys):
    text = _help(name, TOOLS[name], capsys)
    _plain(text, name)
    # The description: the paragraph between the usage and the arguments.
    paragraphs = text.split('\n\n')
    described = ' '.join(paragraphs[1].split())
    assert not described.startswith(('usage', 'positional', 'options')), f'{name}: no description'
    assert described.endswith('.') and described[0].isupper(), f'{name}: {described!r}'
    # Every option's help a sentence too (argparse indents it under or beside the option).
    options = text.split('options:\n', 1)[1]
    helps = re.split(r'\n  (?=-)', options)
    for entry in helps:
        assert ' '.join(entry.split()).endswith('.'), f'{name}: {entry!r}'


@pytest.mark.parametrize('name', sorted(NODES))
def test_a_nodes_help_is_plain_sentences(name, capsys):
    text = _help(name, NODES[name], capsys)
    _plain(text, name)
    lines = text.splitlines()
    assert lines[0].startswith(f'usage: {name} ')
    assert lines[2].endswith('.') and lines[2][0].isupper(), f'{name}: {lines[2]!r}'
    params = [line for line in lines if line.startswith('  ')]
    assert params and all(line.endswith('.') for line in params), name


@pytest.mark.parametrize('doc, expected', [
    ('``adcs-x [--a]``: do it, with :func:`~pkg.mod.fn` and\n:mod:`pkg.mod`.\n\nMore.', 'Do it, with fn and pkg.mod.'),
    ('``adcs-montecarlo <campaign.yaml> [--runs N]``: a Monte Carlo\ncampaign on the batch engine',
     'A Monte Carlo campaign on the batch engine.'),
    ('the ``mode`` of `x`', 'The mode of x.'),
    ('γ of eq. (22)', 'γ of eq. (22).'),
    ('kp1 gain', 'kp1 gain.'),
    ('', ''),
])
def test_a_docstring_becomes_a_description(doc, expected):
    assert description(doc) == expected


def test_plain_keeps_the_text_and_drops_only_the_markup():
    assert plain(':class:`RunData` has ``t`` (s), :meth:`~a.B.c`, :py:func:`f <g.f>`') == 'RunData has t (s), c, f'
    assert sentence('done!') == 'Done!'
