"""Files and functions small enough to read: no source file over 600 lines and no function over 60
lines in the packages, the benchmarks and the docs' scripts (tests are exempt)."""
from __future__ import annotations

import ast

import pytest
from support.paths import ROOT

SOURCES = sorted(p for folder in ('adcs_core', 'adcs_msgs_py', 'adcs_controllers', 'adcs_sim', 'benchmarks', 'docs',
                                  'bags')
                 for p in (ROOT / folder).rglob('*.py'))
MAX_FILE_LINES = 600
MAX_FUNCTION_LINES = 60


@pytest.mark.parametrize('path', SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_file_and_functions_are_small(path):
    text = path.read_text()
    assert text.count('\n') <= MAX_FILE_LINES, f'{path.name}: {text.count(chr(10))} lines > {MAX_FILE_LINES}'
    long = [f'{node.name} (line {node.lineno}): {node.end_lineno - node.lineno + 1} lines'
            for node in ast.walk(ast.parse(text))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]
    assert not long, f'functions over {MAX_FUNCTION_LINES} lines: {long}'
