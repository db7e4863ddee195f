"""
flake8 with ament's plugins and settings, as in the ament_python template.

The template lints '.', which here would include .venv/; this test lints the repository's own
Python files, with setup.cfg's [flake8] section: ament's configuration plus this package's
name for the import order (a second test keeps the two from drifting apart).
"""
import configparser
from pathlib import Path

import ament_flake8
from ament_flake8.main import main_with_errors
import pytest

ROOT = Path(__file__).resolve().parents[1]
LINTED = ['octoroach_model', 'test', 'benchmarks', 'setup.py']


@pytest.mark.long
@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    monkeypatch.chdir(ROOT)  # ament_flake8 skips the dot and underscore folders under the cwd
    rc, errors = main_with_errors(argv=['--config', 'setup.cfg', *LINTED])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8_config_repeats_ament():
    ament_config = Path(ament_flake8.__file__).parent / 'configuration' / 'ament_flake8.ini'
    ament, ours = configparser.ConfigParser(), configparser.ConfigParser()
    ament.read(ament_config)
    ours.read(ROOT / 'setup.cfg')
    differing = {key: (value, ours['flake8'].get(key))
                 for key, value in ament['flake8'].items() if ours['flake8'].get(key) != value}
    assert not differing, f'setup.cfg [flake8] differs from {ament_config}: {differing}'
