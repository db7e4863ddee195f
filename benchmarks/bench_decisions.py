"""
The suite's hidden-effect cases diagnosed by another commit and by this tree: decisions and time.

A change meant to make the diagnosis faster must not change what it decides. This runs the
tests that hide effects in data (test_diagnosis.py, test_extensions.py, test_redraws.py, or
the files given) twice at each suite seed given: once on a copy of commit `--base` (`git
archive`, in a temporary folder) and once on this working tree, one after the other on the
same machine, with the pytest plugin `suite_decisions.py` recording every diagnosis a test
runs. Both draw the same hidden cases where the tests that draw them are the same. Printed
per test: each tree's diagnosis seconds, whether every diagnosis named the same terms and
reached the same adequacy, and the largest change of a named value relative to itself; then
the totals, each tree's pytest outcome and its wall time.

Why it is here: issue 26 asks for a faster diagnosis "with identical decisions on the suite's
hidden cases"; this is that check as a command, for any speed change.

Run: .venv/bin/python benchmarks/bench_decisions.py --base REV [--seed N ...] [--files F ...]
(about twice the hidden-effect files' time per seed: 8 minutes on the two cores).
"""
from __future__ import annotations

import argparse
from collections import defaultdict
import math
from pathlib import Path
import subprocess
import sys
import tempfile
from typing import Any

from bench_suite import HIDDEN_EFFECT_FILES
from revisions import commit_of, export
from suite_decisions import FOLDER_VARIABLE
from suite_records import read_lines, run_tests

REPO = Path(__file__).resolve().parents[1]
FILES = tuple(f'test/{name}' for name in HIDDEN_EFFECT_FILES)


def records(folder: Path) -> dict[str, list[dict[str, Any]]]:
    """Return each test's diagnoses, in the order its process ran them."""
    by_test: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for record in read_lines(folder):
        by_test[record['test']].append(record)
    return by_test


def largest_change(before: dict[str, Any], after: dict[str, Any]) -> tuple[float, str]:
    """Largest |after - before| / |before| over the named values both have, and its name."""
    largest = (0.0, '')
    for table in ('causes', 'extensions'):
        for term, values in before[table].items():
            for name, value in values.items():
                other = after[table].get(term, {}).get(name)
                if _number(value) and _number(other):
                    change = abs(other - value) / max(abs(value), 1e-12)
                    if change > largest[0]:
                        largest = (change, f'{term} {name} {value:.4g} -> {other:.4g}')
    return largest


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def same_decision(before: dict[str, Any], after: dict[str, Any]) -> bool:
    return (set(before['causes']) == set(after['causes'])
            and set(before['extensions']) == set(after['extensions'])
            and before['adequate'] == after['adequate'])


def compare(base: dict[str, list[dict]], head: dict[str, list[dict]]) -> list[dict[str, str]]:
    rows = []
    for test in sorted(set(base) | set(head)):
        before, after = base.get(test, []), head.get(test, [])
        row = {'test': test.split('::', 1)[-1][:90],
               'base s': f'{sum(r["seconds"] for r in before):.1f}' if before else '-',
               'this tree s': f'{sum(r["seconds"] for r in after):.1f}' if after else '-'}
        if len(before) == len(after) and before:
            same = all(same_decision(b, a) for b, a in zip(before, after))
            change, which = max(largest_change(b, a) for b, a in zip(before, after))
            row['same decisions'] = f'{"yes" if same else "NO"} ({len(before)})'
            row['largest value change'] = f'{change:.1e}' + (f' ({which})' if which else '')
        else:
            row['same decisions'] = f'not compared ({len(before)} and {len(after)} diagnoses)'
            row['largest value change'] = '-'
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--base', required=True, help='the commit to compare with')
    parser.add_argument('--seed', type=int, nargs='+', default=[4242])
    parser.add_argument('--files', nargs='+', default=list(FILES))
    arguments = parser.parse_args(argv)
    base = commit_of(arguments.base)
    try:
        with tempfile.TemporaryDirectory(prefix='bench-decisions-') as scratch:
            base_tree = export(base, Path(scratch) / 'base_tree')
            for seed in arguments.seed:
                if not compared_at(seed, base, base_tree, arguments.files, Path(scratch)):
                    return 1
    except KeyboardInterrupt:
        print('interrupted: nothing kept (the copies and records were temporary)',
              file=sys.stderr)
        return 130
    return 0


def compared_at(seed: int, base: str, base_tree: Path, files: list[str], scratch: Path
                ) -> bool:
    """Run both trees at `seed` and print the comparison; False where nothing was recorded."""
    outcomes = {}
    for name, tree, folder in (('base', base_tree, 'base'), ('this tree', REPO, 'head')):
        print(f'seed {seed}: running the tests of {name} ...', file=sys.stderr, flush=True)
        outcomes[name] = run_tests(tree, seed, files, scratch / f'{folder}-{seed}',
                                   'suite_decisions', FOLDER_VARIABLE)
    before, after = records(scratch / f'base-{seed}'), records(scratch / f'head-{seed}')
    rows = compare(before, after)
    if not rows:
        print(f'error: seed {seed}: no diagnosis recorded (base: {outcomes["base"][0]}; this '
              f'tree: {outcomes["this tree"][0]})', file=sys.stderr)
        return False
    print(f'\nsuite seed {seed}: base {base[:7]}, this tree {_described()}')
    print('| ' + ' | '.join(rows[0]) + ' |')
    print('|' + ' --- |' * len(rows[0]))
    for row in rows:
        print('| ' + ' | '.join(row.values()) + ' |')
    compared = [row for row in rows if row['same decisions'].startswith(('yes', 'NO'))]
    differing = [row['test'] for row in compared if row['same decisions'].startswith('NO')]
    total = {key: sum(r['seconds'] for found in found_by.values() for r in found)
             for key, found_by in (('base', before), ('head', after))}
    ratio = total['head'] / total['base'] if total['base'] else math.nan
    print(f'diagnoses: base {total["base"]:.0f} s, this tree {total["head"]:.0f} s '
          f'({ratio:.2f} of base); tests compared {len(compared)}, with a different '
          f'decision {len(differing)}{": " + ", ".join(differing) if differing else ""}')
    for name, (outcome, wall) in outcomes.items():
        print(f'{name}: {outcome}; {wall:.0f} s wall')
    return True


def _described() -> str:
    found = subprocess.run(['git', 'describe', '--always', '--dirty'], cwd=REPO,
                           capture_output=True, text=True)
    return found.stdout.strip() or 'unknown'


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
