"""A Griffe extension for the API reference (mkdocs.yml): Sphinx cross-reference roles in docstrings
(``:class:`Scenario```, ``:meth:`Scenario.run_graph```, ``:func:``, ``:mod:``, ``:data:``, ``:attr:``,
``:exc:``, ``:obj:``) become plain code spans, which Markdown renders; ``~`` (last component only) is
honoured. The docstrings stay as ``help()`` and the numpydoc tools read them."""
from __future__ import annotations

import re

import griffe

ROLE = re.compile(r':(?:py:)?(?:class|meth|func|mod|data|attr|exc|obj):`(~?)([^`]+)`')


def plain(text: str) -> str:
    """The docstring text with every role replaced by a code span of its target."""
    return ROLE.sub(lambda m: '`' + (m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)) + '`', text)


class SphinxRoles(griffe.Extension):
    """Rewrites each docstring as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
