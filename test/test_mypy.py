"""mypy on the package with setup.cfg's [mypy] section; its cache in .mypy_cache saves time."""
from pathlib import Path

from mypy import api
from mypy.main import process_options
from mypy.options import PER_MODULE_OPTIONS
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
def test_the_numerical_core_is_checked_as_strictly_as_mypy_strict(monkeypatch, tmp_path):
    # test_mypy reports on these packages with setup.cfg's per-module options; where those
    # are every option --strict sets (read from mypy itself, so that a new mypy's new strict
    # flag shows here), its run is a --strict run on them: a second mypy run (15-45 s on a
    # clean clone, no cache) would find nothing more.
    monkeypatch.chdir(ROOT)
    empty = tmp_path / 'empty.cfg'
    empty.write_text('[mypy]\n')
    _, plain = process_options(['--config-file', str(empty)], require_targets=False)
    _, strict = process_options(['--strict', '--config-file', str(empty)],
                                require_targets=False)
    strict_options = [name for name in sorted(PER_MODULE_OPTIONS)
                      if getattr(plain, name) != getattr(strict, name)]
    assert len(strict_options) >= 8, strict_options
    _, configured = process_options(['--config-file', 'setup.cfg'], require_targets=False)
    global_options = [name for name in dir(strict) if not name.startswith('_')
                      and name not in PER_MODULE_OPTIONS
                      and not callable(getattr(strict, name))
                      and getattr(plain, name) != getattr(strict, name)]
    looser = [name for name in global_options
              if getattr(configured, name) != getattr(strict, name)]
    assert not looser, f'setup.cfg leaves out global options --strict sets: {looser}'
    for package in STRICT_PACKAGES:
        ours = configured.clone_for_module(f'{package}.any_module')
        looser = [name for name in strict_options
                  if getattr(ours, name) != getattr(strict, name)]
        assert not looser, f'{package} is checked less strictly than --strict: {looser}'
    # the section is read per module: outside the core the package is not held to them
    outside = configured.clone_for_module('octoroach_model.cli')
    assert not outside.disallow_untyped_defs
