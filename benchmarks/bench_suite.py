"""
Where `make test`'s time goes: wall time, the cores' busy and idle seconds, and the tests' own.

Runs `make test JOBS=N` itself at a fixed suite seed, once per worker count asked, with
`--durations=0` added (the Makefile's PYTEST_ARGS), and prints per run: the wall time, the
machine's busy and idle core-seconds over it (from /proc/stat: run it with nothing else on
the machine), the worker-seconds pytest lists, and those of the groups that take most of them
(the tests that hide effects in data, the Dask study tests, the robot-space property). Where
the workers' seconds went that were not in a test (`suite_timeline.py`, a pytest plugin
loaded for the run): before each worker's first test (start-up, collection), after each
one's last (the other still busy: the imbalance; then the suite's exit), and between tests.

The machine's speed moves from day to day (the same suite at the same seed was busy 791 and
991 core-seconds on two days), so before and after the suites it times a reference
workload in a fresh process: the suite's Table II null diagnosis (test_diagnosis.py's
settings, 300 runs), and prints the busy core-seconds in units of it: a figure that compares
across days where seconds do not.

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
import tempfile
import time

from suite_timeline import FOLDER_VARIABLE

REPO = Path(__file__).resolve().parents[1]
# the files of tests that hide effects in data (bench_decisions.py runs them too)
HIDDEN_EFFECT_FILES = ('test_diagnosis.py', 'test_extensions.py', 'test_redraws.py')
GROUPS = {
    'tests that hide effects in data': HIDDEN_EFFECT_FILES,
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


def outside_tests(folder: Path, launched: float, finished: float) -> dict[str, str]:
    """
    Return the workers' seconds outside their tests, from `suite_timeline`'s files.

    Before the first test, after the last one (with the suite's exit after the last test of
    all, and the longest a worker took from its unconfigure to its exit handler), and
    between tests (set-up of module fixtures is inside a test's span).
    """
    spans, in_tests, own_ends = [], 0.0, []
    for path in sorted(folder.glob('gw*.txt')):
        events = [line.split('\t') for line in path.read_text().splitlines()]
        times = defaultdict(list)
        for event, time_s, _ in events:
            times[event].append(float(time_s))
        starts, ends = times['start'], times['end']
        if starts and ends:
            spans.append((starts[0], ends[-1]))
            in_tests += sum(end - start for start, end in zip(starts, ends))
            own_ends += [exit_s - stop for exit_s, stop in zip(times['exit'][-1:],
                                                               times['unconfigure'][-1:])]
    if not spans:
        return dict.fromkeys(TIMELINE_CELLS, 'n/a')
    before = sum(first - launched for first, _ in spans)
    after = sum(finished - last for _, last in spans)
    between = sum(last - first for first, last in spans) - in_tests
    last_test = max(last for _, last in spans)
    own = f'{max(own_ends):.1f}' if own_ends else 'n/a'
    return dict(zip(TIMELINE_CELLS, (
        f'{before:.0f}', f'{after:.0f} (exit {finished - last_test:.0f} s, teardown {own} s)',
        f'{between:.0f}')))


TIMELINE_CELLS = ('worker-s before first test', 'worker-s after last test',
                  'worker-s between tests')


def run_suite(jobs: int, seed: int) -> dict[str, str]:
    """Run `make test` once on `jobs` workers; return the table row's cells."""
    with tempfile.TemporaryDirectory(prefix='suite-timeline-') as folder:
        path = os.pathsep.join(filter(None, [str(REPO / 'benchmarks'),
                                             os.environ.get('PYTHONPATH')]))
        env = {**os.environ, 'OCTOROACH_TEST_SEED': str(seed), 'PYTHONPATH': path,
               FOLDER_VARIABLE: folder}
        before, started, launched = cpu_seconds(), time.monotonic(), time.time()
        done = subprocess.run(
            ['make', '--no-print-directory', 'test', f'JOBS={jobs}',
             'PYTEST_ARGS=--durations=0 -q -p no:cacheprovider -p suite_timeline'],
            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wall, after, finished = time.monotonic() - started, cpu_seconds(), time.time()
        timeline = outside_tests(Path(folder), launched, finished)
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
    return {**cells, **timeline}


REFERENCE = """
import sys, time
from dataclasses import replace
sys.path.insert(0, sys.argv[1])
import octoroach_model as om
from octoroach_model.diagnosis import diagnose
from hidden_effects import FAST
measured = om.simulate(300, seed=7)
started = time.process_time()
diagnose(measured, replace(FAST, seed=7))
print(time.process_time() - started)
"""


def reference_seconds() -> float:
    """Return the CPU seconds of the reference diagnosis in a fresh process (one core)."""
    done = subprocess.run([sys.executable, '-c', REFERENCE, str(REPO / 'test')], cwd=REPO,
                          stdout=subprocess.PIPE, text=True, check=True)
    return float(done.stdout.split()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seed', type=int, default=4242,
                        help='the suite seed (OCTOROACH_TEST_SEED), the same for every run')
    parser.add_argument('--jobs', type=int, nargs='+', default=[3],
                        help='xdist worker counts to run, in turn (default 3, as make test)')
    arguments = parser.parse_args(argv)
    print('timing the reference diagnosis ...', file=sys.stderr, flush=True)
    references = [reference_seconds()]
    rows = []
    for jobs in arguments.jobs:
        print(f'running the suite on {jobs} workers at seed {arguments.seed} ...',
              file=sys.stderr, flush=True)
        rows.append(run_suite(jobs, arguments.seed))
    references.append(reference_seconds())
    reference = sum(references) / len(references)
    for row in rows:
        busy = row['busy core-s']
        row['busy, references'] = f'{float(busy) / reference:.0f}' if busy != 'n/a' else 'n/a'
    print(f'suite seed {arguments.seed}; core-seconds of the whole machine over the run; '
          f'reference diagnosis {references[0]:.1f} and {references[1]:.1f} CPU-s before '
          f'and after (test_diagnosis.py\'s Table II null; "busy, references": busy '
          f'core-s over their mean)')
    print('| ' + ' | '.join(rows[0]) + ' |')
    print('|' + ' --- |' * len(rows[0]))
    for row in rows:
        print('| ' + ' | '.join(row.values()) + ' |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
