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
from typing import Any

from octoroach_model.jsonio import jsonable
from octoroach_model.model import check_effects, simulate
from octoroach_model.paths import Paths
from octoroach_model.studies.damage import damage_paths
from octoroach_model.studies.design import (
    DAMAGE, draw_robot, draw_signs, replicate_seeds, RobotDraw, Task)
from octoroach_model.studies.spec import StudySpec
from octoroach_model.studies.table import COLUMN_NAMES, typed_row
from octoroach_model.studies.terms import column, main_parameter, null_value, term_values, TERMS

OK, ERROR, SKIPPED = 'ok', 'error', 'skipped'


class Skip(Exception):
    """A task that cannot be run for a reason of the design (e.g. no limit to multiply)."""


def report_fields(report: Any) -> dict[str, Any]:
    """Return the report's JSON fields, which a row reads (where a study meets a report)."""
    return jsonable(report.to_json())


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


def run_task(task: Task, spec: StudySpec, null_row: Mapping[str, Any] | None = None
             ) -> dict[str, Any]:
    """Simulate, damage and diagnose the task's data set; return its row of the table."""
    use_large_malloc_thresholds()
    started = time.perf_counter()
    draw = draw_robot(spec, task.replicate)
    runs = task.runs_cell if task.runs_cell is not None else draw.runs
    assert runs is not None  # without run-count cells, every replicate draws its own count
    row = _empty_row(task, spec, draw, runs)
    try:
        effects = task_effects(task, spec, null_row, draw.cycles / draw.stride_frequency_hz)
        row.update(_truth_columns(effects, task))
        measured = simulate_data(spec, draw, runs, effects, row)
        from octoroach_model.diagnosis import diagnose

        report = report_fields(diagnose(measured, task_settings(task, spec, draw.data_seed)))
        row.update(outcome_columns(report, effects))
        row['status'] = OK
    except Skip as reason:
        row.update(status=SKIPPED, note=str(reason))
    except Exception as error:  # noqa: BLE001 - a data set the diagnosis fails on is a result
        row.update(status=ERROR, note=f'{type(error).__name__}: {error}')
    row['elapsed_s'] = round(time.perf_counter() - started, 3)
    return typed_row(row)


def task_settings(task: Task, spec: StudySpec, seed: int) -> Any:
    """
    Return the task's DiagnosisSettings: the spec's, whole detection limits on nulls only.

    A study reads limits off null data sets alone (the limit multiples, the median limits);
    elsewhere the size bound's own limit is reported, and a quarter of the work is saved.
    """
    settings = spec.diagnosis_settings(seed)
    if task.arm.kind == 'null':
        return settings
    return replace(settings, detection_limits=False)


def task_effects(task: Task, spec: StudySpec, null_row: Mapping[str, Any] | None,
                 duration_s: float) -> dict[str, dict[str, float]]:
    """
    Return the effects put into the task's data set, signs applied and sizes checked.

    A size is the distance of the main parameter from its value of no effect (change_point's
    speed factor from 1); change_point's time defaults to half the run and run_mixture's
    fraction to 0.3 (studies/terms.py).
    """
    arm = task.arm
    effects = arm.effect_dict()
    if arm.kind in ('absolute', 'relative'):
        sign = {'positive': 1.0, 'negative': -1.0}.get(
            arm.sign, draw_signs(spec, task.replicate)[arm.cause])
        size = arm.size if arm.kind == 'absolute' else _limit_size(task, null_row)
        effects[arm.cause] = term_values(arm.cause, sign * size, effects[arm.cause],
                                         duration_s)
    else:
        for term, values in effects.items():
            main = main_parameter(term)
            effects[term] = term_values(term, values[main] - null_value(term), values,
                                        duration_s)
    return check_effects(effects)


def _limit_size(task: Task, null_row: Mapping[str, Any] | None) -> float:
    cause = task.arm.cause
    if null_row is None or null_row.get('status') != OK:
        raise Skip('the null data set of this replicate has no diagnosis to read the limit from')
    limit = null_row.get(f'limit_{column(cause)}')
    if limit is None or not math.isfinite(limit) or limit <= 0:
        raise Skip(f'the diagnosis reported no detection limit for {cause} on the null data '
                   f'set of this replicate')
    return task.arm.limit_multiple * float(limit)


def simulate_data(spec: StudySpec, draw: RobotDraw, runs: int,
                  effects: Mapping[str, Mapping[str, float]], row: dict[str, Any]) -> Paths:
    """
    Simulate the replicate's robot with `effects`, damaged as the spec says.

    The damage counts and the duration go into `row`.
    """
    sigma1, sigma2 = draw.sigmas()
    paths = simulate(runs, seed=draw.data_seed, sigma1=sigma1, sigma2=sigma2,
                     cycles=draw.cycles, parameters=draw.parameters(), effects=effects)
    damaged = damage_paths(paths, spec.damage, replicate_seeds(spec.seed, draw.replicate)[DAMAGE])
    row.update(runs_cut=damaged.runs_cut, frames_dropped=damaged.frames_dropped,
               duration_s=float(paths.t[-1]))
    return damaged.paths


