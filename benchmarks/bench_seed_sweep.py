"""
One test that hides an effect in data, drawn at many suite seeds: what each draw decided.

A test that hides an effect draws its case from the suite seed, so a single run says little
of how often the diagnosis finds that kind of case; its docstring's counts ("suite seeds
1-16: 15 named, 1 flagged") are a sweep over seeds. This runs the test (a file and a pytest
-k expression that picks one test in it) once per
suite seed, with the plugin `suite_decisions.py` recording every diagnosis it ran, and prints
per seed the pytest outcome, the terms named and whether the model was adequate; then how
many seeds reached each decision. With `--base REV` the same seeds run on a copy of that
commit too (`git archive`, in a temporary folder), beside this tree.

Run: .venv/bin/python benchmarks/bench_seed_sweep.py FILE -k EXPRESSION [--seeds 1-16]
     [--base REV] [--workers 2]
e.g. test/test_extensions.py -k turn_that_grows_within_each_run (16 seeds, about 3 minutes
on the two cores; twice that with --base).
"""
from __future__ import annotations

import argparse
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import sys
import tempfile
from typing import Any

from revisions import commit_of, export
from suite_decisions import FOLDER_VARIABLE
from suite_records import read_lines, run_tests

REPO = Path(__file__).resolve().parents[1]


def seeds_of(text: str) -> list[int]:
    """Return the seeds of '1-16' or '3,7,11' (or both: '1-4,9')."""
    seeds: list[int] = []
    for part in text.split(','):
        low, _, high = part.partition('-')
        try:
            seeds.extend(range(int(low), int(high or low) + 1))
        except ValueError:
            raise SystemExit(f'error: --seeds {text!r}: give seeds as 1-16 or 3,7,11') from None
    if not seeds:
        raise SystemExit('error: --seeds names no seed')
    return seeds


def run_at(tree: Path, test: list[str], seed: int, folder: Path
           ) -> tuple[str, list[dict[str, Any]]]:
    """Run `test` (pytest's arguments) in `tree` at suite seed `seed`; outcome, diagnoses."""
    outcome, _ = run_tests(tree, seed, test, folder, 'suite_decisions', FOLDER_VARIABLE,
                           workers=('-p', 'no:xdist'))
    return outcome.split(' in ')[0], read_lines(folder)


def decision(records: list[dict[str, Any]]) -> str:
    """Say in a few words what the diagnoses decided: terms named, adequate or not."""
    if not records:
        return 'no diagnosis recorded'
    words = []
    for record in records:
        named = sorted(record['causes']) + sorted(record['extensions'])
        words.append(f'{", ".join(named) or "nothing"} named, '
                     f'{"adequate" if record["adequate"] else "not adequate"}')
    return '; '.join(words)


def sweep(tree: Path, test: list[str], seeds: list[int], scratch: Path, workers: int,
          label: str) -> dict[int, tuple[str, str]]:
    """Run every seed (`workers` at a time); {seed: (outcome, decision)}."""
    def one(seed: int) -> tuple[int, tuple[str, str]]:
        outcome, records = run_at(tree, test, seed, scratch / f'{label}-{seed}')
        print(f'{label} seed {seed}: {outcome}: {decision(records)}', file=sys.stderr,
              flush=True)
        return seed, (outcome, decision(records))
    with ThreadPoolExecutor(workers) as pool:
        return dict(pool.map(one, seeds))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('file', help='a test file, e.g. test/test_extensions.py')
    parser.add_argument('-k', dest='expression', required=True,
                        help="pytest's -k expression picking one test of the file")
    parser.add_argument('--seeds', default='1-16', help='suite seeds: 1-16, or 3,7,11')
    parser.add_argument('--base', default=None, help='a commit to run beside this tree')
    parser.add_argument('--workers', type=int, default=2, help='tests run at once')
    arguments = parser.parse_args(argv)
    seeds = seeds_of(arguments.seeds)
    if not (REPO / arguments.file).is_file():
        raise SystemExit(f'error: {arguments.file!r} is no test file here')
    test = [arguments.file, '-k', arguments.expression]
    base = commit_of(arguments.base) if arguments.base else None
    try:
        with tempfile.TemporaryDirectory(prefix='bench-seed-sweep-') as scratch:
            trees = [('this tree', REPO)]
            if base:
                trees.insert(0, (f'base {base[:7]}', export(base, Path(scratch) / 'base')))
            results = {label: sweep(tree, test, seeds, Path(scratch),
                                    max(arguments.workers, 1), label.split()[0])
                       for label, tree in trees}
    except KeyboardInterrupt:
        print('interrupted: nothing kept (the copies and records were temporary)',
              file=sys.stderr)
        return 130
    print(f'{arguments.file} -k {arguments.expression!r} at suite seeds {arguments.seeds}')
    print('| seed | ' + ' | '.join(results) + ' |')
    print('| --- |' + ' --- |' * len(results))
    for seed in seeds:
        print(f'| {seed} | ' + ' | '.join(f'{found[seed][0]}: {found[seed][1]}'
                                          for found in results.values()) + ' |')
    for label, found in results.items():
        tally = Counter(outcome_decision[1] for outcome_decision in found.values())
        failed = sum('failed' in outcome or 'error' in outcome for outcome, _ in found.values())
        print(f'{label}: ' + '; '.join(f'{count} x {what}' for what, count in tally.most_common())
              + f'; {failed} of {len(seeds)} seeds failed')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
