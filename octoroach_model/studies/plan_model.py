"""
`plan` by a calibrated model of the power curve (`method='model'`, the default): seconds.

How it decides (docs/studies.md, "How plan decides"):

1. **Pilots.** PILOTS data sets of the robot without the effect (PILOT_RUNS runs each, side
   by side) are fitted as the diagnosis fits them and the term's first step of the forward
   selection is taken on each (diagnosis/live.py, `pilot_model`). The errors of its size and
   the expected t of its held-out test at the requested size give the power at any run
   count (diagnosis/power.py): P(size bound clears the floor) x P(held-out test
   significant), at the diagnosis's levels (every candidate in the race). The pilots'
   powers are averaged.
2. **Calibration.** The predicted power is shifted on the probit scale by the question's
   shift: its group's, measured by the studies where 80 % was predicted
   (power.CALIBRATION_COUNTS), widened by how far a question may lie from its group
   (power.question_sd); and bent about the pilots' 80 % point by a slope factor with a prior
   (power.SLOPE_SD). The answer is where the calibrated curve reaches the requested power at
   the posterior median, its 95 % interval where it does at the ends of the posterior's
   (`Calibration.target_shifts`).
3. **Checks, as time allows** (`budget_s`, the plan's whole time), or exactly `checks` of
   them. Data sets with the effect at the requested size are simulated at the current
   answer (`check_runs`) and the term's first step taken on each, at the diagnosis's
   levels; each outcome, in the order the checks were placed, updates the question's shift
   and slope (`after_check`), and with them the answer, its interval and where the next
   checks go. A check starts only when it can end within the budget (its expected time from
   the checks so far).

What it leaves out, and the reason: the full diagnosis of each check (a minute each with
every candidate in the race); the first step of C alone is what names C when it is the only
effect, and what the detection limits (and so the power model) describe. The full
simulation that `method='simulate'` runs is the reference: benchmarks/bench_plan.py puts
both answers side by side.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field, replace
import math
import time
from typing import Any

import numpy as np
from scipy import stats

from octoroach_model.diagnosis.causes import CANDIDATES
from octoroach_model.diagnosis.decide import decision_z
from octoroach_model.diagnosis.live import (
    decide, fit_held, Levels, pilot_model, Question, stated_size)
from octoroach_model.diagnosis.modelfit import FittedModel
from octoroach_model.diagnosis.power import Calibration, fixed, PowerModel, shifted
from octoroach_model.settings import Progress
from octoroach_model.studies.design import build_tasks, draw_robot, RobotDraw
from octoroach_model.studies.replicate import simulate_data, task_effects
from octoroach_model.studies.rows import Status
from octoroach_model.studies.spec import StudySpec

PILOTS = 2
PILOT_RUNS = 500
CURVE_POINTS = 41
Answer = tuple[float, tuple[float, float]]      # runs, and their 95 % interval


@dataclass(frozen=True)
class CheckOutcome:
    """One simulated check: the term at the size, `runs` runs, named or not."""

    runs: int
    replicate: int
    seed: int
    status: Status
    named: bool
    predicted: float             # the pilots' (uncalibrated) power at these runs
    estimate: float
    se: float                    # the estimate's standard error, in its units
    clears_floor: bool           # the size bound cleared the floor (P1 of diagnosis/power.py)
    test_z: float                # the held-out gain in standard errors (P2's test) ...
    test_critical_z: float       # ... and the value it had to pass
    gain: float
    p_value: float
    elapsed_s: float
    note: str = ''

    @property
    def test_passed(self) -> bool:
        """Whether the held-out test's z passed its critical value (named needs both)."""
        return self.test_z > self.test_critical_z


@dataclass(frozen=True)
class ModelAnswer:
    """What the calibrated model answers, and what it rests on."""

    runs: float                                   # inf: never within MOST_RUNS
    interval: tuple[float, float]
    shift: float
    shift_interval_95: tuple[float, float]
    slope: float
    slope_interval_95: tuple[float, float]
    sources: tuple[str, ...]
    pilots: tuple[PilotDataSet, ...]
    checks: tuple[CheckOutcome, ...]
    curve: tuple[tuple[float, float, float, float, float], ...]  # runs, power, low, high,
    #                                                     and the pilots' (uncalibrated) power
    models: tuple[PowerModel, ...] = field(default=(), metadata={'json': False}, repr=False)


