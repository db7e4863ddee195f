"""
pydocstyle with ament's convention, as in the ament_python template.

The template checks '.' and 'test'; here that would include .venv/, so the repository's own
Python files are named.
"""
from pathlib import Path

from ament_pep257.main import main
import pytest

ROOT = Path(__file__).resolve().parents[1]
LINTED = ['octoroach_model', 'test', 'benchmarks', 'setup.py']


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc = main(argv=LINTED)
    assert rc == 0, 'Found code style errors / warnings'
