"""
`plan_runs`: how many runs an experiment needs to detect a cause of a given size.

Two methods (docs/studies.md, "How plan decides"). `method='model'` (the default, seconds):
a calibrated model of the power curve from two pilot data sets, checked by simulation as
time allows (studies/plan_model.py). `method='simulate'` (minutes, the reference): many data
sets simulated and diagnosed in full at several run counts, as follows.

1. Pilot: one data set of the paper's model on the robot (PILOT_RUNS runs) is diagnosed; the
   detection limit L it reports for the cause gives a first guess n0 = PILOT_RUNS (L / size)^2
   (a limit that shrinks as 1 / sqrt(runs)). Only a starting point: the answer comes from 3.
2. Coarse grid: n0 / 4, n0 / 2, n0, 2 n0 (within [min_runs, max_runs]); at each, `replicates`
   data sets with the effect at `size` are diagnosed. Replicate r uses the same seed at every
   run count (common random numbers: for most causes a smaller data set is the first runs of
   a larger one).
3. Fit: power(n) = 1 / (1 + exp(-(a + b ln n))) by maximum likelihood over every diagnosed
   data set (studies/power_curve.py); the answer is the n where the fit reaches the
   requested power, with its profile-likelihood 95 % interval, scaled for the replicates'
   common random numbers.
4. Refine: if the answer lies beyond the grid, the grid grows by doubling (or halving) up to
   max_runs (down to min_runs); otherwise one more run count at the answer is diagnosed and
   the fit repeated. At most MAX_ROUNDS rounds after the coarse grid.

The observed share at every run count is reported with its Wilson interval beside the fit.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from enum import StrEnum
import math
from pathlib import Path
import time
from typing import Any, NamedTuple, TYPE_CHECKING

import numpy as np

from octoroach_model.diagnosis.diagnose import MIN_RUNS
from octoroach_model.errors import ParameterError
from octoroach_model.jsonio import dumps
from octoroach_model.settings import (
    check_callable, check_setting, number, Progress, setting, shown, unknown_name)
from octoroach_model.studies.design import build_tasks
from octoroach_model.studies.execute import run_tasks
from octoroach_model.studies.plan_model import runs_interval_text
from octoroach_model.studies.power_curve import fit_power_curve, INTERVAL_METHOD, PowerFit
from octoroach_model.studies.rows import Status, StudyRow
from octoroach_model.studies.spec import (
    Arm, ArmKind, nominal_robot, NULL, parse_spec, robot_spec, RobotSpec, StudySpec)
from octoroach_model.studies.summary import wilson
from octoroach_model.studies.table import write_table
from octoroach_model.studies.terms import main_parameter, null_value, TERMS
from octoroach_model.workers import check_where, CONNECT_TIMEOUT_S, executor_where, where_to_run

if TYPE_CHECKING:
    from octoroach_model.studies.plan_model import PilotDataSet

PILOT_RUNS = 200
BUDGET_S = 15.0             # method 'model': seconds a plan may take, pilots and checks
MOST_CHECKS = 1000          # method 'model': the most checks --checks may ask
MAX_ROUNDS = 3


class PlanMethod(StrEnum):
    """How a plan finds its answer: a calibrated power model, or many data sets diagnosed."""

    MODEL = 'model'
    SIMULATE = 'simulate'


METHODS = tuple(method.value for method in PlanMethod)      # the --method choices


class PlanStatus(StrEnum):
    """What a plan found: a run count, the fewest runs suffice, or more than the most."""

    FOUND = 'found'
    AT_MIN_RUNS = 'at_min_runs'
    ABOVE_MAX_RUNS = 'above_max_runs'


@dataclass(frozen=True)
class PlanSettings:
    """
    What a user sets of a plan: the one source of `plan`'s options and `plan_runs`' defaults.

    `plan_runs` checks the values (power strictly between 0 and 1, a positive budget,
    max_runs at least MIN_RUNS, ...); the fields say so to the user.
    """

    power: float = setting(0.8, 'probability of naming the cause', low=0.0, high=1.0,
                           open_low=True, open_high=True)
    method: str = setting('model', 'model: a calibrated model of the power curve from two '
                          'pilot data sets, checked by simulation as --budget-s allows '
                          '(seconds); simulate: data sets diagnosed in full at several run '
                          'counts (minutes, the reference); docs/studies.md, "How plan decides"',
                          choices=METHODS)
    budget_s: float = setting(BUDGET_S, 'for --method model: seconds the plan may take, pilots '
                              'and checks', unit='s', low=0.0, open_low=True)
    checks: int | None = setting(None, 'for --method model: take exactly this many checks, '
                                 'however long they take, instead of as many as --budget-s '
                                 'allows: the same answer for the same seed and workers, every '
                                 'time', low=0, high=MOST_CHECKS)
    replicates: int = setting(6, 'for --method simulate: data sets per run count (more on a '
                              'cluster: tighter intervals)', low=1)
    max_runs: int = setting(2000, 'the largest run count tried', low=MIN_RUNS)
    seed: int = setting(0, 'seed of every data set', low=0)


PLAN = PlanSettings()


class PowerPoint(NamedTuple):
    """Observed power at one run count: named in `named` of `data_sets`, Wilson interval."""

    runs: int
    named: int
    data_sets: int
    power: float
    interval_95: tuple[float, float]


LOGISTIC_MODEL = 'power = 1 / (1 + exp(-(intercept + slope ln(runs))))'
CALIBRATED_MODEL = ('P(size bound clears the floor) x P(held-out test significant) from the '
                    'pilots, shifted and bent on the probit scale (diagnosis/power.py)')
MODEL_PILOTS = ("null data sets of the robot; the term's first step on each gives the errors "
                'of its size and the gains of its held-out test')


@dataclass(frozen=True)
class LogisticFit:
    """Method 'simulate': the logistic fit of power in ln(runs) (`fit_power_curve`)."""

    model: str
    intercept: float
    slope: float
    runs_at_target: float | None     # None: the fit never reaches the power asked
    interval_method: str


@dataclass(frozen=True)
class CurvePoint:
    """The calibrated power at one run count, with its 95 % band, and the pilots' own."""

    runs: float
    power: float
    low: float
    high: float
    predicted: float            # the pilots' power before the calibration


