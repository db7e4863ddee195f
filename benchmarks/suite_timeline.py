"""
A pytest plugin for `bench_suite.py`: when each test process starts and ends each test.

Loaded with `-p suite_timeline` (benchmarks/ on PYTHONPATH); each process (the xdist
controller and every worker) appends its events to its own file in the folder that
OCTOROACH_SUITE_TIMELINE names, one line each: event, wall-clock time (s), test id. Without
that variable it records nothing. `exit` is written by an exit handler registered at
configure: it runs after the handlers registered later (by modules the tests import) and
after the interpreter joined its threads, so a long gap from `unconfigure` to it is a test
process slow to end.
"""
from __future__ import annotations

import atexit
import os
from pathlib import Path
import time
from typing import TextIO

FOLDER_VARIABLE = 'OCTOROACH_SUITE_TIMELINE'
_stream: list[TextIO] = []


def _write(event: str, test: str = '') -> None:
    folder = os.environ.get(FOLDER_VARIABLE)
    if not folder:
        return
    if not _stream:
        name = os.environ.get('PYTEST_XDIST_WORKER', 'controller')
        _stream.append((Path(folder) / f'{name}.txt').open('a', buffering=1))
    _stream[0].write(f'{event}\t{time.time():.3f}\t{test}\n')


def pytest_configure(config) -> None:
    _write('configure')
    atexit.register(_write, 'exit')


def pytest_runtest_logstart(nodeid: str, location) -> None:
    _write('start', nodeid)


def pytest_runtest_logfinish(nodeid: str, location) -> None:
    _write('end', nodeid)


def pytest_unconfigure(config) -> None:
    _write('unconfigure')
