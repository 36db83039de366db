"""The user docs: the site builds without a warning, every link resolves, every repository path a doc
names exists, and the docs speak to users (no development diary, no path outside the repository).

The site is ``mkdocs.yml`` over ``docs/`` (``make docs``); MkDocs checks the links between pages and
their anchors (``validation`` in ``mkdocs.yml``, ``--strict``). The markdown read on GitHub but not
built into the site (README.md, CHANGELOG.md, bags/README.md) is checked here, link by link, and so
is every backticked repository path in all of them.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from support.paths import ROOT

DOCS = ROOT / 'docs'
PAGES = sorted(DOCS.rglob('*.md'))
# Pages the site generates (docs/tools/readme_home.py): the home page is the README.
GENERATED = {DOCS / 'index.md'}
MARKDOWN = [ROOT / 'README.md', ROOT / 'CHANGELOG.md', ROOT / 'bags' / 'README.md', *PAGES]
# What a user reads as the description of the tool as it is; the CHANGELOG is its history.
USER_DOCS = [p for p in MARKDOWN if p.name != 'CHANGELOG.md']

LINK = re.compile(r'!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+"[^"]*")?\)')
FENCE = re.compile(r'^(```|~~~).*?^\1', re.S | re.M)
CODE = re.compile(r'`([^`\n]+)`')
# A word in backticks is taken for a repository path when it starts with one of these.
REPO_DIRS = ('adcs_sim/', 'adcs_core/', 'adcs_controllers/', 'adcs_msgs_py/', 'config/', 'docs/',
             'tests/', 'benchmarks/', 'bags/', 'resource/')
REPO_FILES = {'setup.py', 'setup.cfg', 'package.xml', 'Makefile', 'mkdocs.yml', 'requirements.txt',
              'requirements-dev.txt', 'LICENSE', 'CHANGELOG.md', 'README.md', 'pyproject.toml',
              'MANIFEST.in'}
PLACEHOLDER = set('<>{}*…[]$')


def _prose(path: Path) -> str:
    """The file's text without its fenced code blocks (commands and output are not links)."""
    return FENCE.sub('', path.read_text(encoding='utf-8'))


def relative_links(path: Path) -> list[str]:
    """The targets of the markdown links and images of a file that point into the repository."""
    return [t for t in LINK.findall(_prose(path))
            if not re.match(r'[a-z][a-z0-9+.-]*:', t) and not t.startswith('#')]


def named_paths(text: str) -> list[str]:
    """Backticked words that name a repository path (``tests/x.py::test_y`` names ``tests/x.py``);
    placeholders (``config/<file>.yaml``, globs) are not paths."""
    found = []
    for code in CODE.findall(text):
        for word in code.split():
            word = word.split('::')[0].rstrip('.,;:)')
            if (word.startswith(REPO_DIRS) or word in REPO_FILES) and not PLACEHOLDER & set(word):
                found.append(word)
    return found


def test_named_paths_finds_paths_and_leaves_placeholders():
    text = ('`adcs_sim/app/api.py`, `tests/test_api.py::test_x`, `config/<file>.yaml`, '
            '`docs/seed00*/paper.yaml`, `make run`, `.venv/bin/adcs-run config/a.yaml --out DIR`')
    assert named_paths(text) == ['adcs_sim/app/api.py', 'tests/test_api.py', 'config/a.yaml']


