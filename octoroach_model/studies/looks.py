"""
Deciding again at every look: how often a term is named on data where it is not.

The live decision (diagnosis/live.py) is taken again as the runs come in. A study of it
(`studies/looks.yaml`, run by `benchmarks/bench_looks.py`): each replicate draws a robot as a
study does (studies/design.py: the same seeding), simulates its runs without any effect, and
asks one question of them, the terms taking turns over the replicates (replicate r asks the
r-th term, modulo their number). The question is decided at every `every` runs up to the
study's run count, exactly as the validator decides it (the held baseline fitted again as
the calibration half doubles, the extended model warm-started from the look before); each
look keeps its two statistics (the size bound's distance to the floor in standard errors,
the held-out test's p-value) and the runs in each half, so any decision rule can be applied
to the same looks afterwards (common random numbers):

- **live**: the anytime-valid boundaries of diagnosis/sequential.py (what the validator uses);
- **fixed, every look**: the same decision at the fixed-sample levels at every look (what
  repeating a fixed-sample test does);
- **fixed, last look**: the fixed-sample decision once, at the last look (the level a single
  look has).

A data set counts as a false positive of a rule when the term is named at some look. The
rates come with 95 % Wilson intervals (studies/summary.py).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import csv
from dataclasses import dataclass, field, fields, replace
from enum import StrEnum
import json
import math
from pathlib import Path
import time
from typing import Any, NamedTuple

import numpy as np

from octoroach_model.errors import ParameterError
from octoroach_model.studies.rows import Status
from octoroach_model.studies.spec import parse_spec, StudySpec
from octoroach_model.studies.summary import wilson
from octoroach_model.studies.summary_records import Rate


class Rule(StrEnum):
    """A decision rule applied to the looks (see the module docstring)."""

    LIVE = 'live'
    FIXED_EVERY_LOOK = 'fixed, every look'
    FIXED_LAST_LOOK = 'fixed, last look'


RULES = tuple(Rule)


class Look(NamedTuple):
    """One look: its runs, its halves, and its two statistics (None: not finite)."""

    runs: int
    calibration_runs: int
    held_out_runs: int
    bound_z: float | None
    p_value: float | None
    screened: bool


@dataclass(frozen=True)
class LooksRow:
    """One replicate of a looks study: its robot, its question, and every look at it."""

    key: str
    replicate: int
    term: str
    seed: int = 0
    runs: int = 0
    stride_frequency_hz: float = math.nan
    cycles: float = math.nan
    sample_rate_hz: float = math.nan
    spread_scale: float = math.nan
    status: Status = Status.OK
    note: str = ''
    elapsed_s: float = math.nan
    looks: tuple[Look, ...] = field(default=())

    @property
    def ok(self) -> bool:
        """Return whether every look was taken (only such rows count in a rate)."""
        return self.status == Status.OK


COLUMNS = tuple(column.name for column in fields(LooksRow))


@dataclass(frozen=True)
class LooksSpec:
    """A looks study: a study spec's robot space and seeding, and how to look."""

    study: StudySpec
    every: int
    planned_runs: int
    questions: tuple[str, ...]

    @property
    def max_runs(self) -> int:
        runs = self.study.runs
        assert isinstance(runs, tuple)
        return int(runs[0])

    def term(self, replicate: int) -> str:
        return self.questions[replicate % len(self.questions)]

    def look_counts(self) -> list[int]:
        """Return the run counts looked at: every `every` from the diagnosis's minimum on."""
        from octoroach_model.diagnosis.diagnose import MIN_RUNS

        return [n for n in range(self.every, self.max_runs + 1, self.every) if n >= MIN_RUNS]


