"""
How far the diagnosis's own simulations move the two criteria of a decision near its threshold.

A term is named when its held-out test passes (t = gain / its standard error above the step's
critical t) and its size bound clears its floor. Both are computed from the runs and from
simulated runs. On the same runs, with the halves kept (`split_seed`) and only the simulations
drawn again (the seed moved), this prints each criterion at the first step of the race, draw
by draw, and its spread over the draws: the simulations' share of the criterion. The t is in
units of its own standard error over held-out runs (unit spread over data sets), so a spread
of 0.5 over draws means the simulations add a quarter to the variance the test counts; the
bound's margin, (lower bound - floor) / standard error, likewise. This is the number a mend
of the decision rule needs (docs/diagnosis.md, section 5, "The same runs, another seed").

Data: the reference robot (Table II, Table III's spreads, `om.simulate`'s defaults) with the
term at `--size` (its family's parameter; run_mixture: the yaw rate of `--fraction` of the
runs), one data set per `--data-seeds` entry. The sizes by default are the detection limits
a diagnosis of bags/ (the same robot, 500 runs) reports: run_mixture 4.75 deg/s, heading
random walk 1.23 deg. One robot only: it measures the simulations' share on it, not over
the robot space.

Run: .venv/bin/python benchmarks/bench_draw_margins.py [--family run_mixture] [--size 4.75]
     [--data-seeds 1 2 3] [--draws 4] [--runs 500] [--seed 0] [--workers 2]
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time
from typing import Any, NamedTuple

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

DEFAULT_SIZES = {'run_mixture': 4.75, 'heading_random_walk': 1.23}
PARAMETERS = {'run_mixture': 'yaw_rate_deg_s', 'heading_random_walk': 'step_std_deg'}


class Criteria(NamedTuple):
    """One draw's decision on one data set, and the term's two criteria at the race's step 1."""

    data_seed: int
    draw: int
    named: tuple[str, ...]
    t: float
    t_critical: float
    bound_margin: float        # (lower bound - floor) / standard error; clears above z
    bound_z: float             # the step's decision z the bound is taken at
    cpu_s: float


def diagnosed(family: str, size: float, fraction: float, runs: int, data_seed: int, seed: int,
              draw: int) -> Criteria:
    """Simulate the data set, diagnose it at draw `draw` (halves of `seed`), read the criteria."""
    from scipy import stats

    import octoroach_model as om
    from octoroach_model.diagnosis import diagnose, DiagnosisSettings

    values: dict[str, Any] = {PARAMETERS[family]: size}
    if family == 'run_mixture':
        values['fraction'] = fraction
    measured = om.simulate(runs, seed=data_seed, extensions={family: values})
    started = time.process_time()
    report = diagnose(measured, DiagnosisSettings(
        seed=seed + draw, split_seed=seed, workers=1, detection_limits=False,
        validate_models=False))
    first = report.steps[0]
    entry = next(c for c in first.candidates if c.cause == family)
    held_out = report.split['held_out']
    t = entry.gain / entry.gain_se if entry.gain_se > 0 else math.nan
    t_critical = float(stats.t.isf(first.test_level, held_out - 1))
    margin = ((entry.lower_bound - entry.floor) / entry.standard_error
              if entry.standard_error > 0 else math.nan)
    named = (tuple(c.cause for c in report.causes)
             + tuple(e.term for e in report.extensions))
    return Criteria(data_seed, draw, named, t, t_critical, margin, first.decision_z,
                    time.process_time() - started)


def main() -> int:
    """Diagnose each data set at each draw, side by side, and print the criteria's spread."""
    from concurrent.futures import as_completed

    import numpy as np

    from octoroach_model.workers import process_pool

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--family', choices=sorted(PARAMETERS), default='run_mixture')
    parser.add_argument('--size', type=float, help='default: the reference limit (docstring)')
    parser.add_argument('--fraction', type=float, default=0.3,
                        help="run_mixture's share of turning runs (default 0.3)")
    parser.add_argument('--data-seeds', type=int, nargs='+', default=[1, 2, 3])
    parser.add_argument('--draws', type=int, default=4)
    parser.add_argument('--runs', type=int, default=500)
    parser.add_argument('--seed', type=int, default=0, help='the seed of the halves')
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args()
    size = DEFAULT_SIZES[args.family] if args.size is None else args.size
    jobs = [(data_seed, draw) for data_seed in args.data_seeds for draw in range(args.draws)]
    print(f'{args.family} at {size:g} ({PARAMETERS[args.family]}), {args.runs} runs: '
          f'{len(args.data_seeds)} data sets x {args.draws} draws = {len(jobs)} diagnoses, '
          f'{args.workers} processes', flush=True)
    found: list[Criteria] = []
    with process_pool(args.workers, command=True) as pool:
        futures = [pool.submit(diagnosed, args.family, size, args.fraction, args.runs,
                               data_seed, args.seed, draw) for data_seed, draw in jobs]
        for done, future in enumerate(as_completed(futures), 1):
            row = future.result()
            found.append(row)
            print(f'[{done}/{len(jobs)}] data {row.data_seed} draw {row.draw}: '
                  f'{", ".join(row.named) or "nothing"}; t {row.t:.2f} (critical '
                  f'{row.t_critical:.2f}), bound margin {row.bound_margin:.2f} (needs '
                  f'{row.bound_z:.2f}) ({row.cpu_s:.0f} s)', flush=True)
    print('\n| data seed | named the same at every draw | t over draws | its SD | '
          'bound margin over draws | its SD |')
    print('| --- | --- | --- | --- | --- | --- |')
    t_sd, margin_sd = [], []
    for data_seed in args.data_seeds:
        rows = sorted((row for row in found if row.data_seed == data_seed),
                      key=lambda row: row.draw)
        ts = np.array([row.t for row in rows])
        margins = np.array([row.bound_margin for row in rows])
        t_sd.append(float(np.std(ts, ddof=1)))
        margin_sd.append(float(np.std(margins, ddof=1)))
        same = len({frozenset(row.named) for row in rows}) == 1
        print(f'| {data_seed} | {"yes" if same else "no"} | '
              f'{" ".join(f"{value:.2f}" for value in ts)} | {t_sd[-1]:.2f} | '
              f'{" ".join(f"{value:.2f}" for value in margins)} | {margin_sd[-1]:.2f} |')
    pooled_t = math.sqrt(float(np.mean(np.square(t_sd))))
    pooled_margin = math.sqrt(float(np.mean(np.square(margin_sd))))
    cpu_s = sum(row.cpu_s for row in found)
    print(f'\npooled SD over draws, same runs: t {pooled_t:.2f}, bound margin '
          f"{pooled_margin:.2f} (the data's own: 1 each); CPU {cpu_s:.0f} s")
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
