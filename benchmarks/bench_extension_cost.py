"""
What the library of extension families costs: `diagnose` of bags/ with and without it.

The 500 runs in bags/, end to end, with this checkout and with the release before the
families joined the race, in one run.

The earlier release is copied out of this repository's history into a temporary folder
(`revisions.export`: nothing registered in the repository) and run with the same
environment; the two programs alternate, REPEATS times each, so that a busy machine slows
both alike. Prints the median wall time of each and their ratio (issue 23 asks for at most
1.5). `--candidate REV` times another commit in place of this checkout (copied out the same
way), so that a figure about two past commits can be measured again (docs/speed.md:
c5602ef against 878b61e).

Run: .venv/bin/python benchmarks/bench_extension_cost.py [--baseline REV] [--candidate REV]
     [--repeats N]
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

from revisions import commit_of, export

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
    parser.add_argument('--candidate', help='time this commit instead of this checkout')
    parser.add_argument('--repeats', type=int, default=3, help='runs of each program')
    args = parser.parse_args(argv)
    revisions = {'baseline': commit_of(args.baseline),
                 'current': commit_of(args.candidate) if args.candidate else None}
    with tempfile.TemporaryDirectory() as scratch:
        sources = {name: export(rev, Path(scratch) / name) if rev else REPO
                   for name, rev in revisions.items()}
        times: dict[str, list[float]] = {'baseline': [], 'current': []}
        for repeat in range(args.repeats):
            for name, source in sources.items():
                seconds = timed_diagnosis(source, Path(scratch) / f'{name}_{repeat}')
                times[name].append(seconds)
                print(f'{name} run {repeat + 1}: {seconds:.1f} s', file=sys.stderr)
    before, after = (statistics.median(times[name]) for name in ('baseline', 'current'))
    ratios = sorted(late / early for early, late in zip(times['baseline'], times['current']))
    print('| diagnose bags/ (500 runs, 2 workers, report and plots) | median wall time |')
    print('| --- | --- |')
    print(f'| commit {args.baseline} | {before:.1f} s |')
    print(f'| {"commit " + args.candidate if args.candidate else "this checkout"} | '
          f'{after:.1f} s |')
    print(f'| ratio (of the medians; of each pair of runs: {ratios[0]:.2f}-{ratios[-1]:.2f}) '
          f'| {after / before:.2f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