def load_looks(path: str | Path) -> LooksSpec:
    """Read a looks spec: a study spec with a `looks:` mapping (every, planned_runs, questions)."""
    from octoroach_model.diagnosis.causes import CANDIDATES
    from octoroach_model.safe_yaml import load_yaml_file

    path = Path(path)
    data = load_yaml_file(path, ParameterError)
    if not isinstance(data, dict) or not isinstance(data.get('looks'), dict):
        raise ParameterError(f'{path}: a looks spec is a study spec with a looks: mapping')
    data = dict(data)
    looks = dict(data.pop('looks'))
    study = parse_spec(data, default_name=path.stem)
    if not isinstance(study.runs, tuple) or len(study.runs) != 1:
        raise ParameterError(f'{path}: runs must be one run count (the last look)')
    known = [cause.name for cause in CANDIDATES]
    questions = looks.get('questions', 'all')
    questions = known if questions == 'all' else list(questions)
    unknown = [term for term in questions if term not in known]
    if unknown or not questions:
        raise ParameterError(f'{path}: unknown questions {unknown}; known: {", ".join(known)}')
    every = int(looks.get('every', 25))
    if every < 1:
        raise ParameterError(f'{path}: every must be a positive number of runs')
    return LooksSpec(study, every, int(looks.get('planned_runs', 500)), tuple(questions))


def looks_task(spec: LooksSpec, replicate: int) -> LooksRow:
    """Simulate replicate `replicate`'s null runs and decide its question at every look."""
    from octoroach_model.diagnosis.live import (
        calibration_mask, decide, fit_held, Levels, Question, REFIT_GROWTH)
    from octoroach_model.studies.design import draw_robot
    from octoroach_model.studies.replicate import simulate_data, use_large_malloc_thresholds

    use_large_malloc_thresholds()
    started = time.perf_counter()
    draw = draw_robot(spec.study, replicate)
    term = spec.term(replicate)
    row = LooksRow(f'{term}/r{replicate}', replicate, term, draw.data_seed, spec.max_runs,
                   draw.stride_frequency_hz, draw.cycles, draw.sample_rate_hz,
                   draw.spread_scale)
    looks: list[Look] = []
    try:
        runs = simulate_data(spec.study, draw, spec.max_runs, {}).paths
        settings = replace(spec.study.diagnosis_settings(draw.data_seed), workers=1,
                           detection_limits=False)
        # the size only sets runs_needed, which a false-positive study does not use
        question = Question(term, 1.0)
        levels = Levels.fixed(settings)        # screens least: valid for every rule
        held, warm = None, None
        for count in spec.look_counts():
            measured = runs.subset(np.arange(count))
            calibration = int(calibration_mask(measured, settings.seed).sum())
            if held is None or calibration >= REFIT_GROWTH * held.calibration_runs:
                held, warm = fit_held(measured, question, settings, with_power=False), None
            look = decide(measured, held, question, settings, levels, warm=warm)
            if look.extended is not None and not look.screened:
                warm = look.extended
            looks.append(Look(look.runs, look.calibration_runs, look.held_out_runs,
                              _plain(look.bound_z), _plain(look.p_value), bool(look.screened)))
    except Exception as error:  # noqa: BLE001 - a data set that fails is a row, not a crash
        row = replace(row, status=Status.ERROR, note=f'{type(error).__name__}: {error}')
    return replace(row, looks=tuple(looks), elapsed_s=round(time.perf_counter() - started, 3))