@dataclass(frozen=True)
class CalibratedFit:
    """Method 'model': the calibrated power model (plan_model.py) and its curve."""

    model: str
    shift: float
    shift_interval_95: tuple[float, float]
    slope: float
    slope_interval_95: tuple[float, float]
    calibration: tuple[str, ...]
    curve: tuple[CurvePoint, ...]


@dataclass(frozen=True)
class SimulatedPilot:
    """Method 'simulate': the one diagnosed null data set the first run counts come from."""

    runs: int
    limit: float | None              # the detection limit it reported (None: none)
    guess_runs: float
    how: str
    status: Status
    note: str


@dataclass(frozen=True)
class ModelPilots:
    """Method 'model': the null data sets the power model was made from."""

    data_sets: tuple[PilotDataSet, ...]
    how: str


@dataclass(frozen=True)
class PlanResult:
    """The answer of `plan_runs` and the curve it came from (docs/studies.md)."""

    cause: str
    parameter: str
    size: float
    power: float
    runs_needed: int | None
    runs_needed_interval_95: tuple[float | None, float | None]
    status: PlanStatus
    statement: str
    curve: tuple[PowerPoint, ...]
    fit: LogisticFit | CalibratedFit
    pilot: SimulatedPilot | ModelPilots | None    # None: the run counts were given ({})
    robot: RobotSpec
    replicates: int
    seed: int
    elapsed_s: float
    rows: tuple[StudyRow, ...] = field(default=(), metadata={'json': False}, repr=False)
    method: PlanMethod = PlanMethod.SIMULATE
    checks: tuple = ()            # method 'model': the simulated checks (plan_model.py)

    def to_json(self) -> dict:
        from octoroach_model.jsonio import fields_jsonable

        plain = fields_jsonable(self)
        plain['curve'] = [point._asdict() for point in self.curve]
        if self.pilot is None:
            plain['pilot'] = {}
        return plain