@dataclass(frozen=True)
class PilotDataSet:
    """One pilot: a null data set of a replicate's robot, and the time it took."""

    replicate: int
    runs: int
    seed: int
    elapsed_s: float


def robot_model(draw: RobotDraw) -> FittedModel:
    """Return the robot a replicate simulates, as the model a baseline fit starts from."""
    return FittedModel(draw.parameters(), (0.0, 0.0, math.pi / 2), draw.spread_scale, {})


def pilot_task(spec: StudySpec, question: Question, replicate: int, runs: int
               ) -> tuple[PowerModel, PilotDataSet]:
    """Simulate a null data set of replicate `replicate`'s robot; its power model (step 1)."""
    from octoroach_model.studies.replicate import use_large_malloc_thresholds

    use_large_malloc_thresholds()
    started = time.perf_counter()
    draw = draw_robot(spec, replicate)
    measured = simulate_data(spec, draw, runs, {}).paths
    settings = spec.diagnosis_settings(draw.data_seed)
    model = pilot_model(measured, question, settings, robot_model(draw))
    return model, PilotDataSet(replicate, runs, draw.data_seed,
                               round(time.perf_counter() - started, 3))


def check_task(spec: StudySpec, question: Question, runs: int, replicate: int
               ) -> CheckOutcome:
    """Simulate the term at the size with `runs` runs; take its first step (module doc)."""
    from octoroach_model.studies.replicate import use_large_malloc_thresholds

    use_large_malloc_thresholds()
    started = time.perf_counter()
    draw = draw_robot(spec, replicate)
    task = replace(build_tasks(spec)[0], runs_cell=runs, replicate=replicate)
    try:
        effects = task_effects(task, spec, None, draw.duration_s)
        measured = simulate_data(spec, draw, runs, effects).paths
        settings = spec.diagnosis_settings(draw.data_seed)
        held = fit_held(measured, question, settings, robot_model(draw), with_power=False)
        look = decide(measured, held, question, settings,
                      Levels.fixed(settings, len(CANDIDATES)))
    except Exception as error:  # noqa: BLE001 - a check that fails is a result, not a crash
        return CheckOutcome(runs, replicate, draw.data_seed, Status.ERROR, False, math.nan,
                            math.nan, math.nan, False, math.nan, math.nan, math.nan, math.nan,
                            round(time.perf_counter() - started, 3),
                            f'{type(error).__name__}: {error}')
    se = (stated_size(look.term, look.model.estimate.se) if look.model is not None
          else math.nan)
    return CheckOutcome(runs, replicate, draw.data_seed, Status.OK, look.named_here, math.nan,
                        look.estimate, se, look.clears_floor, look.test_z,
                        look.test_critical_z, look.gain, look.p_value,
                        round(time.perf_counter() - started, 3))


@dataclass
class PredictedCurve:
    """The pilots' power curve at the diagnosis's levels, averaged over the pilots."""

    models: Sequence[PowerModel]
    z_bound: float
    z_test: float

    def predicted(self, runs: float) -> float:
        """Return the pilots' (uncalibrated) power with `runs` runs."""
        return float(np.mean([model.power(runs, fixed(self.z_bound), fixed(self.z_test))
                              for model in self.models]))

    def power(self, runs: float, shift: float = 0.0) -> float:
        """Return the power with `runs` runs, shifted by `shift` on the probit scale."""
        predicted = self.predicted(runs)
        return shifted(predicted, shift) if shift else predicted

    def runs_for(self, target: float, shift: float, least: int, most: int) -> float:
        """Fewest runs in [least, most] where the shifted power reaches `target` (inf: none)."""
        if self.power(least, shift) >= target:
            return float(least)
        low, high = float(least), float(least)
        while self.power(high, shift) < target:
            low, high = high, high * 2
            if high > 4 * most:
                return math.inf
        while high - low > 1:
            middle = math.floor((low + high) / 2)
            low, high = (middle, high) if self.power(middle, shift) < target else (low, middle)
        return high


