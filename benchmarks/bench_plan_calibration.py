"""
How often `plan`'s answer interval holds the true run count, through its calibration and checks.

`plan --method model` (studies/plan_model.py) shifts and bends the pilots' predicted power
curve on the probit scale (diagnosis/power.py): by its group's shift, measured by the studies
(`CALIBRATION_COUNTS`), widened by how far a question's own shift may lie from it
(`question_sd`), and by a slope factor about the point where the pilots predict 80 %, from
its prior (`SLOPE_SD`); each check then updates the question's shift and slope, and the
answer with them. Here the questions are simulated: a known predicted curve (a probit in ln
runs, 80 % at 300 runs), a true shift that is a draw of the group's (from its posterior) plus
a deviation, and plan's own calibration, check placement and updates
(`Calibration.for_term`, `plan_model.checked_answer`) on outcomes drawn from the true curve.
Printed per case: how often the answer's 95 % interval holds the run count where the true
curve reaches 80 % (with a 95 % Wilson interval), the median width of the interval (high /
low) and the median |ln(answer / truth)|, for three calibrations on the same questions: the
shift and slope (plan's), the question's shift alone with the slope held at 1 (plan's before
the slope), and the group's shift taken as the question's (before that).

Cases: deviations drawn at the spread plan assumes (`question_sd`, from the terms' counts
in CALIBRATION_COUNTS), at twice it (about the top of its likelihood interval), none (the
group right), one fixed miss of -0.8 (initial_pose_error at 15 deg on 10-cycle runs: 7 of
16 checks named it where 72-79 % was predicted); and deviations at the spread assumed on a
true curve whose slope in ln runs is 0.6 or 1.6 times the predicted one's (about one sd of
the slope's prior either way), and 0.3 times (a curve nearly flat in the runs, as
lateral_slip's first step at 0.3 cm/s on Table II's robot).

Run: .venv/bin/python benchmarks/bench_plan_calibration.py [--questions 400] [--checks 16]
     [--term persistent_turning] [--seed 1]
The figures in docs/studies.md ("How plan decides") come from the default call (about 95 s).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from octoroach_model.diagnosis.power import (  # noqa: E402
    Calibration, question_sd, SHIFTS, terms_log_likelihood)
from octoroach_model.studies.plan_model import (  # noqa: E402
    checked_answer, PredictedCurve)

TARGET = 0.8
MIN_RUNS, MAX_RUNS = 40, 20_000
SLOPE = 1.2                     # probit units per unit of ln runs: 50 % to 80 % over x 2


class KnownCurve(PredictedCurve):
    """A power curve of known form: a probit in ln runs, 80 % at 300 runs, `slope` x SLOPE."""

    slope: float = 1.0

    def predicted(self, runs: float) -> float:
        from scipy import special

        return float(special.ndtr(special.ndtri(TARGET)
                                  + self.slope * SLOPE * (math.log(runs) - math.log(300))))


def true_curve(slope: float) -> KnownCurve:
    """Return the true curve of a case: the predicted one's form, its slope times `slope`."""
    curve = KnownCurve((), 0.0, 0.0)
    curve.slope = slope
    return curve


def group_shift(term: str, rng: np.random.Generator) -> float:
    """Return a draw of the term's group's shift from its posterior (no question spread)."""
    weights = Calibration.for_term(term, 0.0, 0.0).shift_posterior()
    return float(rng.choice(SHIFTS, p=weights))


def plan_once(term: str, prior: tuple[float | None, float | None], true_shift: float,
              truth_curve: KnownCurve, checks: int, rng: np.random.Generator
              ) -> tuple[bool, float, float]:
    """Run plan's calibration and checks once; return covered, width ratio, |ln error|."""
    _, answer = checked_answer(
        KnownCurve((), 0.0, 0.0), Calibration.for_term(term, *prior), TARGET, MIN_RUNS,
        MAX_RUNS, checks, lambda runs: bool(rng.random() < truth_curve.power(runs, true_shift)))
    truth = truth_curve.runs_for(TARGET, true_shift, MIN_RUNS, MAX_RUNS)
    low, high = answer[1]
    return (low <= truth <= high, high / low if low > 0 else math.inf,
            abs(math.log(answer[0] / truth)))


def wilson(hits: int, total: int) -> tuple[float, float]:
    z = 1.959964
    centre = (hits + z * z / 2) / (total + z * z)
    half = z * math.sqrt(hits * (total - hits) / total + z * z / 4) / (total + z * z)
    return centre - half, centre + half


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--questions', type=int, default=400)
    parser.add_argument('--checks', type=int, default=16)
    parser.add_argument('--term', default='persistent_turning')
    parser.add_argument('--seed', type=int, default=1)
    arguments = parser.parse_args()
    spread = question_sd()
    top = terms_log_likelihood(spread)
    inside = [value for value in np.arange(0.0, 3.0, 0.01)
              if top - terms_log_likelihood(value) <= 1.92]
    print(f'question_sd from CALIBRATION_COUNTS: {spread:.2f} probit units (likelihood '
          f'interval {min(inside):.2f} to {max(inside):.2f}); {arguments.questions} questions '
          'per line, '
          f'{arguments.checks} checks each, term {arguments.term}, seed {arguments.seed}')
    normal = f'N(0, {spread:.2f})'
    cases = [(f'deviation ~ {normal}', lambda rng: rng.normal(0.0, spread), 1.0),
             (f'deviation ~ N(0, {2 * spread:.2f})', lambda rng: rng.normal(0.0, 2 * spread),
              1.0),
             ('no deviation', lambda rng: 0.0, 1.0),
             ('deviation -0.8', lambda rng: -0.8, 1.0),
             (f'{normal}, slope x 0.6', lambda rng: rng.normal(0.0, spread), 0.6),
             (f'{normal}, slope x 1.6', lambda rng: rng.normal(0.0, spread), 1.6),
             (f'{normal}, slope x 0.3', lambda rng: rng.normal(0.0, spread), 0.3)]
    print(f'{"case":<28} {"calibration":<19} {"coverage":>9} {"(95 %)":>14} '
          f'{"width":>6} {"|ln err|":>8}')
    started = time.perf_counter()
    for number, (case, deviation, slope) in enumerate(cases):
        for label, used in (('shift and slope', (None, None)),
                            ('question shift only', (None, 0.0)),
                            ('group shift only', (0.0, 0.0))):
            rng = np.random.default_rng([arguments.seed, number])    # the same questions
            rows = []
            for _ in range(arguments.questions):
                truth = group_shift(arguments.term, rng) + deviation(rng)
                rows.append(plan_once(arguments.term, used, truth, true_curve(slope),
                                      arguments.checks, rng))
            covered = sum(row[0] for row in rows)
            low, high = wilson(covered, len(rows))
            print(f'{case:<28} {label:<19} {covered / len(rows):>9.3f} '
                  f'{f"{low:.3f}-{high:.3f}":>14} {np.median([r[1] for r in rows]):>6.2f} '
                  f'{np.median([r[2] for r in rows]):>8.3f}', flush=True)
    print(f'{time.perf_counter() - started:.0f} s')


if __name__ == '__main__':
    main()