def plan_runs(cause: str, size: float, *, power: float = PLAN.power,
              robot: RobotSpec | Mapping[str, Any] | None = None,
              parameters: Mapping[str, float] | None = None, replicates: int = PLAN.replicates,
              run_counts: Sequence[int] | None = None, min_runs: int | None = None,
              max_runs: int = PLAN.max_runs, rounds: int = MAX_ROUNDS, seed: int = PLAN.seed,
              diagnosis: Mapping[str, Any] | None = None, client: Any | None = None,
              scheduler: str | None = None, workers: int | None = None,
              progress: Progress | None = None, out: str | Path | None = None,
              connect_timeout_s: float = CONNECT_TIMEOUT_S, method: str = PLAN.method,
              budget_s: float = PLAN.budget_s, checks: int | None = PLAN.checks) -> PlanResult:
    """
    Find the number of runs needed to name `cause` at `size` with probability `power`.

    `size` is the cause's main parameter, in its unit; `robot` defaults to Table II (10
    cycles at 50 Hz); `parameters` sets the cause's other parameters; `diagnosis` overrides
    DiagnosisSettings as in a study spec. Where tasks run: as in `run_study`. With `out`,
    writes plan.json, the data sets (table.csv, or checks.csv for the model) and
    power_curve.png there.

    `method`: 'model' (module docstring; `budget_s` bounds its time, pilots and checks, unless
    `checks` fixes how many checks it takes, which makes the answer repeat for a seed) or
    'simulate', where `replicates` data sets are diagnosed at each run count, `run_counts`
    skips the pilot and starts from these counts and `rounds` bounds the refinement rounds
    after the coarse grid.
    """
    started = time.perf_counter()
    check_callable('progress', progress)
    say = progress or (lambda fraction, message: None)
    for name, value in (('power', power), ('budget_s', budget_s), ('replicates', replicates),
                        ('max_runs', max_runs), ('seed', seed)):
        check_setting(PlanSettings, name, value)
    if cause not in TERMS:
        raise ParameterError(f'cause must be a cause of the table or an extension term '
                             f'({", ".join(TERMS)}), got {shown(cause)}')
    if not math.isfinite(number('size', size)):
        raise ParameterError(f'size must be a finite number, got {shown(size)}')
    min_runs = max(MIN_RUNS, min_runs or MIN_RUNS)
    if method not in METHODS:
        raise ParameterError(f'method must be one of {", ".join(METHODS)}, got '
                             f'{unknown_name(method, METHODS)}')
    base = _base_spec(cause, size, robot, parameters, replicates, seed, diagnosis,
                      min_runs, max_runs, power)
    if method == PlanMethod.MODEL:
        if run_counts is not None:
            raise ParameterError('run counts (--runs) go with --method simulate')
        if checks is not None:
            check_setting(PlanSettings, 'checks', checks)
            checks = int(checks)
        check_where(client, scheduler, workers)
        out_dir = _check_out(out)
        result = _plan_by_model(base, cause, size, power, min_runs, max_runs, seed, client,
                                scheduler, workers, connect_timeout_s, budget_s, checks, say,
                                started)
        if out_dir is not None:
            write_plan(result, out_dir)
        return result
    if checks is not None:
        raise ParameterError('a number of checks (--checks) goes with --method model')
    if run_counts is not None:
        run_counts = sorted({int(n) for n in run_counts})
        if not run_counts or run_counts[0] < min_runs or run_counts[-1] > max_runs:
            raise ParameterError(f'run counts must lie in [{min_runs}, {max_runs}], got '
                                 f'{run_counts}')
    check_where(client, scheduler, workers)
    out_dir = _check_out(out)
    rows: list[StudyRow] = []
    with where_to_run(client, scheduler, workers, connect_timeout_s) as where:
        def run(spec: StudySpec, label: str) -> list[StudyRow]:
            tasks = build_tasks(spec)
            new: list[StudyRow] = []

            def arrived(row: StudyRow) -> None:
                new.append(row)
                say(len(new) / len(tasks), f'{label}: {row.key} {row.status} '
                    f'(named: {";".join(row.outcome.named) or "none"})')
            say(0.0, f'{label}: {len(tasks)} data sets')
            run_tasks(tasks, spec, client=where, done={}, on_row=arrived)
            return new

        pilot = None
        if run_counts is None:
            pilot = _pilot(base, run, min_runs, max_runs)
            run_counts = _coarse_grid(pilot.guess_runs, min_runs, max_runs)
        counts = list(run_counts)
        rows += run(_with_runs(base, counts), 'coarse grid')
        for round_number in range(1, rounds + 1):
            fit = fit_power_curve(rows, cause, power)
            more = _next_counts(fit, sorted({row.runs for row in rows}), min_runs, max_runs)
            if not more:
                break
            rows += run(_with_runs(base, more), f'refinement {round_number}')
    fit = fit_power_curve(rows, cause, power)
    result = _result(base, cause, size, power, rows, fit, pilot, seed, replicates,
                     min_runs, max_runs, time.perf_counter() - started)
    if out_dir is not None:
        write_plan(result, out_dir)
    return result


