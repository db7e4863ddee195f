"""mypy on the package with setup.cfg's [mypy] section; its cache in .mypy_cache saves time."""
from pathlib import Path

from mypy import api
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.linter
@pytest.mark.mypy
def test_mypy(monkeypatch):
    monkeypatch.chdir(ROOT)
    report, errors, status = api.run(['--config-file', 'setup.cfg'])
    assert status == 0, f'mypy found type errors:\n{report}{errors}'
