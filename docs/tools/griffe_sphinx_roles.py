"""A Griffe extension for the API reference (mkdocs.yml): Sphinx cross-reference roles in docstrings
(``:class:`Scenario```, ``:meth:`Scenario.run_graph```, ``:func:``, ``:mod:``, ``:data:``, ``:attr:``,
``:exc:``, ``:obj:``) become plain code spans, which Markdown renders; ``~`` (last component only) is
honoured. The docstrings stay as ``help()`` and the numpydoc tools read them."""
from __future__ import annotations

import griffe

from adcs_msgs_py.help_text import replace_roles


def plain(text: str) -> str:
    """The docstring text with every role replaced by a code span of its target."""
    return replace_roles(text, lambda target: f'`{target}`')


class SphinxRoles(griffe.Extension):
    """Rewrites each docstring as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
