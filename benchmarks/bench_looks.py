"""
Error control under repeated looks: the live decision against the fixed-sample one.

Runs (or resumes) studies/looks.yaml into out/studies/looks (one row per null data set in
rows.csv, written as it finishes) on a local process pool, then prints README's table: for
each decision rule, the share of data sets in which the question's term was named at some
look, with a 95 % Wilson interval, and the same for each of its two criteria alone
(octoroach_model/studies/looks.py says how).

Run: .venv/bin/python benchmarks/bench_looks.py [--workers N] [--replicates R] [--report-only]
     [--spec studies/looks.yaml] [--out out/studies/looks]
Hours on two cores (about 40 s per data set of 1000 runs); a stopped run resumes.
"""
from __future__ import annotations

import argparse
from concurrent.futures import as_completed
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from octoroach_model.workers import executor_for
    from octoroach_model.studies.looks import (
        append_row, load_looks, looks_task, read_rows, summarize, table_text)

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--spec', type=Path, default=REPO / 'studies' / 'looks.yaml')
    parser.add_argument('--out', type=Path, default=REPO / 'out' / 'studies' / 'looks')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--replicates', type=int, default=None,
                        help='run only the first R replicates of the spec')
    parser.add_argument('--report-only', action='store_true')
    args = parser.parse_args(argv)
    spec = load_looks(args.spec)
    args.out.mkdir(parents=True, exist_ok=True)
    rows_path = args.out / 'rows.csv'
    rows = read_rows(rows_path)
    done = {row.replicate for row in rows}
    wanted = range(min(args.replicates or spec.study.replicates, spec.study.replicates))
    todo = [replicate for replicate in wanted if replicate not in done]
    if todo and not args.report_only:
        started = time.perf_counter()
        with executor_for(None, args.workers) as pool:
            futures = [pool.submit(looks_task, spec, replicate) for replicate in todo]
            for number, future in enumerate(as_completed(futures), 1):
                row = future.result()
                append_row(rows_path, row)
                rows.append(row)
                print(f'[looks {time.perf_counter() - started:7.0f}s] {number}/{len(todo)} '
                      f'{row.key}: {row.status} {row.note} ({row.elapsed_s:.0f} s)',
                      file=sys.stderr, flush=True)
    rows = [row for row in rows if row.replicate in set(wanted)]
    print(table_text(spec, summarize(spec, rows)))
    errors = [row for row in rows if not row.ok]
    if errors:
        print(f'\n{len(errors)} data sets failed, e.g. {errors[0].key}: {errors[0].note}')
    cpu = sum(row.elapsed_s for row in rows)
    print(f'\n{len(rows)} data sets, {cpu / 60:.0f} worker-minutes '
          f'(median {sorted(row.elapsed_s for row in rows)[len(rows) // 2]:.0f} s each)'
          if rows else '\nno data sets yet')
    return 0


if __name__ == '__main__':
    sys.exit(main())