def _plan_by_model(base: StudySpec, cause: str, size: float, power: float, min_runs: int,
                   max_runs: int, seed: int, client: Any | None, scheduler: str | None,
                   workers: int | None, connect_timeout_s: float, budget_s: float,
                   checks: int | None, say: Progress, started: float) -> PlanResult:
    """Plan with the calibrated power model (plan_model.py), on a pool or a Dask cluster."""
    from octoroach_model.diagnosis.live import Question
    from octoroach_model.studies.plan_model import plan_by_model

    question = Question(cause, size, power)
    with executor_where(client, scheduler, workers, connect_timeout_s) as (executor, count):
        answer = plan_by_model(base, question, min_runs=min_runs, max_runs=max_runs,
                               executor=executor, workers=count, budget_s=budget_s,
                               checks=checks, progress=say)
    return _model_result(base, cause, size, power, answer, seed, min_runs, max_runs,
                         time.perf_counter() - started)


def _model_result(base: StudySpec, cause: str, size: float, power: float, answer: Any,
                  seed: int, min_runs: int, max_runs: int, elapsed_s: float) -> PlanResult:
    """Make the PlanResult of the model method: answer, interval, checks, curve."""
    parameter = main_parameter(cause)
    what = (f'{cause} with {parameter} {null_value(cause):g} - {size:g}' if null_value(cause)
            else f'{cause} with {parameter} = {size:g}')
    checks = [check for check in answer.checks if check.status == Status.OK]
    named = sum(check.named for check in checks)
    basis = (f'calibrated power model from {len(answer.pilots)} pilot data sets, checked on '
             f'{len(checks)} simulated data sets ({named} named)')
    low, high = (float(max(value, min_runs)) if math.isfinite(value) else None
                 for value in answer.interval)
    if not math.isfinite(answer.runs) or answer.runs > max_runs:
        status, needed = PlanStatus.ABOVE_MAX_RUNS, None
        statement = (f'more than {max_runs} runs are needed to name {what} with '
                     f'{_power_text(power)} power ({basis})')
    elif answer.runs <= min_runs:
        status, needed = PlanStatus.AT_MIN_RUNS, min_runs
        statement = (f'{min_runs} runs (the fewest the diagnosis takes) already name {what} '
                     f'with at least {_power_text(power)} power ({basis})')
    else:
        status, needed = PlanStatus.FOUND, int(math.ceil(answer.runs))
        statement = (f'about {needed} runs name {what} with {_power_text(power)} power (95 % '
                     f'interval {runs_interval_text(low or math.inf, high or math.inf)}; '
                     f'{basis})')
    curve = []
    for runs in sorted({check.runs for check in checks}):
        group = [check for check in checks if check.runs == runs]
        rate = wilson(sum(check.named for check in group), len(group))
        assert rate.rate is not None and rate.interval is not None
        curve.append(PowerPoint(runs, rate.successes, rate.trials, rate.rate, rate.interval))
    fit = CalibratedFit(CALIBRATED_MODEL, answer.shift, answer.shift_interval_95,
                        answer.slope, answer.slope_interval_95, answer.sources,
                        tuple(CurvePoint(*point) for point in answer.curve))
    return PlanResult(cause, parameter, size, power, needed, (low, high), status, statement,
                      tuple(curve), fit, ModelPilots(answer.pilots, MODEL_PILOTS), base.robot,
                      len(checks), seed,
                      round(elapsed_s, 2), (), PlanMethod.MODEL, tuple(answer.checks))