def test_relative_links_ignore_urls_anchors_and_code(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('[a](papers.md#seed-000) ![b](figures/x.png) [c](https://example.org) [d](#top)\n'
                    '```\n[e](not_a_link.md)\n```\n[f [g]](api.md "title")\n', encoding='utf-8')
    assert relative_links(page) == ['papers.md#seed-000', 'figures/x.png', 'api.md']


@pytest.mark.parametrize('path', MARKDOWN, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves_in_the_repository(path):
    broken = []
    for target in relative_links(path):
        file = target.split('#')[0]
        if file and not (path.parent / file).resolve().exists() and (path.parent / file).resolve() not in GENERATED:
            broken.append(target)
    assert not broken, f'{path.relative_to(ROOT)}: links to nothing: {broken}'


@pytest.mark.parametrize('path', USER_DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_repository_path_a_doc_names_exists(path):
    missing = sorted({p for p in named_paths(path.read_text(encoding='utf-8')) if not (ROOT / p).exists()})
    assert not missing, f'{path.relative_to(ROOT)} names paths that do not exist: {missing}'


# Development history belongs in the CHANGELOG; a doc cites papers by authors and title, and names
# no folder outside the repository.
DIARY = [
    (re.compile(r'\bissues? ?#?\d+', re.I), 'an issue number'),
    (re.compile(r'\b(?:session|round)s? \d+', re.I), 'a numbered session or round of work'),
    (re.compile(r'tried and not kept', re.I), 'a "tried and not kept" log'),
    (re.compile(r'shared/seeds|/work/|/home/'), 'a path outside the repository'),
]


@pytest.mark.parametrize('path', USER_DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_user_docs_keep_no_development_diary(path):
    text = path.read_text(encoding='utf-8')
    found = [f'{what}: {m.group(0)!r}' for pattern, what in DIARY for m in pattern.finditer(text)]
    assert not found, f'{path.relative_to(ROOT)}: {found}'


def test_the_readme_is_short_and_keeps_the_two_set_up_commands():
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    assert len(text.splitlines()) <= 250
    assert 'make run' in text and 'make test' in text
    makefile = (ROOT / 'Makefile').read_text(encoding='utf-8')
    assert re.search(r'^run:', makefile, re.M) and re.search(r'^test:', makefile, re.M)


def test_every_page_is_in_the_navigation_or_linked_from_one():
    nav = yaml.safe_load((ROOT / 'mkdocs.yml').read_text(encoding='utf-8'))['nav']

    def pages(entry):
        if isinstance(entry, str):
            yield entry
        elif isinstance(entry, dict):
            for value in entry.values():
                yield from pages(value)
        else:
            for item in entry:
                yield from pages(item)
    in_nav = {DOCS / p for p in pages(nav)}
    assert all(p.exists() or p in GENERATED for p in in_nav), sorted(str(p) for p in in_nav if not p.exists())
    linked = {(page.parent / t.split('#')[0]).resolve() for page in PAGES for t in relative_links(page)}
    orphans = [str(p.relative_to(ROOT)) for p in PAGES if p not in in_nav and p.resolve() not in linked]
    assert not orphans, f'pages no reader can reach: {orphans}'


@pytest.mark.slow
def test_the_site_builds_without_a_warning(tmp_path):
    env = {**os.environ, 'NO_MKDOCS_2_WARNING': '1'}
    done = subprocess.run([sys.executable, '-m', 'mkdocs', 'build', '--strict', '--site-dir', str(tmp_path / 'site')],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    log = done.stdout + done.stderr
    assert done.returncode == 0, log
    assert 'WARNING' not in log, log
    api = (tmp_path / 'site' / 'api.html').read_text(encoding='utf-8')
    for name in ('Scenario.run_batch', 'Scenario.run_graph', 'RunResult.metrics', 'load_run', 'campaign_results'):
        assert f'id="adcs_sim.app.api.{name}"' in api, f'the API reference lacks {name}'


def test_the_home_page_is_the_readme_with_its_links_made_the_sites():
    """The site's home page is generated from the README (no copy to drift): links into docs/ become
    page links, a link to another repository file its path in code."""
    sys.path.insert(0, str(DOCS / 'tools'))
    try:
        from readme_home import home_markdown
    finally:
        sys.path.remove(str(DOCS / 'tools'))
    readme = (ROOT / 'README.md').read_text(encoding='utf-8')
    home = home_markdown(readme)
    assert '](docs/' not in home and '[LICENSE](LICENSE)' not in home
    assert home_markdown('[the papers](docs/papers.md#seed-000) and [LICENSE](LICENSE) and [x](https://a.b/c)') == (
        '[the papers](papers.md#seed-000) and `LICENSE` (in the repository) and [x](https://a.b/c)')
    assert len(home.splitlines()) == len(readme.splitlines())
