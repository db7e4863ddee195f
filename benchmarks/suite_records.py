"""
What the suite's recording plugins of benchmarks/ share: where a record goes, how it is read.

A plugin (`suite_decisions.py`, `suite_path_refits.py`) is told a folder by an environment
variable and appends one JSON line per record to its process's file there (`worker_file`),
naming the test that made it (`current_test`); a benchmark runs the suite with it
(`run_tests`: the Makefile's pytest options, `-n 2 --maxschedchunk=2`) and reads the lines
back (`read_lines`).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import re
import subprocess
import sys
import time
from typing import Any

REPO = Path(__file__).resolve().parents[1]
OUTCOME = re.compile(r'(\d+ (passed|failed|error)[^\n]*)')


def worker_file(folder: str | Path) -> Path:
    """Return this pytest process's file of records in `folder`."""
    return Path(folder) / f'{os.environ.get("PYTEST_XDIST_WORKER", "controller")}.jsonl'


def current_test() -> str:
    """Return the node id of the test running now ('' outside a test)."""
    return os.environ.get('PYTEST_CURRENT_TEST', '').rsplit(' ', 1)[0]


def append(folder: str | Path, record: dict[str, Any]) -> None:
    """Append `record` as one JSON line to this process's file in `folder`."""
    with worker_file(folder).open('a') as stream:
        stream.write(json.dumps(record) + '\n')


def read_lines(folder: Path) -> list[dict[str, Any]]:
    """Return every record in `folder`, file by file (each process's in the order it ran)."""
    return [json.loads(line) for path in sorted(folder.glob('*.jsonl'))
            for line in path.read_text().splitlines()]


MAKEFILE_WORKERS = ('-n', '2', '--maxschedchunk=2')     # the Makefile's pytest workers


def run_tests(tree: Path, seed: int, files: list[str], folder: Path, plugin: str,
              variable: str, workers: tuple[str, ...] = MAKEFILE_WORKERS) -> tuple[str, float]:
    """
    Run `files` of `tree` at suite seed `seed`, recording into `folder`; outcome, wall s.

    `plugin` (a module of benchmarks/) records, told the folder by the environment `variable`;
    `files` may carry pytest's selection too (`-k EXPRESSION`), and `workers` replaces the
    Makefile's xdist options (('-p', 'no:xdist'): one process).
    """
    folder.mkdir()
    env = {**os.environ, 'OCTOROACH_TEST_SEED': str(seed), variable: str(folder),
           'PYTHONPATH': os.pathsep.join([str(tree), str(REPO / 'benchmarks')])}
    started = time.perf_counter()
    finished = subprocess.run(
        [sys.executable, '-m', 'pytest', *workers, '-q',
         '-p', 'no:cacheprovider', '-p', plugin, '--rootdir', str(tree), *files],
        cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    found = OUTCOME.findall(finished.stdout)
    return (found[-1][0] if found else f'pytest exit {finished.returncode}'), wall
