"""
A term's detection limit on a study's null data sets, as each of several commits reports it.

When a study run again reports another median limit for a term, this says which commit moved
it: each commit's files are copied out (`revisions.export`), and in a process of its own each
commit's study code rebuilds the spec's null data sets (replicates 0 to N-1, the robot and seed
the study draws) and diagnoses them as the study does (`studies.replicate.run_task`: every
limit, the spec's settings). Printed: per commit, each replicate's limit and their median.
The spec is read from each commit's own folder, so a commit that changed the spec is measured
on its own spec.

Why it is here: open_world's change_point limit fell from 0.0335 (commit f0a79fc) to 0.0257
(e0fb040), a fall the run that found it did not trace (docs/measured.md, "Beyond the table").

Run: .venv/bin/python benchmarks/bench_limit_history.py COMMIT [COMMIT ...]
     [--spec studies/open_world.yaml] [--term change_point] [--replicates 4]
(a null data set of 500 runs takes 15-90 s of one core at these commits.)
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile

from revisions import commit_of, export

REPO = Path(__file__).resolve().parents[1]

# run inside a commit's folder: print one line per null data set, 'REPLICATE LIMIT'
MEASURE = """
import sys
from pathlib import Path
from octoroach_model.studies.design import build_tasks
from octoroach_model.studies.replicate import run_task
from octoroach_model.studies.spec import load_spec

spec = load_spec(Path(sys.argv[1]))
term, replicates = sys.argv[2], int(sys.argv[3])
for task in build_tasks(spec):
    if task.arm.kind.value == 'null' and task.replicate < replicates:
        row = run_task(task, spec)
        print(task.replicate, row.status, row.terms[term].limit, flush=True)
"""


def limits_at(commit: str, spec: str, term: str, replicates: int, scratch: Path
              ) -> list[float]:
    """Return the term's limit on each null data set as `commit` reports it."""
    tree = export(commit, scratch / commit[:12])
    env = {**os.environ, 'PYTHONPATH': str(tree)}
    finished = subprocess.run([sys.executable, '-c', MEASURE, str(tree / spec), term,
                               str(replicates)], cwd=tree, env=env, capture_output=True,
                              text=True)
    if finished.returncode != 0:
        last = (finished.stderr.strip().splitlines() or ['no message'])[-1]
        raise SystemExit(f'error: commit {commit[:12]} could not measure: {last}')
    limits = []
    for line in finished.stdout.splitlines():
        replicate, status, limit = line.split()
        if not status.lower().endswith('ok'):
            raise SystemExit(f'error: commit {commit[:12]}: replicate {replicate} {status}')
        limits.append(float(limit))
    return limits


def main(argv: list[str] | None = None) -> int:
    """Measure and print the limits at each commit given, in the order given."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('commits', nargs='+', help='commits to measure (hash, tag, HEAD~3)')
    parser.add_argument('--spec', default='studies/open_world.yaml',
                        help='the study spec, a path inside the repository')
    parser.add_argument('--term', default='change_point')
    parser.add_argument('--replicates', type=int, default=4)
    arguments = parser.parse_args(argv)
    if arguments.replicates < 1:
        parser.error('--replicates must be at least 1')
    spec = Path(arguments.spec)
    if spec.is_absolute() or '..' in spec.parts:      # read inside each commit's copy only
        parser.error('--spec is a path inside the repository, such as studies/open_world.yaml')
    from octoroach_model.limit_setting import RACED_TERMS

    if arguments.term not in RACED_TERMS:
        parser.error(f'--term must be one of {", ".join(RACED_TERMS)}')
    commits = [commit_of(revision) for revision in arguments.commits]
    print(f'{arguments.term} limits on the nulls of {arguments.spec}, replicates 0-'
          f'{arguments.replicates - 1}\n')
    print('| commit | limits, replicate by replicate | median |')
    print('| --- | --- | --- |')
    with tempfile.TemporaryDirectory(prefix='bench-limit-history-') as scratch:
        for commit in commits:
            limits = limits_at(commit, arguments.spec, arguments.term, arguments.replicates,
                               Path(scratch))
            print(f'| {commit[:7]} | {", ".join(f"{limit:.4g}" for limit in limits)} | '
                  f'{statistics.median(limits):.4g} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