def outcome_columns(report: Mapping[str, Any], effects: Mapping[str, Mapping[str, float]]
                    ) -> dict[str, Any]:
    """
    Compare what the diagnosis named and estimated with the truth put into the data.

    Causes of the table and extension terms alike (`named` lists both, by term); a size's
    relative error is that of its distance from the value of no effect.
    """
    named_entries = {entry['cause']: entry for entry in report['causes']}
    named_entries.update({entry['term']: entry for entry in report.get('extensions') or []})
    candidates = {entry.get('cause'): entry for entry in (
        *report['candidates'], *(report.get('extension_candidates') or []))}
    named = [entry['cause'] for entry in report['causes']] + [
        entry['term'] for entry in report.get('extensions') or []]
    true = list(effects)
    columns: dict[str, Any] = {
        'named': named, 'undecided': undecided_terms(report, named),
        'false_causes': [cause for cause in named if cause not in true],
        'all_true_named': all(cause in named for cause in true) if true else None,
        'adequate': report.get('adequate'),
        'baseline_adequate': _baseline_adequate(report),
        'unexplained': [item.get('statistic', '?') if isinstance(item, Mapping) else str(item)
                        for item in report.get('unexplained') or []],
    }
    for cause in TERMS:
        main, key = main_parameter(cause), column(cause)
        entry = named_entries.get(cause)
        candidate = candidates.get(cause, {})
        source = entry if entry is not None else candidate
        estimate = _number((source.get('parameters') or {}).get(main))
        interval = ((entry or {}).get('interval') or {}).get(main) or [None, None]
        truth = effects.get(cause, {}).get(main)
        distance = truth - null_value(cause) if truth is not None else None
        columns[f'named_{key}'] = entry is not None
        columns[f'estimate_{key}'] = estimate
        columns[f'low_{key}'] = _number(interval[0])
        columns[f'high_{key}'] = _number(interval[1])
        columns[f'limit_{key}'] = _number((candidate.get('detectable') or {}).get(main))
        columns[f'rel_error_{key}'] = (estimate - truth) / distance \
            if truth is not None and distance and math.isfinite(estimate) else math.nan
    return columns


def undecided_terms(report: Mapping[str, Any], named: list[str]) -> list[str]:
    """
    Return the terms reported beside a named one as what the runs cannot tell it from.

    Look-alikes that both qualify at a step (a cause of the table and an extension family, or
    two families), their held-out scores not told apart, are both reported (the chosen one
    named, the other as its rival): the data cannot say which, and the report does not guess.
    """
    return [step['rival']['cause'] for step in report.get('steps') or []
            if step.get('rival') and step.get('chosen') in named]


def _baseline_adequate(report: Mapping[str, Any]) -> bool | None:
    """Return whether the paper's model explained every statistic (as adequacy judges)."""
    bound = report.get('adequacy_bound_z')
    rows = report.get('discrepancies')
    if bound is None or rows is None:
        return None
    return not any(abs(row.get('z', 0.0)) > bound and row.get('material') for row in rows)


def _truth_columns(effects: Mapping[str, Mapping[str, float]], task: Task) -> dict[str, Any]:
    columns: dict[str, Any] = {'true_causes': list(effects)}
    for cause in TERMS:
        columns[f'true_{column(cause)}'] = effects[cause][main_parameter(cause)] \
            if cause in effects else math.nan
    return columns


def _empty_row(task: Task, spec: StudySpec, draw: RobotDraw, runs: int) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(COLUMN_NAMES)
    sigma1, sigma2 = draw.sigmas()
    row.update({
        'key': task.key, 'arm': task.arm.label, 'kind': task.arm.kind,
        'replicate': task.replicate, 'seed': draw.data_seed, 'runs': runs,
        'size': task.arm.size, 'limit_multiple': task.arm.limit_multiple,
        'leg_length_cm': draw.leg_length_cm, 'hip_distance_cm': draw.hip_distance_cm,
        'stride_frequency_hz': draw.stride_frequency_hz, 'cycles': draw.cycles,
        'sample_rate_hz': draw.sample_rate_hz, 'spread_scale': draw.spread_scale,
        'sigma1_rad': sigma1, 'sigma2_rad': sigma2, 'runs_cut': 0, 'frames_dropped': 0,
        'true_causes': [], 'named': [], 'undecided': [], 'false_causes': [], 'unexplained': [],
        'note': '', 'status': ERROR,
    })
    for number, angle in enumerate(draw.touchdown_angles_deg, 1):
        row[f'touchdown_{number}_deg'] = angle
    for cause in TERMS:
        row[f'named_{column(cause)}'] = None
    return row


def _number(value: Any) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return math.nan
    return number if math.isfinite(number) else math.nan