def _base_spec(cause: str, size: float, robot: RobotSpec | Mapping[str, Any] | None,
               parameters: Mapping[str, float] | None, replicates: int, seed: int,
               diagnosis: Mapping[str, Any] | None, min_runs: int, max_runs: int,
               power: float) -> StudySpec:
    """Build the study behind the plan, checked like any spec (one cause at one size)."""
    if not 0 < power < 1:
        raise ParameterError(f'power must lie strictly between 0 and 1, got {power:g}')
    if max_runs < min_runs:
        raise ParameterError(f'max_runs {max_runs} is below the minimum of {min_runs} runs')
    robot = robot if isinstance(robot, RobotSpec) else (
        robot_spec(robot) if robot is not None else nominal_robot())
    entry: dict[str, Any] = {'cause': cause, 'sizes': [size]}
    if parameters:
        entry['parameters'] = dict(parameters)
    spec = parse_spec({'name': f'plan {cause}', 'seed': seed, 'replicates': replicates,
                       'runs': [min_runs], 'causes': [entry],
                       'diagnosis': dict(diagnosis or {})})
    return StudySpec(spec.name, seed, replicates, spec.runs, robot, spec.arms,
                     diagnosis=spec.diagnosis)


def default_spec(cause: str, size: float) -> StudySpec:
    """Return the study a plan of `cause` at `size` builds at its defaults (Table II's robot)."""
    return _base_spec(cause, size, None, None, PLAN.replicates, PLAN.seed, None, MIN_RUNS,
                      PLAN.max_runs, PLAN.power)


def _with_runs(base: StudySpec, counts: Sequence[int]) -> StudySpec:
    return StudySpec(base.name, base.seed, base.replicates, tuple(counts), base.robot,
                     base.arms, diagnosis=base.diagnosis)


def _pilot(base: StudySpec, run: Callable, min_runs: int, max_runs: int) -> SimulatedPilot:
    """
    Diagnose one null data set; the limit it reports gives the first guess of runs.

    Only the planned term's whole limit is computed (the others' would take most of the time).
    """
    arm = base.arms[0]
    pilot_runs = int(min(max(PILOT_RUNS, min_runs), max_runs))
    diagnosis = tuple(sorted({**dict(base.diagnosis), 'limit_terms': (arm.cause,)}.items()))
    spec = StudySpec(base.name, base.seed, 1, (pilot_runs,), base.robot,
                     (Arm(ArmKind.NULL, NULL),), diagnosis=diagnosis)
    row = run(spec, 'pilot')[0]
    limit = row.terms[arm.cause].limit if row.ok else None
    if limit is not None and math.isfinite(limit) and limit > 0:
        guess = pilot_runs * (limit / arm.size) ** 2
        how = (f'the pilot reported a detection limit of {limit:.4g}; runs scaled by '
               f'(limit / size)^2')
    else:
        guess = pilot_runs * 4.0
        how = 'the pilot reported no detection limit; starting at 4 x the pilot runs'
    guess = float(min(max(guess, min_runs), max_runs))
    return SimulatedPilot(pilot_runs, limit, guess, how, row.status, row.note)


