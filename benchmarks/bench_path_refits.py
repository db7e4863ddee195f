"""
Could a screen spare the refits of the table's path causes? What the suite's diagnoses say.

Runs the three files of tests that hide effects in data (bench_suite.HIDDEN_EFFECT_FILES) on
this checkout at each suite seed, with the plugin `suite_path_refits.py` recording every refit
of lateral_slip or speed_decay new to a race's model: the signature's size at each start of the
refit, the refit's size and whether its bound cleared the floor, and which start's end it kept.
Then prints, per cause, how many refits a screen of the families' kind (a size bound out of
reach of the floor even ALLOWANCE standard errors up: `diagnose.SCREEN_ALLOWANCE`) would have
stopped and their seconds, read off the current geometry's start alone or stopped only where
every start is out of reach, and how many of those stopped had cleared the floor after their
refit (a screen that stops one of them can change a decision); and how often each start's end
was kept. docs/diagnosis.md section 11 quotes it.

Run: .venv/bin/python benchmarks/bench_path_refits.py [--seed N ...] [--allowance Z]
About four minutes a seed on two cores.
"""
from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
import sys
import tempfile
from typing import Any

from bench_decisions import FILES
from suite_path_refits import VARIABLE
from suite_records import read_lines, run_tests

REPO = Path(__file__).resolve().parents[1]
START_NAMES = ('current geometry', 'equal angles', "Table II's angles")


def out_of_reach(cause: str, size_se: list[float], floor: float, z: float) -> bool:
    """Apply the screen's rule (`diagnose.out_of_reach`) to a [size, standard error]."""
    from octoroach_model.diagnosis.diagnose import out_of_reach as rule
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    return rule(SizeEstimate(cause, *size_se), floor, z)


def summary(rows: list[dict[str, Any]], allowance: float) -> list[str]:
    """Return the printed table's lines for the recorded refits."""
    lines = ['| cause | refits | seconds | cleared the floor | screen on the current start: '
             'stopped (s), of them cleared | screen on every start: stopped (s), of them '
             'cleared |', '| --- | --- | --- | --- | --- | --- |']
    for cause in sorted({row['cause'] for row in rows}):
        mine = [row for row in rows if row['cause'] == cause]
        cells = [cause, str(len(mine)), f'{sum(row["seconds"] for row in mine):.0f}',
                 str(sum(row['cleared'] for row in mine))]
        for rule in (lambda row, z: out_of_reach(row['cause'], row['starts'][0], row['floor'], z),
                     lambda row, z: all(out_of_reach(row['cause'], start, row['floor'], z)
                                        for start in row['starts'])):
            stopped = [row for row in mine if rule(row, row['z'] - allowance)]
            cells.append(f'{len(stopped)} ({sum(row["seconds"] for row in stopped):.0f} s), '
                         f'{sum(row["cleared"] for row in stopped)}')
        lines.append('| ' + ' | '.join(cells) + ' |')
    kept = Counter(index for row in rows for index in row['kept'])
    lines.append('')
    lines.append('ends kept, by start: ' + ', '.join(
        f'{START_NAMES[index] if index < len(START_NAMES) else index} {count}'
        for index, count in sorted(kept.items())))
    return lines


def main(argv: list[str] | None = None) -> int:
    from octoroach_model.diagnosis.diagnose import SCREEN_ALLOWANCE

    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seed', type=int, nargs='+', default=[31337, 90210])
    parser.add_argument('--allowance', type=float, default=SCREEN_ALLOWANCE)
    arguments = parser.parse_args(argv)
    rows: list[dict[str, Any]] = []
    try:
        with tempfile.TemporaryDirectory(prefix='bench-path-refits-') as scratch:
            for seed in arguments.seed:
                print(f'seed {seed}: running the tests ...', file=sys.stderr, flush=True)
                folder = Path(scratch) / f'seed-{seed}'
                outcome, wall = run_tests(REPO, seed, list(FILES), folder,
                                          'suite_path_refits', VARIABLE)
                print(f'seed {seed}: {outcome}; {wall:.0f} s wall', file=sys.stderr)
                rows += read_lines(folder)
    except KeyboardInterrupt:
        print('interrupted: nothing kept (the records were temporary)', file=sys.stderr)
        return 130
    if not rows:
        print('error: the tests weighed no path cause of the table; nothing to show',
              file=sys.stderr)
        return 1
    print(f'suite seeds {", ".join(map(str, arguments.seed))}; screens at '
          f'{arguments.allowance:g} standard errors up')
    print('\n'.join(summary(rows, arguments.allowance)))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