def plan_by_model(spec: StudySpec, question: Question, *, min_runs: int, max_runs: int,
                  executor: Executor, workers: int, budget_s: float,
                  checks: int | None = None, progress: Progress | None = None) -> ModelAnswer:
    """Answer the plan by the calibrated power model and checks (module docstring)."""
    say = progress or (lambda fraction, message: None)
    started = time.monotonic()
    settings = spec.diagnosis_settings(0)
    candidates = len(CANDIDATES)
    curve_levels = (decision_z(settings.decision_alpha, candidates),
                    float(stats.norm.isf(settings.alpha / candidates)))
    say(0.05, f'pilots: {PILOTS} data sets of {PILOT_RUNS} runs without the effect, the '
              "term's first step on each")
    futures = [executor.submit(pilot_task, spec, question, replicate, PILOT_RUNS)
               for replicate in range(PILOTS)]
    pilots = [future.result() for future in futures]
    curve = PredictedCurve([model for model, _ in pilots], *curve_levels)
    calibration = Calibration.for_term(question.term)
    answer = answer_of(curve, calibration, question.power, min_runs, max_runs)
    say(0.3, f'pilots done ({time.monotonic() - started:.1f} s): predicted '
             f'{runs_answer_text(*answer)}, calibration shift {calibration.shift:+.2f}, '
             f'slope x{calibration.slope:.2f}')
    deadline = started + budget_s if checks is None else math.inf
    done = _check(spec, question, curve, calibration, answer, min_runs, max_runs, executor,
                  workers, deadline, say, checks)
    if done:
        calibration = calibration.updated(
            [check.predicted for check in done if check.status == Status.OK],
            [check.named for check in done if check.status == Status.OK],
            f'checks: named in {sum(check.named for check in done)} of '
            f'{sum(check.status == Status.OK for check in done)} simulated data sets')
        answer = answer_of(curve, calibration, question.power, min_runs, max_runs)
    return ModelAnswer(answer[0], answer[1], calibration.shift, calibration.interval_95,
                       calibration.slope, calibration.slope_interval_95, calibration.sources,
                       tuple(info for _, info in pilots), tuple(done),
                       _curve_points(curve, calibration, answer, min_runs, max_runs),
                       tuple(curve.models))


def answer_of(curve: PredictedCurve, calibration: Calibration, power: float, min_runs: int,
              max_runs: int) -> Answer:
    """Return the runs where the calibrated curve reaches `power`, and their 95 % interval."""
    shift, (low_shift, high_shift) = calibration.target_shifts(power)
    middle = curve.runs_for(power, shift, min_runs, max_runs)
    # a larger shift means more power, so fewer runs: the interval's low end is the high shift
    return middle, (curve.runs_for(power, high_shift, min_runs, max_runs),
                    curve.runs_for(power, low_shift, min_runs, max_runs))


def check_runs(answer: Answer, min_runs: int, max_runs: int) -> int:
    """Return the run count the next check simulates: the current answer, within the range."""
    target = answer[0]
    return (int(min(max(round(target), min_runs), max_runs)) if math.isfinite(target)
            else max_runs)


def after_check(curve: PredictedCurve, calibration: Calibration, predicted: float, named: bool,
                power: float, min_runs: int, max_runs: int) -> tuple[Calibration, Answer]:
    """Return the calibration and the answer updated by one check's outcome."""
    calibration = calibration.updated([predicted], [named], 'check')
    return calibration, answer_of(curve, calibration, power, min_runs, max_runs)


def checked_answer(curve: PredictedCurve, calibration: Calibration, power: float,
                   min_runs: int, max_runs: int, checks: int,
                   named_at: Callable[[int], bool]) -> tuple[Calibration, Answer]:
    """
    Return the calibration and answer after `checks` checks taken in turn, as `_check` does.

    Each check goes where the current answer is (`check_runs`) and `named_at(runs)` says
    whether it named the term: plan's sequence without its simulations, for the
    benchmark and the test that measure its interval on questions of known truth.
    """
    answer = answer_of(curve, calibration, power, min_runs, max_runs)
    for _ in range(checks):
        runs = check_runs(answer, min_runs, max_runs)
        calibration, answer = after_check(curve, calibration, curve.predicted(runs),
                                          named_at(runs), power, min_runs, max_runs)
    return calibration, answer


