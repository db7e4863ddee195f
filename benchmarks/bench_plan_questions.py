"""
Does `plan`'s answer hold on real questions? Its interval against the term's own power curve.

For each question TERM=SIZE (Table II's robot, as `plan` takes it by default): `plan`
(`--method model`, two workers) answers with a run count and a 95 % interval; then the
term's first step is taken as plan's checks take it (`plan_model.check_task`: the term at
the size, the diagnosis's levels) on PER new data sets (replicates from 7000, seeds plan
never uses) at the interval's ends and at the answer, or at the counts given
(TERM=SIZE@N,N,... for one question, `--counts` for all). Printed: the answer, and the share
named at each count with its Wilson interval, beside the power the pilots predicted there
(before the calibration). Where the interval holds the true 80 % point, the share at its low
end is below 80 % and at its high end above.

Then the calibration's slope, measured (diagnosis/power.py: the measured power where p is
predicted is Phi(z80 + shift + slope (Phi^-1(p) - z80))): each question's shift and slope
fitted to its counts (their posterior medians under wide priors, N(0, 1) on both the shift
and ln slope), and the spread of ln slope across the questions that makes all the counts
most likely (type II maximum likelihood, each question's shift integrated over N(0, 1)),
with its likelihood interval: what power.SLOPE_SD should be.

Run: .venv/bin/python benchmarks/bench_plan_questions.py TERM=SIZE[@N,N,...] [...]
     [--counts N,N,...] [--per 24]
The README's figures ("How many runs: plan"): lateral_slip=0.3
gait_frequency_variation=0.008 heading_random_walk=1.0 run_order_drift:yaw_rate=6
periodic_heading=2.0 measurement_noise=0.015 initial_pose_error=15@50,70,90,110
persistent_turning=3 (about 13 minutes).
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence
import math
from pathlib import Path
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from octoroach_model.arrays import FloatArray  # noqa: E402
from octoroach_model.diagnosis.power import (  # noqa: E402
    count_log_likelihood, measured_probit, SLOPE_SD)
from octoroach_model.studies.plan import CalibratedFit, CurvePoint  # noqa: E402

FIRST_REPLICATE = 7000


def question(text: str) -> tuple[str, float, list[int] | None]:
    """Return (term, size, counts) of a TERM=SIZE[@N,N,...] argument, or refuse it in one line."""
    from octoroach_model.limit_setting import RACED_TERMS

    asked, _, counts = text.partition('@')
    term, _, size = asked.partition('=')
    if term not in RACED_TERMS:
        raise argparse.ArgumentTypeError(f'{term[:60]!r} is not a term: one of '
                                         f'{", ".join(RACED_TERMS)}')
    try:
        value = float(size)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text[:60]!r}: the size after = is not a number') \
            from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f'{text[:60]!r}: the size must be a positive number')
    return term, value, counts_of(counts) if counts else None


def counts_of(text: str) -> list[int]:
    """Return the sorted run counts of a comma-separated --counts (each at least 40)."""
    try:
        counts = sorted({int(value) for value in text.split(',')})
    except ValueError:
        raise argparse.ArgumentTypeError('--counts takes whole numbers, comma-separated') \
            from None
    if not counts or counts[0] < 40 or counts[-1] > 100_000:
        raise argparse.ArgumentTypeError('--counts: each count between 40 and 100000')
    return counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('questions', nargs='+', metavar='TERM=SIZE', type=question)
    parser.add_argument('--counts', default=None, type=counts_of,
                        help='run counts, comma-separated')
    parser.add_argument('--per', type=int, default=24, help='data sets at each count')
    arguments = parser.parse_args()
    import octoroach_model as om
    from octoroach_model.diagnosis.live import Question
    from octoroach_model.studies.plan import default_spec
    from octoroach_model.studies.plan_model import check_task
    from octoroach_model.studies.summary import wilson
    from octoroach_model.workers import executor_for

    observed: list[list[tuple[int, int, float]]] = []     # per question: named, of, predicted
    for term, size, own_counts in arguments.questions:
        started = time.perf_counter()
        result = om.plan_runs(term, size, workers=2)
        low, high = result.runs_needed_interval_95
        print(f'{term}={size:g}: {result.statement} ({time.perf_counter() - started:.1f} s)',
              flush=True)
        if own_counts or arguments.counts:
            counts = own_counts or arguments.counts
        elif result.runs_needed is None or low is None or high is None \
                or not math.isfinite(high):
            continue
        else:
            counts = sorted({max(40, round(low)), int(result.runs_needed), round(high)})
        spec = default_spec(term, size)
        asked = Question(term, size)
        assert isinstance(result.fit, CalibratedFit)
        points = result.fit.curve
        rows = []
        with executor_for(None, 2) as pool:
            futures = {runs: [pool.submit(check_task, spec, asked, runs,
                                          FIRST_REPLICATE + replicate)
                              for replicate in range(arguments.per)] for runs in counts}
            for runs in counts:
                done = [future.result() for future in futures[runs]]
                ok = [outcome for outcome in done if outcome.status == 'ok']
                rate = wilson(sum(outcome.named for outcome in ok), len(ok))
                assert rate.rate is not None and rate.interval is not None
                predicted = predicted_at(points, runs)
                rows.append((rate.successes, rate.trials, predicted))
                print(f'    {runs} runs: named in {rate.successes}/{rate.trials} = '
                      f'{rate.rate:.0%} ({rate.interval[0]:.0%}-{rate.interval[1]:.0%}); the '
                      f'pilots predicted {predicted:.0%}', flush=True)
        observed.append(rows)
        shift, slope = question_fit(rows)
        print(f'    shift {shift:+.2f}, slope x{slope:.2f} (posterior medians, wide priors); '
              f'{time.perf_counter() - started:.0f} s', flush=True)
    if observed:
        spread, (low_spread, high_spread) = slope_spread(observed)
        print(f'ln slope spread across these {len(observed)} questions: {spread:.2f} '
              f'(likelihood interval {low_spread:.2f} to {high_spread:.2f}); power.SLOPE_SD '
              f'is {SLOPE_SD}', flush=True)
    return 0


def predicted_at(points: Sequence[CurvePoint], runs: int) -> float:
    """Return the pilots' power at `runs`: the plan curve's probit, linear in ln runs."""
    from scipy import special

    ln_runs = np.log([point.runs for point in points])
    probits = special.ndtri(np.clip([point.predicted for point in points], 1e-9, 1 - 1e-9))
    return float(special.ndtr(np.interp(math.log(runs), ln_runs, probits)))


# wide priors of a question's own shift and ln slope; the grids they are integrated on
WIDE_SD = 1.0
SHIFT_GRID = np.linspace(-4.0, 4.0, 161)
HERMITE = np.polynomial.hermite_e.hermegauss(41)


def log_counts(rows: Sequence[tuple[int, int, float]], log_slope: FloatArray) -> FloatArray:
    """Return log P(rows) on SHIFT_GRID x log_slope (binomial coefficients left out)."""
    total = np.zeros((len(SHIFT_GRID), len(log_slope)))
    for named, trials, predicted in rows:
        probit = measured_probit(predicted, SHIFT_GRID, np.exp(log_slope))
        total += count_log_likelihood(named, trials, probit)
    return total


def question_fit(rows: Sequence[tuple[int, int, float]]) -> tuple[float, float]:
    """Return one question's shift and slope: posterior medians under the wide priors."""
    from scipy import stats

    log_slope = np.linspace(-4.0, 4.0, 321)
    log_p = (log_counts(rows, log_slope) + stats.norm.logpdf(SHIFT_GRID, 0, WIDE_SD)[:, None]
             + stats.norm.logpdf(log_slope, 0, WIDE_SD)[None, :])
    weights = np.exp(log_p - log_p.max())
    weights /= weights.sum()
    shift = float(np.interp(0.5, np.cumsum(weights.sum(axis=1)), SHIFT_GRID))
    slope = math.exp(float(np.interp(0.5, np.cumsum(weights.sum(axis=0)), log_slope)))
    return shift, slope


