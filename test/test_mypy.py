"""mypy on the package with setup.cfg's [mypy] section; its cache in .mypy_cache saves time."""
from pathlib import Path

from mypy import api
import pytest

ROOT = Path(__file__).resolve().parents[1]
# Held to `mypy --strict` (issue 25): the numerical core and what decides on it.
STRICT_PACKAGES = ('octoroach_model.model', 'octoroach_model.validation',
                   'octoroach_model.diagnosis', 'octoroach_model.fitting')


@pytest.mark.linter
@pytest.mark.mypy
def test_mypy(monkeypatch):
    monkeypatch.chdir(ROOT)
    report, errors, status = api.run(['--config-file', 'setup.cfg'])
    assert status == 0, f'mypy found type errors:\n{report}{errors}'


@pytest.mark.linter
@pytest.mark.mypy
def test_mypy_strict_on_the_numerical_core(monkeypatch):
    # The modules these import are read for their types but not reported on (silent): only
    # the four packages are held to --strict. Its own cache: other global options would
    # invalidate test_mypy's at every run (about 12 s each instead of 2).
    monkeypatch.chdir(ROOT)
    packages = [option for name in STRICT_PACKAGES for option in ('-p', name)]
    report, errors, status = api.run(['--strict', '--config-file', 'setup.cfg',
                                      '--follow-imports', 'silent',
                                      '--cache-dir', '.mypy_cache/strict', *packages])
    assert status == 0, f'mypy --strict found type errors:\n{report}{errors}'
