"""
A study's data sets diagnosed again with the code at hand: which decisions changed.

A change to the diagnosis is checked against the rows a study already has: each data set is
simulated again from the study's spec (the same robot, seed and effects; a limit's size read
off the table's null row of its replicate, as the study did) and diagnosed with the current
code, and its row is compared with the table's. Printed: every row whose decisions changed
(named terms, adequacy, false causes, unexplained statistics, status), and over all rows the
largest change of the size of the term hidden in a data set and of any fitted size. The rows
are written to `--out` (a table of the study's format) as they finish, so an interrupted run
keeps them.

docs/diagnosis.md section 3 quotes it on the partial limits rerun at commit 38647f2:
    .venv/bin/python benchmarks/bench_rediagnose.py --spec studies/limits.yaml \
        --table out/studies/limits_38647f2/table.csv --out /tmp/rediagnosed.csv
(105 data sets, about an hour on the two cores; `--keys` picks some.) Whether the new rows'
intervals hold the truth (and the old table's): `bench_interval_coverage.py --tables OUT`.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

DECISIONS = ('status', 'named', 'adequate', 'false_causes', 'unexplained', 'undecided')


def rediagnose(spec_path: str, key: str, null_row):
    """Diagnose the task `key` of the spec again; return its row (a worker's job)."""
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(Path(spec_path))
    task = next(task for task in build_tasks(spec) if task.key == key)
    return study.run_task(task, spec, null_row)


def compare(old, new) -> tuple[list[str], list[tuple[float, str, bool]]]:
    """
    Return the decisions that differ (column: before -> after) and every size's change.

    A size's change comes with its row and term, and whether the term is the one hidden in
    the data set (its arm's).
    """
    from octoroach_model.studies.table import COLUMN_NAMES, row_cells

    before = dict(zip(COLUMN_NAMES, row_cells(old)))
    after = dict(zip(COLUMN_NAMES, row_cells(new)))
    changed = [f'{name}: {before[name] or "-"} -> {after[name] or "-"}'
               for name in COLUMN_NAMES
               if (name in DECISIONS or name.startswith('named_')) and before[name] != after[name]]
    hidden = old.arm.split('@')[0]
    moved = [(abs(float(after[name]) - float(before[name])),
              f'{old.key} {name[len("estimate_"):]}', name[len('estimate_'):] == hidden)
             for name in COLUMN_NAMES
             if name.startswith('estimate_') and before[name] and after[name]]
    return changed, moved


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--spec', required=True, help='the study spec the table was run with')
    parser.add_argument('--table', required=True, type=Path, help="the study's table.csv")
    parser.add_argument('--out', required=True, type=Path,
                        help='a new table for the rows diagnosed again (must not exist)')
    parser.add_argument('--keys', nargs='*', help='task keys to diagnose again (default: '
                        'every row of the table)')
    parser.add_argument('--workers', type=int, default=2, help='local processes (default 2)')
    args = parser.parse_args()
    from octoroach_model.studies.table import append_row, read_table, start_table
    from octoroach_model.workers import process_pool

    if args.out.exists():
        parser.error(f'{args.out} exists: name a new file')
    rows, _ = read_table(args.table)
    nulls = {row.replicate: row for row in rows if row.key.startswith('none/')}
    chosen = [row for row in rows if not args.keys or row.key in args.keys]
    start_table(args.out)
    started, changes, moved = time.perf_counter(), 0, []
    with process_pool(args.workers) as pool:
        futures = {pool.submit(rediagnose, args.spec, row.key, nulls.get(row.replicate)): row
                   for row in chosen}
        for done, future in enumerate(futures, 1):
            old, new = futures[future], future.result()
            append_row(args.out, new)
            changed, sizes = compare(old, new)
            moved += sizes
            changes += bool(changed)
            note = '; '.join(changed) if changed else 'the same decisions'
            print(f'[{done}/{len(chosen)} {time.perf_counter() - started:5.0f} s] {old.key}: '
                  f'{note}', flush=True)
    hidden = [size for size in moved if size[2]]
    print(f'\n{len(chosen)} data sets diagnosed again, {changes} with other decisions')
    if hidden:
        print('largest change of the size of the term hidden in a data set: '
              f'{max(hidden)[0]:.3g} ({max(hidden)[1]})')
    if moved:
        print(f'largest change of any fitted size: {max(moved)[0]:.3g} ({max(moved)[1]})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
