"""
One task of a study: simulate a data set, diagnose it, and say what came out as a row.

`run_task` is what the Dask workers run (and what the in-process run calls in a loop): a pure
function of the task and the spec (and, for a limit multiple, the row of the replicate's null
data set), so that the table is the same wherever and in whatever order tasks run. A data set
the diagnosis cannot handle is a row with status `error` and the reason, not a failed study.
"""
from __future__ import annotations

from collections.abc import Mapping
import ctypes
from dataclasses import replace
import math
import sys
import time
from typing import Any, NamedTuple, TYPE_CHECKING

from octoroach_model.errors import ParameterError
from octoroach_model.model import check_effects, simulate
from octoroach_model.paths import Paths
from octoroach_model.studies.damage import damage_paths
from octoroach_model.studies.design import (
    DAMAGE, draw_robot, draw_signs, replicate_seeds, RobotDraw, Task)
from octoroach_model.studies.rows import Outcome, Status, StudyRow, TermOutcome
from octoroach_model.studies.spec import ArmKind, Sign, StudySpec
from octoroach_model.studies.table import one_line
from octoroach_model.studies.terms import main_parameter, null_value, term_values, TERMS

if TYPE_CHECKING:
    from octoroach_model.diagnosis import DiagnosisReport
    from octoroach_model.diagnosis.records import CandidateResult


class Skip(Exception):
    """A task that cannot be run for a reason of the design (e.g. no limit to multiply)."""


# glibc's mallopt parameters, and the thresholds a plain process reaches for our arrays
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD_BYTES, TRIM_THRESHOLD_BYTES = 32 * 2 ** 20, 64 * 2 ** 20


def use_large_malloc_thresholds() -> bool:
    """
    Let glibc serve arrays up to 32 MB from its heap, as in a plain process.

    Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536, which pins the mmap
    threshold at 128 kB: every larger array is then mapped and unmapped afresh, and a diagnosis
    runs 2.2 times slower (37.3 s instead of 16.7 s for 424 runs). This undoes it in whatever
    worker runs the task, on any cluster. False where there is no glibc.
    """
    if not sys.platform.startswith('linux'):
        return False
    try:
        libc = ctypes.CDLL('libc.so.6')
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                    and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
    except (OSError, AttributeError):
        return False


def run_task(task: Task, spec: StudySpec, null_row: StudyRow | None = None) -> StudyRow:
    """Simulate, damage and diagnose the task's data set; return its row of the table."""
    use_large_malloc_thresholds()
    started = time.perf_counter()
    draw = draw_robot(spec, task.replicate)
    runs = task.runs(draw)
    row = _empty_row(task, draw, runs)
    try:
        effects = task_effects(task, spec, null_row, draw.duration_s)
        row = replace(row, true_causes=tuple(effects), terms=_truth_terms(effects))
        simulated = simulate_data(spec, draw, runs, effects)
        row = replace(row, duration_s=simulated.duration_s, runs_cut=simulated.runs_cut,
                      frames_dropped=simulated.frames_dropped)
        from octoroach_model.diagnosis import diagnose

        report = diagnose(simulated.paths, task_settings(task, spec, draw.data_seed))
        outcome, terms = read_report(report, effects)
        row = replace(row, outcome=outcome, terms=terms, status=Status.OK)
    except Skip as reason:
        row = replace(row, status=Status.SKIPPED, note=one_line(str(reason)))
    except Exception as error:  # noqa: BLE001 - a data set the diagnosis fails on is a result
        row = replace(row, status=Status.ERROR, note=one_line(f'{type(error).__name__}: {error}'))
    return replace(row, elapsed_s=round(time.perf_counter() - started, 3))


def task_settings(task: Task, spec: StudySpec, seed: int) -> Any:
    """
    Return the task's DiagnosisSettings: the spec's, whole detection limits on nulls only.

    A study reads limits off null data sets alone (the limit multiples, the median limits);
    elsewhere the size bound's own limit is reported, and a quarter of the work is saved.
    """
    settings = spec.diagnosis_settings(seed)
    if task.arm.kind == ArmKind.NULL:
        return settings
    return replace(settings, detection_limits=False)


