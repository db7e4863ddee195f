"""
What every offline program does with a bad command line or bad data, before any work.

Exit codes (README, "Exit codes"; the table in `octoroach_model.errors`): 2 for a usage error
(unknown option, a malformed or out-of-range value, which the message names), 1 for data or
values that cannot be used, 3 for an output that cannot be written; one line `error: ...` on
stderr, never a traceback. An output that cannot be written is refused before any input is
read. `--help` shows every option's default.
"""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys
import time

import pytest

from octoroach_model.commands import OFFLINE

REPO = Path(__file__).resolve().parents[1]


def run(*args, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'octoroach_model', *map(str, args)],
                          cwd=REPO, capture_output=True, text=True, timeout=timeout)


def one_line(result: subprocess.CompletedProcess) -> str:
    assert 'Traceback' not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith('error:'), result.stderr
    return lines[0]


@pytest.mark.parametrize('program', sorted(OFFLINE))
def test_an_unknown_option_is_a_usage_error_with_exit_2(program) -> None:
    result = run(program, '--no-such-option')
    assert result.returncode == 2
    assert 'see --help' in one_line(result)


@pytest.mark.parametrize('program', ['simulate', 'validate', 'diagnose'])
def test_a_negative_seed_names_the_option(program, tmp_path) -> None:
    inputs = [] if program == 'simulate' else [tmp_path]
    outputs = {'simulate': ['--paths', 3, '--out', tmp_path / 'bag'],
               'diagnose': ['--out', tmp_path / 'out']}.get(program, [])
    result = run(program, *inputs, *outputs, '--seed', -1)
    assert result.returncode == 2
    line = one_line(result)
    assert '--seed' in line and 'non-negative' in line


@pytest.mark.parametrize('program', sorted(OFFLINE))
def test_help_shows_every_option_with_a_description(program) -> None:
    result = run(program, '--help')
    assert result.returncode == 0
    lines = result.stdout.splitlines()
    options = [number for number, line in enumerate(lines)         # not a wrapped description
               if line.startswith('  -') and not line.startswith('   ')]
    assert options, result.stdout
    for number in options:
        # argparse puts the description after two spaces, or on the next, deeper line
        line = lines[number].strip()
        after = lines[number + 1] if number + 1 < len(lines) else ''
        on_next = (after.startswith(' ' * 8) and after.strip()
                   and not after.strip().startswith('-'))
        assert '  ' in line or on_next, f'{program}: {line!r} has no description'


def test_defaults_are_shown_in_help() -> None:
    text = ' '.join(run('simulate', '--help').stdout.split())
    assert '(default: 10.0)' in text and 'seed of every random draw (default: 0)' in text


def test_diagnose_refuses_an_output_that_exists_before_reading_any_input(tmp_path) -> None:
    existing = tmp_path / 'report'
    existing.mkdir()
    (existing / 'report.json').write_text('{}')
    started = time.monotonic()
    result = run('diagnose', REPO / 'bags', '--out', existing)
    assert result.returncode == 3 and 'not empty' in one_line(result)
    assert time.monotonic() - started < 20     # no 500-run diagnosis happened first
    assert (existing / 'report.json').read_text() == '{}'   # nothing overwritten


def test_data_that_cannot_be_used_is_exit_1(tmp_path) -> None:
    not_a_bag = tmp_path / 'runs.mcap'
    not_a_bag.write_text('not an MCAP file')
    result = run('validate', not_a_bag)
    assert result.returncode == 1
    one_line(result)


def test_an_output_where_nothing_can_be_written_is_refused_at_once() -> None:
    # /proc takes no new file: the check comes before the 500 runs are read and diagnosed
    started = time.monotonic()
    result = run('diagnose', REPO / 'bags', '--out', '/proc/octoroach_report')
    assert result.returncode == 3 and 'cannot write in /proc' in one_line(result)
    assert time.monotonic() - started < 20