def _plain(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


class FirstLooks(NamedTuple):
    """The runs of the first look at which a rule names the term, and meets each criterion."""

    named: int | None
    bound: int | None
    test: int | None


@dataclass(frozen=True)
class RuleRates:
    """Under one rule: the share named at some look, per criterion, and per kind of term."""

    named: Rate
    bound: Rate
    test: Rate
    by_kind: Mapping[str, Rate]


@dataclass(frozen=True)
class LooksSummary:
    """What a looks study measured: its data sets, its looks, the rates under each rule."""

    data_sets: int
    errors: int
    looks: tuple[int, ...]
    rules: Mapping[Rule, RuleRates]


def named_at(looks: Sequence[Sequence[Any]], rule: Rule, settings_alpha: tuple[float, float],
             planned_runs: int) -> FirstLooks:
    """
    Return the runs of the first look at which a rule names the term (None: never).

    And the same for each of its two criteria alone (`bound`, `test`).
    """
    from octoroach_model.diagnosis.sequential import Boundary

    decision_alpha, alpha = settings_alpha
    anytime = rule == Rule.LIVE
    bound = Boundary(decision_alpha, anytime, planned_runs / 2)
    test = Boundary(alpha, anytime, planned_runs / 2)
    chosen = looks[-1:] if rule == Rule.FIXED_LAST_LOOK else looks
    first = FirstLooks(None, None, None)
    for runs, calibration, held_out, bound_z, p_value, _ in chosen:
        clears = bound_z is not None and bound_z > bound.z(calibration)
        significant = p_value is not None and p_value < test.p(held_out)
        first = FirstLooks(*(
            int(runs) if met and earlier is None else earlier
            for earlier, met in zip(first, (clears and significant, clears, significant))))
    return first


def summarize(spec: LooksSpec, rows: Sequence[LooksRow]) -> LooksSummary:
    """Return, per rule, the share of data sets named at some look (and per criterion)."""
    settings = spec.study.diagnosis_settings(0)
    levels = (settings.decision_alpha, settings.alpha)
    ok = [row for row in rows if row.ok and row.looks]
    rules = {}
    for rule in RULES:
        firsts = [named_at(row.looks, rule, levels, spec.planned_runs) for row in ok]
        named, bound, test = (wilson(sum(getattr(first, criterion) is not None
                                         for first in firsts), len(ok))
                              for criterion in FirstLooks._fields)
        rules[rule] = RuleRates(named, bound, test, _by_kind(ok, firsts))
    return LooksSummary(len(ok), len(rows) - len(ok), tuple(spec.look_counts()), rules)


def _by_kind(rows: Sequence[LooksRow], firsts: Sequence[FirstLooks]) -> dict[str, Rate]:
    from octoroach_model.diagnosis.causes import BY_NAME

    groups: dict[str, list[bool]] = {}
    for row, first in zip(rows, firsts):
        kind = 'causes' if not BY_NAME[row.term].is_extension else 'extensions'
        groups.setdefault(kind, []).append(first.named is not None)
    return {kind: wilson(sum(named), len(named)) for kind, named in groups.items()}


def table_text(spec: LooksSpec, summary: LooksSummary) -> str:
    """Return the summary as the Markdown table README shows."""
    counts = summary.looks
    lines = [f'{summary.data_sets} null data sets (one question each, {len(spec.questions)} '
             f'terms in turn), looks at {counts[0]}, {counts[1]}, ... {counts[-1]} runs '
             f'({len(counts)} looks)', '',
             '| decision | named at some look (95 % interval) | size bound cleared at some '
             'look | test significant at some look |', '| --- | --- | --- | --- |']
    for rule in RULES:
        entry = summary.rules[rule]
        cells = [_rate_text(rate) for rate in (entry.named, entry.bound, entry.test)]
        lines.append(f'| {rule} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def _rate_text(rate: Rate) -> str:
    if not rate.trials or rate.rate is None or rate.interval is None:
        return '-'
    low, high = rate.interval
    return (f'{rate.successes}/{rate.trials} = {100 * rate.rate:.1f} % '
            f'({100 * low:.1f}-{100 * high:.1f} %)')


def read_rows(path: Path) -> list[LooksRow]:
    """Read the rows written so far (a cut-off last line is dropped)."""
    if not path.exists():
        return []
    rows = []
    with path.open(newline='') as stream:
        for cells in csv.DictReader(stream):
            try:
                rows.append(_row_of(cells))
            except (ValueError, TypeError):
                continue
    return rows


def _row_of(cells: Mapping[str, str]) -> LooksRow:
    """Return the row of rows.csv's cells: the looks as JSON, an empty number a default."""
    def number(name: str, kind: type = float) -> Any:
        return kind(cells[name]) if cells[name] else (math.nan if kind is float else 0)

    return LooksRow(cells['key'], int(cells['replicate']), cells['term'], number('seed', int),
                    number('runs', int), number('stride_frequency_hz'), number('cycles'),
                    number('sample_rate_hz'), number('spread_scale'), Status(cells['status']),
                    cells['note'], number('elapsed_s'),
                    tuple(Look(*look) for look in json.loads(cells['looks'])))


def append_row(path: Path, row: LooksRow) -> None:
    """Append one row (flushed), writing the header first to a new file."""
    new = not path.exists()
    with path.open('a', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\n')
        if new:
            writer.writerow(COLUMNS)
        writer.writerow([json.dumps([list(look) for look in row.looks]) if name == 'looks'
                         else getattr(row, name) for name in COLUMNS])
        stream.flush()