def task_effects(task: Task, spec: StudySpec, null_row: StudyRow | None,
                 duration_s: float) -> dict[str, dict[str, float]]:
    """
    Return the effects put into the task's data set, signs applied and sizes checked.

    A size is the distance of the main parameter from its value of no effect (change_point's
    speed factor from 1); change_point's time defaults to half the run and run_mixture's
    fraction to 0.3 (studies/terms.py).
    """
    arm = task.arm
    effects = arm.effect_dict()
    if arm.kind in (ArmKind.ABSOLUTE, ArmKind.RELATIVE):
        sign = arm.sign.sides[0] if arm.sign != Sign.BOTH \
            else draw_signs(spec, task.replicate)[arm.cause]
        size = arm.size if arm.kind == ArmKind.ABSOLUTE else _limit_size(task, null_row)
        effects[arm.cause] = term_values(arm.cause, sign * size, effects[arm.cause],
                                         duration_s)
        if arm.kind == ArmKind.RELATIVE:
            try:
                return check_effects(effects)
            except ParameterError as error:     # a multiple of a limit near the term's edge
                raise Skip(f'{arm.limit_multiple:g} times the detection limit on the null data '
                           f'set is past what the model takes ({error})') from error
    else:
        for term, values in effects.items():
            main = main_parameter(term)
            effects[term] = term_values(term, values[main] - null_value(term), values,
                                        duration_s)
    return check_effects(effects)


def _limit_size(task: Task, null_row: StudyRow | None) -> float:
    cause = task.arm.cause
    if null_row is None or null_row.status != Status.OK:
        raise Skip('the null data set of this replicate has no diagnosis to read the limit from')
    limit = null_row.terms[cause].limit
    if not math.isfinite(limit) or limit <= 0:
        raise Skip(f'the diagnosis reported no detection limit for {cause} on the null data '
                   f'set of this replicate')
    return task.arm.limit_multiple * float(limit)


class Simulated(NamedTuple):
    """A task's data set as the diagnosis gets it, and what the damage did to it."""

    paths: Paths
    duration_s: float
    runs_cut: int
    frames_dropped: int


def simulate_data(spec: StudySpec, draw: RobotDraw, runs: int,
                  effects: Mapping[str, Mapping[str, float]]) -> Simulated:
    """Simulate the replicate's robot with `effects`, damaged as the spec says."""
    sigma1, sigma2 = draw.sigmas()
    paths = simulate(runs, seed=draw.data_seed, sigma1=sigma1, sigma2=sigma2,
                     cycles=draw.cycles, parameters=draw.parameters(), effects=effects)
    damaged = damage_paths(paths, spec.damage, replicate_seeds(spec.seed, draw.replicate)[DAMAGE])
    return Simulated(damaged.paths, float(paths.t[-1]), damaged.runs_cut,
                     damaged.frames_dropped)


def read_report(report: DiagnosisReport, effects: Mapping[str, Mapping[str, float]]
                ) -> tuple[Outcome, dict[str, TermOutcome]]:
    """
    Compare what the diagnosis named and estimated with the truth put into the data.

    Causes of the table and extension terms alike (`named` lists both, by term); a size's
    relative error is that of its distance from the value of no effect.
    """
    from octoroach_model.diagnosis.records import named_by_term

    named = named_by_term(report.causes, report.extensions)
    true = list(effects)
    outcome = Outcome(
        named=tuple(named), false_causes=tuple(term for term in named if term not in true),
        all_true_named=all(term in named for term in true) if true else None,
        adequate=bool(report.adequate), unexplained=tuple(
            item.statistic for item in report.unexplained),
        baseline_adequate=_baseline_adequate(report),
        undecided=undecided_terms(report, tuple(named)))
    candidates = {entry.cause: entry
                  for entry in (*report.candidates, *report.extension_candidates)}
    terms = {}
    for term in TERMS:
        main = main_parameter(term)
        entry, candidate = named.get(term), candidates.get(term)
        source = entry if entry is not None else candidate
        estimate = _number(main_value(source.parameters, main)) if source is not None \
            else math.nan
        low, high = (main_value(entry.interval, main) if entry is not None else None) \
            or (None, None)
        truth = effects[term][main] if term in effects else None
        distance = truth - null_value(term) if truth is not None else None
        terms[term] = TermOutcome(
            true=_number(truth), named=entry is not None, estimate=estimate, low=_number(low),
            high=_number(high),
            rel_error=(estimate - truth) / distance
            if truth is not None and distance and math.isfinite(estimate) else math.nan,
            limit=_number(main_value(candidate.detectable, main))
            if candidate is not None else math.nan, **_test_columns(report, candidate),
            **_limit_columns(candidate))
    return outcome, terms


