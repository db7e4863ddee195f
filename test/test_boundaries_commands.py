"""
Every command repeatable, every output whole or absent, one meaning per option and exit code.

Each test reproduces a problem of issue 24: Ctrl-C on `diagnose` left report.json and
summary.md without plots (which then blocked the re-run) and printed `ForkProcess ...
KeyboardInterrupt` tracebacks; a second `make demo` failed on its own output and `make
clean` deleted the venv; `--workers 0` was an error for `diagnose` but "in this process" for
`study`; README linked docs/formats.md as `formats.md`.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import time

import pytest

import octoroach_model as om
from octoroach_model.errors import EXIT_CODES, EXIT_INTERRUPTED
from octoroach_model.recordings import save_dataset

REPO = Path(__file__).resolve().parents[1]
# Python keeps SIGINT ignored when it starts with it ignored (a background job of a
# non-interactive shell); the child gets Python's default handler, as in a terminal.
WITH_CTRL_C = ('import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); '
               "runpy.run_module('octoroach_model', run_name='__main__', alter_sys=True)")


@pytest.fixture(scope='module')
def runs40(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp('runs')
    return save_dataset(folder / 'runs40.npz', om.simulate(40, seed=1, cycles=4))


def test_ctrl_c_on_diagnose_leaves_no_report_and_no_traceback(runs40, tmp_path):
    out = tmp_path / 'report'
    process = subprocess.Popen([sys.executable, '-c', WITH_CTRL_C, 'diagnose', str(runs40),
                                '--out', str(out), '--workers', '2'], cwd=REPO,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    lines: list[str] = []
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:        # into the side-by-side work of the workers
        line = process.stderr.readline()
        lines.append(line)
        if not line or 'step 1' in line:
            break
    os.killpg(process.pid, signal.SIGINT)     # what a terminal's Ctrl-C does: the group
    stdout, stderr = process.communicate(timeout=120)
    stderr = ''.join(lines) + stderr
    assert process.returncode == 130, stderr
    assert 'Traceback' not in stderr and 'KeyboardInterrupt' not in stderr, stderr
    assert stderr.rstrip().splitlines()[-1] == 'error: diagnose: interrupted', stderr
    assert not out.exists()                   # nothing, so the same command runs again
    assert not [p for p in tmp_path.iterdir() if p.name != 'report'], list(tmp_path.iterdir())


def test_workers_has_one_meaning_in_study_and_diagnose():
    texts = {name: subprocess.run([sys.executable, '-m', 'octoroach_model', name, '--help'],
                                  cwd=REPO, capture_output=True, text=True).stdout
             for name in ('diagnose', 'study', 'plan')}
    for name, text in texts.items():
        flat = ' '.join(text.split())
        assert '0 runs everything in this process' in flat, name
        assert 'one per core' in flat, name


def make(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run(['make', '--no-print-directory', *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_make_demo_replaces_its_own_output_never_a_users(tmp_path):
    """`make demo` with a stand-in for Python that writes a report as diagnose would."""
    fake = tmp_path / 'python'
    fake.write_text('#!/bin/sh\n# -m octoroach_model diagnose INPUT --out DIR ...\n'
                    'mkdir "$6" && date +%s%N > "$6/report.json"\n')
    fake.chmod(0o755)
    demo = tmp_path / 'demo'
    common = ['-o', '.venv/.installed', 'demo', f'PY={fake}', f'DEMO={demo}']
    first = make(*common)
    assert first.returncode == 0, first.stderr
    before = (demo / 'report.json').read_text()
    time.sleep(0.01)
    second = make(*common)
    assert second.returncode == 0, second.stderr
    assert (demo / 'report.json').read_text() != before      # replaced, again and again

    users = tmp_path / 'users'
    users.mkdir()
    (users / 'notes.txt').write_text('mine')
    refused = make('-o', '.venv/.installed', 'demo', f'PY={fake}', f'DEMO={users}')
    assert refused.returncode != 0 and 'was not written by make demo' in refused.stderr
    assert (users / 'notes.txt').read_text() == 'mine'


def test_make_clean_keeps_the_venv_and_distclean_removes_it():
    clean = make('-n', 'clean').stdout
    distclean = make('-n', 'distclean').stdout
    assert '.venv' not in clean and 'rm -rf' in clean
    assert 'rm -rf .venv' in distclean


def test_make_clean_removes_the_demo_but_keeps_studies_and_a_users_folder(tmp_path):
    """`make clean` used to remove all of out/, hours of studies with it."""
    shutil.copy(REPO / 'Makefile', tmp_path / 'Makefile')
    study = tmp_path / 'out' / 'studies' / 'limits'
    study.mkdir(parents=True)
    (study / 'table.csv').write_text('key\n')
    demo = tmp_path / 'out' / 'demo'
    demo.mkdir()
    (demo / '.written-by-make-demo').touch()
    users = tmp_path / 'mine'
    users.mkdir()
    done = subprocess.run(['make', '-C', str(tmp_path), 'clean', f'DEMO={users}'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and users.is_dir()           # not marked: a user's folder
    done = subprocess.run(['make', '-C', str(tmp_path), 'clean'], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0
    assert not demo.exists() and (study / 'table.csv').read_text() == 'key\n'


LINK = re.compile(r'\[[^\]]*\]\(([^)\s]+)\)')


def test_every_link_in_readme_and_docs_resolves():
    broken = []
    for page in [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]:
        for target in LINK.findall(page.read_text()):
            if re.match(r'[a-z]+://', target) or target.startswith('mailto:'):
                continue
            path, _, anchor = target.partition('#')
            resolved = (page.parent / path) if path else page
            if not resolved.exists():
                broken.append(f'{page.name}: {target}')
            elif anchor and resolved.suffix == '.md' and anchor not in anchors(resolved):
                broken.append(f'{page.name}: {target} (no such heading)')
    assert not broken, broken


def anchors(page: Path) -> set[str]:
    """Return a page's heading anchors as GitHub makes them (lower case, no punctuation)."""
    found = set()
    for line in page.read_text().splitlines():
        if line.startswith('#'):
            text = line.lstrip('#').strip().lower()
            found.add(re.sub(r'\s', '-', re.sub(r'[^\w\s-]', '', text)))
    return found


