"""
What the library of extension families costs: `diagnose` of bags/ with and without it.

The 500 runs in bags/, end to end, with this checkout and with the release before the
families joined the race, in one run.

The earlier release is checked out from this repository's history into a temporary folder
(`git worktree add --detach`, removed at the end) and run with the same environment; the two
programs alternate, REPEATS times each, so that a busy machine slows both alike. Prints the
median wall time of each and their ratio (issue 23 asks for at most 1.5).

Run: .venv/bin/python benchmarks/bench_extension_cost.py [--baseline REV] [--repeats N]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
BASELINE = '3d46d39'     # the last release whose diagnosis raced the six causes alone


def timed_diagnosis(source: Path, out: Path) -> float:
    """
    Run `diagnose bags/` with the package at `source`; return its wall time in seconds.

    Run from `source` itself: `python -m` puts the working folder first on the path.
    """
    env = {**os.environ, 'PYTHONPATH': str(source)}
    started = time.perf_counter()
    subprocess.run([sys.executable, '-m', 'octoroach_model', 'diagnose', str(REPO / 'bags'),
                    '--out', str(out), '--seed', '1'], env=env, check=True, cwd=source,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--baseline', default=BASELINE, help='the earlier release (a git rev)')
    parser.add_argument('--repeats', type=int, default=3, help='runs of each program')
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        earlier = Path(scratch) / 'baseline'
        subprocess.run(['git', '-C', str(REPO), 'worktree', 'add', '--detach', str(earlier),
                        args.baseline], check=True, capture_output=True)
        try:
            times: dict[str, list[float]] = {'baseline': [], 'current': []}
            for repeat in range(args.repeats):
                for name, source in (('baseline', earlier), ('current', REPO)):
                    seconds = timed_diagnosis(source, Path(scratch) / f'{name}_{repeat}')
                    times[name].append(seconds)
                    print(f'{name} run {repeat + 1}: {seconds:.1f} s', file=sys.stderr)
        finally:
            subprocess.run(['git', '-C', str(REPO), 'worktree', 'remove', '--force',
                            str(earlier)], check=False, capture_output=True)
    before, after = (statistics.median(times[name]) for name in ('baseline', 'current'))
    print('| diagnose bags/ (500 runs, 2 workers, report and plots) | median wall time |')
    print('| --- | --- |')
    print(f'| release {args.baseline} (six causes in the race) | {before:.1f} s |')
    print(f'| this checkout (six causes and seven family terms) | {after:.1f} s |')
    print(f'| ratio | {after / before:.2f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
