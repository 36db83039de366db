"""MkDocs hook: the site's home page is the README, so the two never differ.

Links from the README into ``docs/`` become links between pages (``docs/x.md`` -> ``x.md``); a link to a
repository file outside ``docs/`` (``CHANGELOG.md``, ``LICENSE``), which the site does not carry, becomes
its path in code with "in the repository". The README's sentence about building the site is kept: it is
true of the page too.
"""
from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File

LINK = re.compile(r'\[([^\]]+)\]\((?!https?://|#|mailto:)([^)#\s]+)(#[^)\s]*)?\)')


def home_markdown(readme: str) -> str:
    """The README's text with its relative links made those of the site's home page."""
    def link(m: re.Match) -> str:
        text, target, anchor = m.group(1), m.group(2), m.group(3) or ''
        if target.startswith('docs/'):
            return f'[{text}]({target[len("docs/"):]}{anchor})'
        if text.strip('`') == target:
            return f'`{target}` (in the repository)'
        return f'{text} (`{target}` in the repository)'
    return LINK.sub(link, readme)


def on_files(files, config):
    readme = Path(config['docs_dir']).parent / 'README.md'
    files.append(File.generated(config, 'index.md', content=home_markdown(readme.read_text(encoding='utf-8'))))
    return files
