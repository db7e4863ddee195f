"""
The documentation in docs/ says what the code does, in the project's own words.

Checked here: links and anchors between the pages resolve, the figures a page quotes come
from the code block beside them, the table of causes and Table II match the code and
config/table2.yaml, and nothing points users to files outside the repository.
"""
from __future__ import annotations

from pathlib import Path
import re
import subprocess
import sys

import pytest
import yaml

from octoroach_model.model import EFFECT_PARAMETERS, PARAMETER_RANGES

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / 'docs'
OWN_PAGES = ('index.md', 'model.md', 'validation.md', 'causes.md', 'extensions.md')
# Pages other parts of the project write; a link to one is checked once the page exists.
OTHER_PAGES = ('diagnosis.md', 'report.md', 'ros.md', 'bags.md', 'formats.md',
               'formats_mocap.md', 'studies.md', 'measured.md', 'speed.md')
LINK = re.compile(r'\]\(([^)\s]+)\)')
CHECKED_BLOCK = re.compile(
    r'<!-- test/test_docs\.py runs the next Python block.*?-->\s*'
    r'```python\n(?P<code>.*?)```\s*```text\n(?P<output>.*?)```', re.DOTALL)


def read(page: str) -> str:
    return (DOCS / page).read_text(encoding='utf-8')


def github_anchor(heading: str) -> str:
    """Return the anchor GitHub gives a heading: lower case, no punctuation, spaces to '-'."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def anchors(page: Path) -> set[str]:
    text = page.read_text(encoding='utf-8')
    text = re.sub(r'```.*?```', '', text, flags=re.DOTALL)   # no headings inside code
    return {github_anchor(match) for match in re.findall(r'^#+ (.+)$', text, re.MULTILINE)}


@pytest.mark.parametrize('page', OWN_PAGES)
def test_every_link_between_the_pages_resolves(page):
    for target in LINK.findall(read(page)):
        if re.match(r'[a-z]+://', target):
            continue
        name, _, anchor = target.partition('#')
        path = (DOCS / name) if name else DOCS / page
        if name in OTHER_PAGES and not path.exists():
            continue
        assert path.is_file(), f'{page}: link to missing {target}'
        if anchor:
            assert anchor in anchors(path), f'{page}: no heading for #{anchor} in {name}'


def test_the_index_links_every_page():
    linked = {target.partition('#')[0] for target in LINK.findall(read('index.md'))}
    assert set(OWN_PAGES) - {'index.md'} <= linked
    assert set(OTHER_PAGES) <= linked
    present = {path.name for path in DOCS.glob('*.md') if not path.name.startswith('README_')}
    assert present - {'index.md'} <= linked, 'a page in docs/ is missing from index.md'


def test_nothing_points_to_files_outside_the_repository():
    sources = [DOCS / page for page in OWN_PAGES]
    for folder in ('model', 'validation'):
        sources += sorted((REPO / 'octoroach_model' / folder).glob('*.py'))
    for path in sources:
        text = path.read_text(encoding='utf-8')
        for outside in ('NOTES.md', 'CONTRACT.md', '/work/'):
            assert outside not in text, f'{path.relative_to(REPO)} mentions {outside}'


@pytest.mark.parametrize('page', ['model.md', 'validation.md'])
def test_the_figures_of_a_page_come_from_the_code_block_beside_them(page):
    checked = list(CHECKED_BLOCK.finditer(read(page)))
    assert checked, f'{page} has lost its checked code block'
    for block in checked:
        ran = subprocess.run([sys.executable, '-c', block['code']], cwd=REPO,
                             capture_output=True, text=True, timeout=300)
        assert ran.returncode == 0, ran.stderr
        assert ran.stdout.strip() == block['output'].strip()


def table_rows(page: str, first_column: str) -> list[list[str]]:
    """Cells of the Markdown table whose header starts with `first_column`."""
    rows, inside = [], False
    for line in read(page).splitlines():
        if line.startswith(f'| {first_column} |'):
            inside = True
            continue
        if inside and line.startswith('| ---'):
            continue
        if inside and line.startswith('|'):
            rows.append([cell.strip() for cell in line.strip('|').split(' | ')])
        elif inside:
            break
    return rows


def test_the_table_of_causes_lists_every_cause_with_its_parameters_and_ranges():
    rows = {row[0].strip('`'): row for row in table_rows('causes.md', 'cause')}
    assert list(rows) == ['none', 'initial_pose_error', 'measurement_noise',
                          'gait_frequency_variation', 'speed_decay', 'lateral_slip',
                          'persistent_turning']
    assert set(rows) - {'none'} == set(EFFECT_PARAMETERS)
    for cause, parameters in EFFECT_PARAMETERS.items():
        documented = re.findall(r'`(\w+)` \([^,]+, (-?[\d.]+)-(-?[\d.]+)\)', rows[cause][1])
        assert [name for name, _, _ in documented] == list(parameters), cause
        for name, low, high in documented:
            assert (float(low), float(high)) == PARAMETER_RANGES[name], (cause, name)


def test_table_ii_in_the_model_page_is_the_shipped_file():
    shipped = yaml.safe_load((REPO / 'config' / 'table2.yaml').read_text())['octoroach_model']
    quoted = {}
    for row in table_rows('model.md', 'parameter'):
        for key, value in re.findall(r'`(\w+): ([^`]+)`', row[-1]):
            quoted[key] = yaml.safe_load(value)
    assert quoted == shipped
