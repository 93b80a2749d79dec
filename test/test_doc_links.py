"""The documentation points only at what the repository has (issue 33: the README cited
DESIGN.md and shared/tools, which it does not).

Every relative link of README.md, docs/ and msg_docs/ names an existing file, and an anchor
(``file.md#heading``) one of its headings (GitHub's slugs); no page refers to the design
notes or tools that live outside the repository.
"""
from pathlib import Path
import re

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / 'README.md', ROOT / 'CHANGELOG.rst'] + sorted((ROOT / 'docs').glob('*.md')) \
    + sorted((ROOT / 'msg_docs').glob('*.md'))
LINK = re.compile(r'\]\(([^)\s]+)\)')


def slug(heading):
    """GitHub's anchor of a markdown heading."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def anchors(path):
    return {slug(h) for h in re.findall(r'^#+ (.*)$', path.read_text(), re.M)}


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    for target in LINK.findall(page.read_text()):
        if re.match(r'[a-z]+:', target):
            continue                                    # a URL
        name, _, anchor = target.partition('#')
        path = (page.parent / name).resolve() if name else page
        assert path.exists(), f'{page.name}: {target} does not exist'
        if anchor and path.suffix == '.md':
            assert anchor in anchors(path), f'{page.name}: no heading #{anchor} in {name}'


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_page_cites_what_the_repository_does_not_have(page):
    text = page.read_text()
    assert 'DESIGN.md' not in text and 'shared/tools' not in text, page.name


def test_no_source_cites_the_design_notes():
    sources = list((ROOT / 'tensegrity_ros').rglob('*.py')) + \
        [p for p in (ROOT / 'test').glob('*.py') if p.name != Path(__file__).name] + \
        sorted((ROOT / 'config').glob('*.yaml')) + sorted((ROOT / 'launch').glob('*.py'))
    citing = [str(p.relative_to(ROOT)) for p in sources if 'DESIGN.md' in p.read_text()]
    assert not citing, citing
