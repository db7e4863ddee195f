"""
A study's summary as typed records: the rates, per arm, per term and per run count.

`studies/summary.py` computes them from the rows; the plots, the `study` command and
benchmarks read their fields. They become summary.json only at the file edge, through
octoroach_model/jsonio.py: field order is the file's key order, a field's metadata names its
key (`json_name`), writes a record's fields in its place (`json_inline`, as a rate inside an
entry) or leaves it out when None (`json_omit_none`). docs/studies.md describes every field.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from octoroach_model.jsonio import OMIT_NONE
from octoroach_model.studies.rows import Status
from octoroach_model.studies.spec import Sign

INLINE = {'json_inline': True}
FALSE_POSITIVE_TARGET = 0.05
# a run-count cell: the count of runs, or 'drawn' (each replicate drew its own)
RunsCell = int | str


@dataclass(frozen=True)
class Rate:
    """k of n, the share, and its 95 % Wilson interval (None for n = 0)."""

    successes: int = field(metadata={'json_name': 'count'})
    trials: int = field(metadata={'json_name': 'data_sets'})
    rate: float | None
    interval: tuple[float, float] | None = field(metadata={'json_name': 'interval_95'})


@dataclass(frozen=True)
class StatusCounts:
    """How many rows the study has, per status, and the first problems (key: note)."""

    rows: int
    counts: Mapping[Status, int]
    first_problems: tuple[str, ...]


@dataclass(frozen=True)
class RateByRuns:
    """A rate over the data sets of one run count."""

    runs: RunsCell
    rate: Rate = field(metadata=INLINE)


@dataclass(frozen=True, kw_only=True)
class FalsePositive:
    """Null data sets in which anything was named: overall, per run count, and what."""

    definition: str = ("share of data sets from the paper's model (no effect) in which "
                       'any cause or extension was named')
    overall: Rate = field(metadata=INLINE)
    target: float = FALSE_POSITIVE_TARGET
    by_runs: tuple[RateByRuns, ...]
    causes_named: Mapping[str, int]


@dataclass(frozen=True, kw_only=True)
class InadequateOnNulls:
    """The adequacy check's false alarms, and which statistics it left unexplained."""

    overall: Rate = field(metadata=INLINE)
    by_runs: tuple[RateByRuns, ...]
    unexplained: Mapping[str, int]


@dataclass(frozen=True, kw_only=True)
class Power:
    """The share of data sets that named a cause put in at an absolute size."""

    cause: str
    parameter: str
    size: float
    sign: Sign
    runs: RunsCell
    named: Rate = field(metadata=INLINE)


@dataclass(frozen=True, kw_only=True)
class PowerAtLimit:
    """
    The share that named a cause put in at a multiple of its reported detection limit.

    With what became of the misses; `target` and `meets_target` at 1 x and 2 x only; how far
    the held-out test got.
    """

    cause: str
    limit_multiple: float
    runs: RunsCell
    median_size: float | None
    named: Rate = field(metadata=INLINE)
    named_or_undecided: Rate
    missed: int
    missed_not_adequate: int
    baseline_inadequate: Rate
    target: str | None = field(default=None, metadata=OMIT_NONE)
    meets_target: bool | None = field(default=None, metadata=OMIT_NONE)
    # the term's held-out t against the t it had to pass, where it was scored: the median of
    # t - t_critical, in how many data sets it was a close call (within CLOSE_CALL_SE of its
    # scoring errors of it: scored again on more runs) and in how many of those the runs
    # scored again turned the decision; None for tables without them
    median_t_margin: float | None = field(default=None, metadata=OMIT_NONE)
    close_calls: int | None = field(default=None, metadata=OMIT_NONE)
    turned: int | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class Estimation:
    """The main parameter's errors where the cause was named; the intervals' coverage."""

    arm: str
    cause: str
    runs: RunsCell
    named: int
    median_abs_relative_error: float | None
    median_relative_error: float | None
    interval_coverage: Rate


@dataclass(frozen=True, kw_only=True)
class Recovery:
    """A `together` arm: every true cause named, each one named, another named too."""

    arm: str
    causes: tuple[str, ...]
    runs: RunsCell
    definition: str = 'share of data sets in which every true cause was named'
    all_named: Rate = field(metadata=INLINE)
    each_named: Mapping[str, Rate]
    other_named: Rate


@dataclass(frozen=True, kw_only=True)
class DetectionLimit:
    """The median detection limit a term reported on null data sets of one run count."""

    cause: str
    parameter: str
    runs: RunsCell
    median_limit: float | None
    reported: int
    data_sets: int


@dataclass(frozen=True, kw_only=True)
class Confusion:
    """Per true cause or term (or none): how many named each one, and reported undecided."""

    definition: str = ('data sets with one true cause or extension term (or none): how many '
                       'named each cause or term; `undecided`: how many reported each beside '
                       'the named one as what the runs cannot tell it from')
    data_sets: Mapping[str, int]
    named: Mapping[str, Mapping[str, int]]
    undecided: Mapping[str, Mapping[str, int]]


@dataclass(frozen=True)
class Timing:
    """Wall time of the tasks (None after a resume), median and total seconds per task."""

    wall_time_s: float | None
    median_task_s: float | None
    total_task_s: float | None


@dataclass(frozen=True)
class StudySummary:
    """What a study measured (summary.json, in this field order)."""

    study: str
    spec_hash: str
    seed: int
    status: StatusCounts
    false_positive: FalsePositive
    inadequate_on_nulls: InadequateOnNulls
    false_causes_with_effects: Rate
    power: tuple[Power, ...]
    power_at_limit_multiples: tuple[PowerAtLimit, ...]
    estimation: tuple[Estimation, ...]
    two_cause_recovery: tuple[Recovery, ...]
    detection_limits: tuple[DetectionLimit, ...]
    confusion: Confusion
    timing: Timing
