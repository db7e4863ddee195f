"""
Do a named term's 95 % intervals hold its size? One robot of a study, its runs drawn again.

A study's limit multiples share their replicate's data seed (common random numbers: the 1x
and 2x data sets of a robot carry the same runs' noise, only the term's size differs), so a
robot whose interval misses at 1x misses alike at 2x: the table's intervals are about half
as many independent checks as rows. This benchmark draws the runs of one replicate's robot
anew N times (data seeds offset 1..N), puts the term in at the size asked, diagnoses each
data set with the study's settings, and prints per draw the estimate and its interval, then
how many intervals held the truth (with a Clopper-Pearson interval) and the spread of the
standardised errors (estimate - truth) / reported standard error: near 1 where the reported
errors are right; a mean far from 0 is a bias the interval does not count.

Why: studies/ramp_limits.yaml's intervals held the truth in 13 of 17 rows, two robots
(replicates 7 and 9) off by the same amount at both multiples (README, "What the diagnosis
can find"); whether their errors are too small or those were two unlucky draws was open.

With `--tables`, it reads studies' tables instead (out/studies/*/table.csv) and prints, per
study and term, how many named terms' intervals held the truth and the mean and spread of their
standardised errors, then all of them together (rows of one replicate share its runs' noise:
the count of independent checks is nearer the robots' than the rows').

Run: .venv/bin/python benchmarks/bench_interval_coverage.py studies/ramp_limits.yaml
         --replicate 7 --term yaw_rate_ramp --size 3.0473 --draws 12
     .venv/bin/python benchmarks/bench_interval_coverage.py --tables out/studies/*/table.csv
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
from pathlib import Path
import sys
import time

import numpy as np
from scipy import stats


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('spec', type=Path, nargs='?',
                        help='the study spec file the robot is drawn from')
    parser.add_argument('--replicate', type=int, help="the replicate's robot")
    parser.add_argument('--term', help='cause or extension put into the runs')
    parser.add_argument('--size', type=float,
                        help="the term's signed size (its main parameter's distance from none)")
    parser.add_argument('--draws', type=int, default=12, help='data sets drawn (default 12)')
    parser.add_argument('--runs', type=int, default=None,
                        help="runs per data set (default: the spec's first run count)")
    parser.add_argument('--tables', type=Path, nargs='+',
                        help="studies' table.csv files to read instead of drawing runs")
    args = parser.parse_args(argv)
    if args.tables:
        return from_tables(args.tables)
    if None in (args.spec, args.replicate, args.term, args.size):
        parser.error('give a spec, --replicate, --term and --size (or --tables)')

    from octoroach_model.diagnosis import diagnose
    from octoroach_model.studies.design import draw_robot
    from octoroach_model.studies.replicate import read_report, simulate_data
    from octoroach_model.studies.spec import load_spec
    from octoroach_model.studies.terms import term_values

    spec = load_spec(args.spec)
    robot = draw_robot(spec, args.replicate)
    runs = args.runs or spec.runs[0]
    effects = {args.term: term_values(args.term, args.size, {}, robot.duration_s)}
    print(f'# {spec.name} replicate {args.replicate}: {args.term} {args.size:+g}, {runs} runs, '
          f'{args.draws} draws of the runs (data seeds {robot.data_seed}+1..{args.draws})')
    print('| draw | named | estimate | 95 % interval | held | z |')
    print('| --- | --- | --- | --- | --- | --- |')
    held, z_values = 0, []
    started = time.perf_counter()
    for draw in range(1, args.draws + 1):
        seed = robot.data_seed + draw
        again = replace(robot, data_seed=seed)
        measured = simulate_data(spec, again, runs, effects).paths
        settings = replace(spec.diagnosis_settings(seed), detection_limits=False)
        _, terms = read_report(diagnose(measured, settings), effects)
        outcome = terms[args.term]
        covered = bool(outcome.low <= args.size <= outcome.high)
        z = (outcome.estimate - args.size) / ((outcome.high - outcome.low) / (2 * 1.959964))
        if outcome.named:
            held += covered
            z_values.append(z)
        print(f'| {draw} | {"yes" if outcome.named else "no"} | {outcome.estimate:.3f} | '
              f'{outcome.low:.3f} to {outcome.high:.3f} | {"yes" if covered else "no"} | '
              f'{z:+.2f} |', flush=True)
    named = len(z_values)
    print(f'\nnamed {named} of {args.draws}; intervals held the truth in {held} of {named}',
          end='')
    if named:
        low, high = stats.binomtest(held, named).proportion_ci(0.95, method='exact')
        z = np.array(z_values)
        spread = z.std(ddof=1) if named > 1 else math.nan
        print(f' ({100 * held / named:.0f} %, 95 % CI {100 * low:.0f}-{100 * high:.0f} %); '
              f'standardised errors: mean {z.mean():+.2f}, sd {spread:.2f} '
              f'(1 where the reported errors are right)')
    else:
        print()
    print(f'{time.perf_counter() - started:.0f} s')
    return 0


def from_tables(paths: list[Path]) -> int:
    """Print the named terms' interval coverage and standardised errors in study tables."""
    import csv

    pooled: list[float] = []
    print('| study | term | named | intervals that held | mean z | sd z | largest abs z |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    for path in paths:
        with open(path, newline='') as stream:
            rows = list(csv.DictReader(stream))
        by_term: dict[str, list[float]] = {}
        for row in rows:
            for column, value in row.items():
                if not column.startswith('named_') or value not in ('True', 'true', '1'):
                    continue
                term = column[len('named_'):]
                try:
                    truth, estimate, low, high = (float(row[prefix + term]) for prefix in (
                        'true_', 'estimate_', 'low_', 'high_'))
                except (KeyError, ValueError):
                    continue
                if math.isfinite(truth) and math.isfinite(low) and high > low:
                    by_term.setdefault(term, []).append(
                        (estimate - truth) / ((high - low) / (2 * 1.959964)))
        for term, values in by_term.items():
            z = np.array(values)
            pooled += values
            print(f'| {path.parent.name} | {term} | {len(z)} | '
                  f'{int(np.sum(np.abs(z) <= 1.959964))} | {z.mean():+.2f} | '
                  f'{z.std(ddof=1) if len(z) > 1 else math.nan:.2f} | {np.abs(z).max():.1f} |')
    z = np.array(pooled)
    if len(z):
        held = int(np.sum(np.abs(z) <= 1.959964))
        print(f'\nall: {held} of {len(z)} intervals held the truth ({100 * held / len(z):.1f} %); '
              f'standardised errors mean {z.mean():+.2f}, sd {z.std(ddof=1):.2f}; 95th '
              f'percentile of |z| {np.quantile(np.abs(z), 0.95):.2f} (1.96 where the intervals '
              f'are right)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
