"""What a command prints for ``--help``: plain text in sentences, from a docstring.

The docstrings are reStructuredText (``literal``, :func:`name`, :mod:`~package.module`); a
terminal shows that markup as it is. :func:`description` turns a module docstring's first
paragraph into a program description (the synopsis before its first colon, which argparse's
usage line already shows, left out); :func:`sentence` turns any short text (a parameter's doc)
into a plain sentence; :func:`command_parser` is the argparse parser of a tool whose description
and every option's help are so written. Every tool and every node executable builds its help with
them.
"""
from __future__ import annotations

import argparse
import re

# :role:`target`, :domain:role:`target`, with an optional ~ (show the last dotted part only).
_ROLE = re.compile(r':(?:[A-Za-z]+:)+`(~?)([^`<]*?)(?:\s*<[^`>]*>)?`')
_LITERAL = re.compile(r'``(.+?)``', re.S)
_INTERPRETED = re.compile(r'(?<![\w`])`([^`]+)`(?![\w`])')
# A leading synopsis: ``adcs-run [scenario.yaml] [--out DIR]``: ...
_SYNOPSIS = re.compile(r'^\s*``[^`]+``\s*:\s*', re.S)
_END = ('.', '?', '!')
# A plain lower-case English word at the start (not kp1, wheels.names, q4 or γ).
_WORD = re.compile(r"[a-z][a-z'-]*(?=[\s,;:()!?]|\.(?!\w)|$)")


def replace_roles(text: str, shown=lambda target: target) -> str:
    """``text`` with every cross-reference role replaced by ``shown(target)``: the target as written,
    its last dotted part with ``~``, the title of ``title <target>`` (also the API reference's
    Markdown, docs/tools/griffe_sphinx_roles.py)."""
    return _ROLE.sub(lambda m: shown(m[2].rsplit('.', 1)[-1] if m[1] else m[2]), text)


def plain(text: str) -> str:
    """``text`` without reST markup, its whitespace (line breaks included) collapsed to single spaces."""
    text = replace_roles(text)
    text = _LITERAL.sub(r'\1', text)
    text = _INTERPRETED.sub(r'\1', text)
    return ' '.join(text.split())


def sentence(text: str) -> str:
    """``text`` as one plain sentence: no markup, a capital first letter (when it begins with a
    plain lower-case word: a symbol, a name such as ``kp1`` or ``wheels.names`` stays as written),
    a full stop at the end (``''`` stays ``''``)."""
    text = plain(text).rstrip(' :;,')
    if not text:
        return ''
    if _WORD.match(text):
        text = text[0].upper() + text[1:]
    return text if text.endswith(_END) else text + '.'


def description(doc: str | None) -> str:
    """A program's description from its module docstring: the first paragraph, without the
    leading synopsis, as plain sentences."""
    first = (doc or '').strip().split('\n\n', 1)[0]
    return sentence(_SYNOPSIS.sub('', first, count=1))


class PlainHelpFormatter(argparse.HelpFormatter):
    """argparse's formatter, each option's help (its ``%(default)s`` expanded) as a plain sentence."""

    def _expand_help(self, action) -> str:
        return sentence(super()._expand_help(action))


def command_parser(prog: str, doc: str | None) -> argparse.ArgumentParser:
    """The parser of the command ``prog``: its description from ``doc`` (a module docstring, or the
    text itself) by :func:`description`, every option's help a plain sentence."""
    return argparse.ArgumentParser(prog=prog, description=description(doc), formatter_class=PlainHelpFormatter)
