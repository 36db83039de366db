"""What setup.py and requirements.txt declare, read without running or installing anything."""
from __future__ import annotations

import ast
import re

from support.paths import ROOT

# --- setup.py, read without running it --------------------------------------------------------

def _setup_py_dict(name: str) -> dict:
    """The literal dict assigned to ``name`` at module level in setup.py."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError(f'setup.py defines no module-level {name} dict')


NODES = _setup_py_dict('NODES')
TOOLS = _setup_py_dict('TOOLS')


# --- requirements.txt ---------------------------------------------------------------------------

PIN = re.compile(r'^(?P<name>[A-Za-z0-9][A-Za-z0-9._-]*)(\[[a-z0-9_,-]+\])?==(?P<version>[0-9][0-9A-Za-z.+-]*)$')


def normal_name(name: str) -> str:
    """A distribution name normalised as pip compares them (PEP 503)."""
    return re.sub(r'[-_.]+', '-', name).lower()


def requirements() -> dict[str, str]:
    """requirements.txt -> {normalised distribution name: the full line}; every line pinned."""
    out = {}
    for line in (ROOT / 'requirements.txt').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            match = PIN.match(line)
            assert match, f'requirements.txt: {line!r} is not pinned (name==version)'
            out[normal_name(match['name'])] = line
    return out
