"""
Where `make test`'s time goes: wall time, the cores' busy and idle seconds, and the tests' own.

Runs `make test JOBS=N` itself at a fixed suite seed, once per worker count asked, with
`--durations=0` added (the Makefile's PYTEST_ARGS), and prints per run: the wall time, the
machine's busy and idle core-seconds over it (from /proc/stat: run it with nothing else on
the machine), the worker-seconds pytest lists, and those of the groups that take most of them
(the tests that hide effects in data, the Dask study tests, the robot-space property).

Why it is here: issue 26 asks for `make test` within 6 minutes; this says whether the cores
are idle (more workers would help) or full (the tests must cost less), and which tests cost.
Not in `make bench` (it takes two cores for about 8 minutes a run).

Run: .venv/bin/python benchmarks/bench_suite.py [--seed N] [--jobs 2 3]
"""
from __future__ import annotations

import argparse
from collections import defaultdict
import os
from pathlib import Path
import re
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parents[1]
GROUPS = {
    'tests that hide effects in data': ('test_diagnosis.py', 'test_extensions.py',
                                        'test_redraws.py'),
    'Dask study tests': ('test_studies_dask.py',),
    'robot-space property': ('test_robot_space.py',),
}
DURATION = re.compile(r'^([0-9.]+)s (call|setup|teardown)\s+test/([^:]+)::')
PASSED = re.compile(r'(\d+) passed')


def cpu_seconds() -> tuple[float, float] | None:
    """Busy and idle seconds of all cores since boot (None where /proc/stat is absent)."""
    try:
        fields = Path('/proc/stat').read_text().splitlines()[0].split()[1:]
    except OSError:
        return None
    user, nice, system, idle, iowait = (int(value) for value in fields[:5])
    tick = os.sysconf('SC_CLK_TCK')
    return (user + nice + system) / tick, (idle + iowait) / tick


def run_suite(jobs: int, seed: int) -> dict[str, str]:
    """Run `make test` once on `jobs` workers; return the table row's cells."""
    before, started = cpu_seconds(), time.monotonic()
    done = subprocess.run(
        ['make', '--no-print-directory', 'test', f'JOBS={jobs}',
         'PYTEST_ARGS=--durations=0 -q -p no:cacheprovider'],
        cwd=REPO, env={**os.environ, 'OCTOROACH_TEST_SEED': str(seed)},
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall, after = time.monotonic() - started, cpu_seconds()
    per_file: dict[str, float] = defaultdict(float)
    passed = '?'
    for line in done.stdout.splitlines():
        if match := DURATION.match(line):
            per_file[match.group(3)] += float(match.group(1))
        elif match := PASSED.search(line):
            passed = match.group(1)
    busy, idle = ((f'{after[0] - before[0]:.0f}', f'{after[1] - before[1]:.0f}')
                  if before and after else ('n/a', 'n/a'))
    cells = {'workers': str(jobs), 'passed': passed if done.returncode == 0 else
             f'{passed} (exit {done.returncode})', 'wall, s': f'{wall:.0f}',
             'busy core-s': busy, 'idle core-s': idle,
             'worker-s listed': f'{sum(per_file.values()):.0f}'}
    for group, files in GROUPS.items():
        cells[group] = f'{sum(per_file[name] for name in files):.0f}'
    return cells


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seed', type=int, default=4242,
                        help='the suite seed (OCTOROACH_TEST_SEED), the same for every run')
    parser.add_argument('--jobs', type=int, nargs='+', default=[2],
                        help='xdist worker counts to run, in turn (default 2, as make test)')
    arguments = parser.parse_args(argv)
    rows = []
    for jobs in arguments.jobs:
        print(f'running the suite on {jobs} workers at seed {arguments.seed} ...',
              file=sys.stderr, flush=True)
        rows.append(run_suite(jobs, arguments.seed))
    print(f'suite seed {arguments.seed}; core-seconds of the whole machine over the run')
    print('| ' + ' | '.join(rows[0]) + ' |')
    print('|' + ' --- |' * len(rows[0]))
    for row in rows:
        print('| ' + ' | '.join(row.values()) + ' |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
