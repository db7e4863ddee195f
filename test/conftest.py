"""
Suite-wide set-up: an isolated ROS domain per test process, and one visible random seed.

Parallel runs (pytest-xdist workers, two CI jobs on one machine) must never hear each other,
so the domain id comes from the worker and the process id. Child processes started by tests
inherit these variables.

Tests that draw their cases at random (hidden causes, robots) take them from one suite seed:
OCTOROACH_TEST_SEED if set, else a fresh one chosen by the controlling process before the
workers start (so every worker uses the same), printed in pytest's header and in every
failure message that depends on it. `OCTOROACH_TEST_SEED=N make test` replays a run.

Tests marked `long` (15 s or more) run first: xdist hands tests out in collection order, and
a long test started last keeps one core busy while the other has nothing left to do.
"""
from __future__ import annotations

import hashlib
import os
import random

import matplotlib

matplotlib.use('Agg')
SEED_VARIABLE = 'OCTOROACH_TEST_SEED'
# the markers of the ament_python template's lint tests, and of the mypy test beside them
LINT_MARKERS = {
    'linter': 'a static check of the code (flake8, pep257, mypy)',
    'flake8': "flake8 with ament's plugins and settings",
    'pep257': "pydocstyle with ament's convention",
    'mypy': 'mypy on the package',
}


def _isolated_domain_id() -> int:
    """
    Return this test process's domain: one run's workers take consecutive ids.

    The run's base comes from xdist's id of the run (shared by its workers; the process id
    without xdist), so two workers of one run never share a domain, and two runs at once
    share one only where their bases fall within a worker count of each other.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    worker_index = int(''.join(ch for ch in worker if ch.isdigit()) or 0)
    run = os.environ.get('PYTEST_XDIST_TESTRUNUID') or str(os.getpid())
    base = int.from_bytes(hashlib.sha256(run.encode()).digest()[:4], 'big')
    # Fast DDS with LOCALHOST range accepts domain ids 0..232; keep clear of 0 (the default).
    return 1 + (base + worker_index) % 200


os.environ['ROS_DOMAIN_ID'] = str(_isolated_domain_id())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')


def pytest_configure(config) -> None:
    """Fix the suite seed before any worker starts (they inherit it); name the lint markers."""
    os.environ.setdefault(SEED_VARIABLE, str(random.SystemRandom().randrange(10 ** 6)))
    for marker, meaning in LINT_MARKERS.items():
        config.addinivalue_line('markers', f'{marker}: {meaning}')
    config.addinivalue_line('markers', 'long: takes 15 s or more; run first (see above)')


def pytest_collection_modifyitems(config, items) -> None:
    """Put the tests marked `long` first, each group in its collected order."""
    items.sort(key=lambda item: item.get_closest_marker('long') is None)


def pytest_report_header(config) -> str:
    return (f'{SEED_VARIABLE}={os.environ[SEED_VARIABLE]} (set it to replay the random draws '
            f'of this run)')