def test_the_exit_code_table_is_the_same_in_readme_and_in_every_program():
    readme = ' '.join((REPO / 'README.md').read_text().split())
    for code, meaning in EXIT_CODES.items():
        assert f'| {code} | {meaning}' in readme, (code, meaning)
    usage = subprocess.run([sys.executable, '-m', 'octoroach_model', '--help'], cwd=REPO,
                           capture_output=True, text=True).stdout
    assert '3 output cannot be written' in usage


@pytest.mark.parametrize('command', ['simulate', 'convert'])
def test_a_bag_written_by_simulate_or_convert_is_whole_or_absent(tmp_path, monkeypatch, command):
    from octoroach_model.recordings.standard_bag import pose_writer

    source = tmp_path / 'source'
    om.write_paths_bag(source, om.simulate(3, seed=1, cycles=3))
    out = tmp_path / 'out'
    written = []

    def fail_after_the_first_run(self, stamps, poses, **more):
        if written:
            raise KeyboardInterrupt
        written.append(len(stamps))
        return original(self, stamps, poses, **more)

    original = pose_writer.PoseBagWriter.write_poses
    monkeypatch.setattr(pose_writer.PoseBagWriter, 'write_poses', fail_after_the_first_run)
    from octoroach_model.commands import run_command
    args = (['--paths', '3', '--out', str(out), '--cycles', '3'] if command == 'simulate'
            else [str(source), '--out', str(out)])
    assert run_command(command, args) == EXIT_INTERRUPTED
    assert written and not out.exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ['source']   # nothing left