def spread_log_likelihood(observed: Sequence[Sequence[tuple[int, int, float]]],
                          spread: float) -> float:
    """Return log P(all counts) with ln slope ~ N(0, spread), each shift ~ N(0, WIDE_SD)."""
    from scipy import special, stats

    nodes, weights = HERMITE
    weights = weights / weights.sum()
    step = float(SHIFT_GRID[1] - SHIFT_GRID[0])
    shift_prior = stats.norm.logpdf(SHIFT_GRID, 0, WIDE_SD) + math.log(step)
    total = 0.0
    for rows in observed:
        table = log_counts(rows, spread * nodes) + shift_prior[:, None]
        total += float(special.logsumexp(table + np.log(weights)[None, :]))
    return total


def slope_spread(observed: Sequence[Sequence[tuple[int, int, float]]]
                 ) -> tuple[float, tuple[float, float]]:
    """Return the spread of ln slope that makes `observed` most likely, and its interval."""
    grid = np.linspace(0.0, 2.0, 201)
    values = np.array([spread_log_likelihood(observed, spread) for spread in grid])
    inside = grid[values >= values.max() - 1.92]        # chi-squared(1) 95 % / 2
    return float(grid[int(np.argmax(values))]), (float(inside.min()), float(inside.max()))


if __name__ == '__main__':
    sys.exit(main())