def _limit_columns(candidate: CandidateResult | None) -> dict[str, Any]:
    """Return whether a term's size bound cleared, and its limit's predicted powers."""
    if candidate is None:
        return {}
    predicted = candidate.detectable_power
    return {'clears_floor': candidate.clears_floor,
            'bound_power': _number(predicted.get('size_bound')),
            'test_power': _number(predicted.get('held_out_test'))}


def _test_columns(report: DiagnosisReport, candidate: CandidateResult | None
                  ) -> dict[str, Any]:
    """Return a term's held-out t, the t it had to pass, its scoring error, its first t."""
    t = candidate.held_out_t if candidate is not None else None
    if candidate is None or t is None:
        return {}
    return {'t': t, 't_critical': report.critical_t(candidate),
            't_scoring_se': _number(candidate.t_scoring_se),
            'first_t': _number(candidate.first_t)}


def main_value(values: Mapping[str, Any], main: str) -> Any:
    """
    Return a report's value of a term's main parameter (None where it has none).

    The one place a study reads the report's mappings by parameter (sizes, intervals, limits).
    """
    return values.get(main)


def undecided_terms(report: DiagnosisReport, named: tuple[str, ...]) -> tuple[str, ...]:
    """
    Return the terms reported beside a named one as what the runs cannot tell it from.

    Look-alikes that both qualify at a step (a cause of the table and an extension family, or
    two families), their held-out scores not told apart, are both reported (the chosen one
    named, the other as its rival): the data cannot say which, and the report does not guess.
    """
    return tuple(step.rival.cause for step in report.steps
                 if step.rival is not None and step.chosen in named)


def _baseline_adequate(report: DiagnosisReport) -> bool | None:
    """Return whether the paper's model explained every statistic (as adequacy judges)."""
    bound = report.adequacy_bound_z
    if not math.isfinite(bound):
        return None
    return not any(abs(row.z) > bound and row.material for row in report.discrepancies)


def _truth_terms(effects: Mapping[str, Mapping[str, float]]) -> dict[str, TermOutcome]:
    """Return each term's columns before a diagnosis: its true size (NaN when absent)."""
    return {term: TermOutcome(true=float(effects[term][main_parameter(term)]))
            if term in effects else TermOutcome() for term in TERMS}


def _empty_row(task: Task, draw: RobotDraw, runs: int) -> StudyRow:
    """Return the task's row before anything was run: what the design and the draw say."""
    sigma1, sigma2 = draw.sigmas()
    first, second, third, fourth = (float(angle) for angle in draw.touchdown_angles_deg)
    return StudyRow(
        key=task.key, arm=task.arm.label, kind=task.arm.kind, replicate=task.replicate,
        seed=draw.data_seed, runs=runs, size=float(task.arm.size),
        limit_multiple=float(task.arm.limit_multiple),
        leg_length_cm=float(draw.leg_length_cm), hip_distance_cm=float(draw.hip_distance_cm),
        touchdown_1_deg=first, touchdown_2_deg=second, touchdown_3_deg=third,
        touchdown_4_deg=fourth, stride_frequency_hz=float(draw.stride_frequency_hz),
        cycles=float(draw.cycles), sample_rate_hz=float(draw.sample_rate_hz),
        spread_scale=float(draw.spread_scale), sigma1_rad=float(sigma1),
        sigma2_rad=float(sigma2))


def _number(value: Any) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return math.nan
    return number if math.isfinite(number) else math.nan
