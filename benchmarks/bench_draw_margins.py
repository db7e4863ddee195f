"""
How far the diagnosis's own simulations move the two criteria of a decision near its threshold.

A term is named when its held-out test passes (t = gain / its standard error above the step's
critical t) and its size bound clears its floor. Both are computed from the runs and from
simulated runs. On the same runs, with the halves kept (`split_seed`) and only the simulations
drawn again (the seed moved), this prints the term's criteria at the first step of the race,
draw by draw (a term screened there, neither refit nor scored, has no t; a term can be named
at a later step), and their spread over the draws: the simulations' share. The t is in units
of its own standard error over the held-out runs, which leaves the simulations out, so a
spread of 0.5 over draws means they add a quarter to the variance the test counts; the size
is in units of its reported standard error; the bound's margin is (lower bound - floor) /
standard error. These are the numbers a mend of the decision rule needs (docs/diagnosis.md,
section 5, "The same runs, another seed").

Data: the reference robot (Table II, Table III's spreads, `om.simulate`'s defaults) with the
term at `--size` (its family's parameter; run_mixture: the yaw rate of `--fraction` of the
runs), one data set per `--data-seeds` entry. The default sizes sit near the decision's
threshold on this robot, found by trying: at 4.75 deg/s (the limit a diagnosis of bags/
reports, whose runs carry a start-pose error as well) every draw named the mixture, t 4.3 to
6.4. One robot only: the simulations' share on it, not over the robot space.

Run: .venv/bin/python benchmarks/bench_draw_margins.py [--family run_mixture] [--size 3.9]
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

DEFAULT_SIZES = {'run_mixture': 3.9, 'heading_random_walk': 1.0}
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
    size: float                # the term's fitted size (its family's parameter)
    size_se: float             # its standard error
    screened: bool             # not refit nor scored: its bound or evidence out of reach (t nan)
    cpu_s: float


def diagnosed(family: str, size: float, fraction: float, runs: int, data_seed: int, seed: int,
              draw: int) -> Criteria:
    """Simulate the data set, diagnose it at draw `draw` (halves of `seed`), read the criteria."""
    from scipy import stats

    import octoroach_model as om
    from octoroach_model.diagnosis import diagnose, DiagnosisSettings
    from octoroach_model.diagnosis.diagnose import redraw_settings

    values: dict[str, Any] = {PARAMETERS[family]: size}
    if family == 'run_mixture':
        values['fraction'] = fraction
    measured = om.simulate(runs, seed=data_seed, extensions={family: values})
    started = time.process_time()
    report = diagnose(measured, redraw_settings(DiagnosisSettings(seed=seed), draw))
    first = report.steps[0]
    entry = next(c for c in first.candidates if c.cause == family)
    held_out = report.split['held_out']
    t = entry.gain / entry.gain_se if entry.gain_se > 0 else math.nan
    t_critical = float(stats.t.isf(first.test_level, held_out - 1))
    margin = ((entry.lower_bound - entry.floor) / entry.standard_error
              if entry.standard_error > 0 else math.nan)
    size = entry.parameters[PARAMETERS[family]]
    return Criteria(data_seed, draw, tuple(report.named_terms), t, t_critical, margin,
                    first.decision_z,
                    float(size) if isinstance(size, (int, float)) else math.nan,
                    entry.standard_error, entry.screened, time.process_time() - started)


def _t(row: Criteria) -> str:
    return 'screened' if row.screened else f'{row.t:.2f}'


def _spread(values: Any) -> float:
    """Return the standard deviation of the finite values (nan with fewer than two)."""
    import numpy as np

    finite = values[np.isfinite(values)]
    return float(np.std(finite, ddof=1)) if len(finite) > 1 else math.nan


def _pooled(spreads: list[float]) -> float:
    """Return the root mean square of the finite spreads (data sets weigh alike)."""
    finite = [value for value in spreads if math.isfinite(value)]
    return math.sqrt(sum(value * value for value in finite) / len(finite)) if finite \
        else math.nan


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
                  f'{", ".join(row.named) or "nothing"}; t {_t(row)} (critical '
                  f'{row.t_critical:.2f}), bound margin {row.bound_margin:.2f} (needs '
                  f'{row.bound_z:.2f}) ({row.cpu_s:.0f} s)', flush=True)
    print('\n| data seed | named the same at every draw | t over draws | its SD | '
          'bound margin over draws | its SD | size over draws | its SD / its SE |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- |')
    t_sd, margin_sd, size_sd = [], [], []
    for data_seed in args.data_seeds:
        rows = sorted((row for row in found if row.data_seed == data_seed),
                      key=lambda row: row.draw)
        ts = np.array([row.t for row in rows])
        margins = np.array([row.bound_margin for row in rows])
        sizes = np.array([row.size for row in rows])
        t_sd.append(_spread(ts))
        margin_sd.append(_spread(margins))
        size_sd.append(_spread(sizes) / float(np.mean([row.size_se for row in rows])))
        same = len({frozenset(row.named) for row in rows}) == 1
        print(f'| {data_seed} | {"yes" if same else "no"} | '
              f'{" ".join(_t(row) for row in rows)} | {t_sd[-1]:.2f} | '
              f'{" ".join(f"{value:.2f}" for value in margins)} | {margin_sd[-1]:.2f} | '
              f'{" ".join(f"{value:.3g}" for value in sizes)} | {size_sd[-1]:.2f} |')
    pooled_t, pooled_margin, pooled_size = (_pooled(sds) for sds in (t_sd, margin_sd, size_sd))
    cpu_s = sum(row.cpu_s for row in found)
    print(f'\npooled SD over draws, same runs: t {pooled_t:.2f}, bound margin '
          f"{pooled_margin:.2f}, size {pooled_size:.2f} of its standard error (the data's "
          f'own: 1 each); CPU {cpu_s:.0f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