def _coarse_grid(guess: float, min_runs: int, max_runs: int) -> list[int]:
    """
    Return the run counts guess / 4 ... 2 guess within the bounds.

    At least three counts where the bounds allow: a guess at a bound grows away from it by
    doubling (or halving).
    """
    counts = {int(round(min(max(guess * factor, min_runs), max_runs)))
              for factor in (0.25, 0.5, 1.0, 2.0)}
    while len(counts) < 3 and max(counts) < max_runs:
        counts.add(min(2 * max(counts), max_runs))
    while len(counts) < 3 and min(counts) > min_runs:
        counts.add(max(min(counts) // 2, min_runs))
    return sorted(counts)


def _next_counts(fit: PowerFit, counts: list[int], min_runs: int, max_runs: int) -> list[int]:
    """
    Return the run counts of the next round ([] when the answer is pinned down).

    The grid grows or shrinks toward the answer, or gains the answer itself; nothing is
    added beyond the bounds.
    """
    answer = fit.runs_at_target
    if answer > counts[-1]:
        step = min(counts[-1] * 2, max_runs)
        return [step] if step > counts[-1] else []
    if answer < counts[0]:
        step = max(counts[0] // 2, min_runs)
        return [step] if step < counts[0] else []
    near = int(round(answer))
    if any(abs(near - n) <= 0.1 * n for n in counts):
        return []
    return [near]


def _result(base: StudySpec, cause: str, size: float, power: float,
            rows: list[StudyRow], fit: PowerFit, pilot: SimulatedPilot | None, seed: int,
            replicates: int, min_runs: int, max_runs: int, elapsed_s: float) -> PlanResult:
    parameter = main_parameter(cause)
    curve = []
    for runs in fit.counts:
        group = [row for row in rows if row.runs == runs and row.ok]
        rate = wilson(sum(bool(row.terms[cause].named) for row in group), len(group))
        assert rate.rate is not None and rate.interval is not None  # fit.counts have ok rows
        curve.append(PowerPoint(runs, rate.successes, rate.trials, rate.rate, rate.interval))
    answer = fit.runs_at_target
    what = (f'{cause} with {parameter} {null_value(cause):g} - {size:g}' if null_value(cause)
            else f'{cause} with {parameter} = {size:g}')
    if answer > max_runs or not math.isfinite(answer):
        status, needed = PlanStatus.ABOVE_MAX_RUNS, None
        statement = (f'more than {max_runs} runs are needed to name {what} with '
                     f'{_power_text(power)} power (at {fit.counts[-1]} runs: '
                     f'{curve[-1].power:.0%} of {curve[-1].data_sets} data sets)')
    elif answer <= min_runs:
        status, needed = PlanStatus.AT_MIN_RUNS, min_runs
        statement = (f'{min_runs} runs (the fewest the diagnosis takes) already name {what} '
                     f'with at least {_power_text(power)} power')
    else:
        status, needed = PlanStatus.FOUND, int(math.ceil(answer))
        low, high = (max(value, min_runs) for value in fit.interval_95)
        statement = (f'about {needed} runs name {what} with {_power_text(power)} power (95 % '
                     f'interval {runs_interval_text(low, high)}, from {len(rows)} diagnosed '
                     'data sets)')
    interval_low, interval_high = (float(max(v, min_runs)) if math.isfinite(v) else None
                                   for v in fit.interval_95)
    logistic = LogisticFit(LOGISTIC_MODEL, fit.intercept, fit.slope,
                           fit.runs_at_target if math.isfinite(answer) else None,
                           INTERVAL_METHOD)
    return PlanResult(cause, parameter, size, power, needed, (interval_low, interval_high),
                      status, statement, tuple(curve), logistic, pilot, base.robot,
                      replicates, seed, round(elapsed_s, 2),
                      tuple(sorted(rows, key=lambda row: (row.runs, row.replicate))))


def _power_text(power: float) -> str:
    """Say a requested power as given: 80%, 95%, 99.9999% (not rounded up to 100%)."""
    return f'{100 * power:.6g}%'


def _check_out(out: str | Path | None) -> Path | None:
    """Check that `out` may be written: new, or an empty directory (nothing is created)."""
    if out is None:
        return None
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ParameterError(f'--out {out} exists and is not an empty directory')
    return out


def write_plan(result: PlanResult, out: Path) -> dict[str, Path]:
    """
    Write plan.json, the data sets and power_curve.png to `out`.

    The data sets: table.csv (every diagnosed data set, method 'simulate') or checks.csv
    (every simulated check, method 'model').
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ParameterError(f'--out {out}: cannot create it ({error.strerror})') from None
    model = result.method == PlanMethod.MODEL
    paths = {'plan': out / 'plan.json', 'table': out / ('checks.csv' if model else 'table.csv'),
             'plot': out / 'power_curve.png'}
    paths['plan'].write_text(dumps(result, indent=2) + '\n')
    if model:
        from octoroach_model.studies.plan_model import outcome_rows

        _write_checks(paths['table'], outcome_rows(result.checks))
        plot_model_curve(result, paths['plot'])
    else:
        write_table(paths['table'], result.rows)
        plot_power_curve(result, paths['plot'])
    return paths


def _write_checks(path: Path, rows: list[dict[str, Any]]) -> None:
    """Write the checks as CSV (one row each, the columns of plan_model.CheckOutcome)."""
    import csv
    import io

    from octoroach_model.fileio import write_text_atomic
    from octoroach_model.studies.plan_model import CheckOutcome

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=[f.name for f in fields(CheckOutcome)],
                            lineterminator='\n')
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(path, buffer.getvalue())


def plot_model_curve(result: PlanResult, path: Path) -> None:
    """Plot the calibrated power curve with its band, the checks and the answer."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6.5, 4.5))
    assert isinstance(result.fit, CalibratedFit)
    points = result.fit.curve
    runs = np.array([point.runs for point in points])
    axis.fill_between(runs, [point.low for point in points],
                      [point.high for point in points], color='tab:blue', alpha=0.15,
                      label='95 % band (calibration)')
    axis.plot(runs, [point.power for point in points], color='tab:blue',
              label='predicted power, calibrated')
    axis.plot(runs, [point.predicted for point in points], color='tab:blue', linestyle=':',
              label="the pilots' prediction, before the calibration")
    if result.curve:
        checked = np.array([point.runs for point in result.curve], dtype=float)
        rates = np.array([point.power for point in result.curve])
        below = rates - np.array([point.interval_95[0] for point in result.curve])
        above = np.array([point.interval_95[1] for point in result.curve]) - rates
        axis.errorbar(checked, rates, yerr=[below, above], fmt='o', capsize=4,
                      color='tab:green', label='checks: share named (95 % Wilson)')
    axis.axhline(result.power, color='grey', linestyle='--',
                 label=f'requested power {_power_text(result.power)}')
    if result.runs_needed is not None:
        axis.axvline(result.runs_needed, color='tab:red',
                     label=f'answer: {result.runs_needed} runs')
    axis.set_xscale('log')
    axis.set_ylim(-0.02, 1.02)
    axis.set_xlabel('runs recorded (log scale)')
    axis.set_ylabel('power: probability the cause is named')
    axis.set_title(f'Runs needed: {result.cause}, {result.parameter} = {result.size:g}')
    axis.legend(fontsize=7, loc='lower right')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def plot_power_curve(result: PlanResult, path: Path) -> None:
    """Plot observed power (Wilson intervals), the fitted curve, the target and the answer."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6.5, 4.5))
    runs = np.array([point.runs for point in result.curve], dtype=float)
    rates = np.array([point.power for point in result.curve])
    below = rates - np.array([point.interval_95[0] for point in result.curve])
    above = np.array([point.interval_95[1] for point in result.curve]) - rates
    axis.errorbar(runs, rates, yerr=[below, above], fmt='o', capsize=4, color='tab:blue',
                  label='share of data sets with the cause named (95 % Wilson interval)')
    grid = np.geomspace(min(runs.min(), result.runs_needed or runs.min()) * 0.8,
                        max(runs.max(), result.runs_needed or runs.max()) * 1.25, 200)
    assert isinstance(result.fit, LogisticFit)
    fitted = 1 / (1 + np.exp(-(result.fit.intercept + result.fit.slope * np.log(grid))))
    axis.plot(grid, fitted, color='tab:blue', alpha=0.7, label='logistic fit in ln(runs)')
    axis.axhline(result.power, color='grey', linestyle='--',
                 label=f'requested power {_power_text(result.power)}')
    if result.runs_needed is not None:
        axis.axvline(result.runs_needed, color='tab:red',
                     label=f'answer: {result.runs_needed} runs')
        low, high = result.runs_needed_interval_95
        if low is not None or high is not None:
            axis.axvspan(low or grid[0], high or grid[-1], color='tab:red', alpha=0.12,
                         label='95 % interval of the answer (profile likelihood)')
    axis.set_xscale('log')
    axis.set_ylim(-0.02, 1.02)
    axis.set_xlabel('runs recorded (log scale)')
    axis.set_ylabel('power: share of data sets with the cause named')
    axis.set_title(f'Runs needed: {result.cause}, {result.parameter} = {result.size:g}')
    axis.legend(fontsize=7, loc='lower right')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