def _check(spec: StudySpec, question: Question, curve: PredictedCurve,
           calibration: Calibration, answer: Answer, min_runs: int, max_runs: int,
           executor: Executor, workers: int, deadline: float, say: Progress,
           most: int | None = None) -> list[CheckOutcome]:
    """
    Run checks at the current answer until the deadline, or `most` of them (module docstring).

    The outcomes update the answer in the order the checks were placed, not as they end, so
    that the same checks (a seed, a count, the workers) give the same answer every time.
    """
    done: list[CheckOutcome] = []
    running: dict[Future, tuple[int, float]] = {}
    replicate = PILOTS
    costs: list[float] = []

    def expected_cost(runs: int) -> float:
        # the checks so far, per run, times the runs (a first guess before any is done)
        per_run = float(np.median(costs)) if costs else 4.0 / PILOT_RUNS
        return per_run * runs

    while True:
        runs = check_runs(answer, min_runs, max_runs)
        now = time.monotonic()
        while (len(running) < max(workers, 1) and now + expected_cost(runs) <= deadline
               and (most is None or replicate - PILOTS < most)):
            future = executor.submit(check_task, spec, question, runs, replicate)
            running[future] = (runs, curve.predicted(runs))
            replicate += 1
        if not running:
            return done
        oldest = next(iter(running))          # dicts keep the order the checks were placed
        runs_done, predicted = running.pop(oldest)
        outcome = replace(oldest.result(), predicted=predicted)
        done.append(outcome)
        if outcome.status == Status.OK:
            costs.append(outcome.elapsed_s / max(runs_done, 1))
            calibration, answer = after_check(curve, calibration, predicted, outcome.named,
                                              question.power, min_runs, max_runs)
        say(min(0.3 + 0.6 * len(done) / (len(done) + 2), 0.95),
            f'check {len(done)}: {runs_done} runs, '
            + ('named' if outcome.named else 'not named' if outcome.status == Status.OK
               else f'failed ({outcome.note})')
            + f' (predicted power {predicted:.0%}); answer now {runs_answer_text(*answer)}')


def _curve_points(curve: PredictedCurve, calibration: Calibration,
                  answer: Answer, min_runs: int, max_runs: int
                  ) -> tuple[tuple[float, float, float, float, float], ...]:
    """Return the calibrated curve (runs, power, its 95 % band, the pilots') by the answer."""
    finite = [value for value in (answer[0], *answer[1]) if math.isfinite(value)]
    low = max(min(finite or [min_runs]) / 2, min_runs)
    high = min(max(finite or [max_runs]) * 2, 4 * max_runs)
    points = []
    for runs in np.geomspace(low, max(high, low * 1.01), CURVE_POINTS):
        predicted = curve.predicted(runs)
        points.append((float(runs), *calibration.power_band(predicted), predicted))
    return tuple(points)


def runs_interval_text(low: float, high: float) -> str:
    """Say an interval of run counts: '150 to 400 runs', '150 runs to more than any tried'."""
    if math.isfinite(high):
        return f'{low:.0f} to {high:.0f} runs'
    if math.isfinite(low):
        return f'{low:.0f} runs to more than any run count tried'
    return 'more than any run count tried'


def runs_answer_text(runs: float, interval: tuple[float, float]) -> str:
    """Say an answer and its interval: '120 runs (95 % 80 to 400 runs)'."""
    said = f'{runs:.0f} runs' if math.isfinite(runs) else 'more than any run count tried'
    return f'{said} (95 % {runs_interval_text(*interval)})'


def outcome_rows(checks: Sequence[CheckOutcome]) -> list[dict[str, Any]]:
    """Return the checks as plain rows (checks.csv)."""
    from dataclasses import asdict

    return [asdict(check) for check in checks]
