"""
One row of a study's table as a typed record: what was put into a data set and what came out.

A row is built in process from the task, the robot drawn, the simulation and the typed
diagnosis report (studies/replicate.py); the summary, plan and plots read its fields. Only
studies/table.py turns a row into the cells of table.csv and back (docs/studies.md names every
column): `outcome`'s fields are columns of their own, and each term's `TermOutcome` gives the
columns `<field>_<term>`.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
import math

from octoroach_model.studies.spec import ArmKind
from octoroach_model.studies.terms import TERMS


class Status(StrEnum):
    """What became of a task: diagnosed, failed (the note says why) or not run by design."""

    OK = 'ok'
    ERROR = 'error'
    SKIPPED = 'skipped'


@dataclass(frozen=True)
class TermOutcome:
    """
    One term's columns: its size in the data, whether it was named, and what was reported.

    Sizes are the term's main parameter; `rel_error` is the estimate's error relative to the
    true size's distance from the value of no effect; `limit` the detection limit reported;
    `t`, `t_critical` and `t_scoring_se` how far its held-out test got (how far above or below
    its threshold a term at a limit sits, and whether other simulated runs could turn it);
    `first_t` its t before a close call was scored again on more simulated runs;
    `clears_floor` whether its size bound cleared its floor at that step; `bound_power` and
    `test_power` what the detection limit predicted at the limit (diagnosis/limits.py: P(the
    size bound clears), P(the held-out test is significant)), where a whole decision's limit
    was computed (null data sets). NaN where there is nothing to say; `named` and
    `clears_floor` None where the task was not diagnosed.
    """

    true: float = math.nan
    named: bool | None = None
    estimate: float = math.nan
    low: float = math.nan
    high: float = math.nan
    rel_error: float = math.nan
    limit: float = math.nan
    t: float = math.nan              # held-out t at the last step it was weighed
    t_critical: float = math.nan     # what that t had to pass there
    t_scoring_se: float = math.nan   # that t's error from the scored simulated runs
    first_t: float = math.nan        # a close call's t on its first scored runs (scored again)
    clears_floor: bool | None = None    # its size bound cleared the floor at that step
    bound_power: float = math.nan    # the limit's predicted P(size bound clears) at the limit
    test_power: float = math.nan     # the limit's predicted P(held-out test significant) there


NO_TERMS: Mapping[str, TermOutcome] = {term: TermOutcome() for term in TERMS}


@dataclass(frozen=True)
class Outcome:
    """What the diagnosis named and judged, against the truth (None: not diagnosed)."""

    named: tuple[str, ...] = ()
    false_causes: tuple[str, ...] = ()
    all_true_named: bool | None = None
    adequate: bool | None = None
    unexplained: tuple[str, ...] = ()
    baseline_adequate: bool | None = None
    undecided: tuple[str, ...] = ()


@dataclass(frozen=True)
class StudyRow:
    """
    One data set of a study: the task, the robot drawn, the damage, the outcome, the status.

    `terms` holds every term of studies/terms.py (TERMS), in that order.
    """

    key: str
    arm: str
    kind: ArmKind
    replicate: int
    seed: int
    runs: int
    size: float = math.nan
    limit_multiple: float = math.nan
    leg_length_cm: float = math.nan
    hip_distance_cm: float = math.nan
    touchdown_1_deg: float = math.nan
    touchdown_2_deg: float = math.nan
    touchdown_3_deg: float = math.nan
    touchdown_4_deg: float = math.nan
    stride_frequency_hz: float = math.nan
    cycles: float = math.nan
    sample_rate_hz: float = math.nan
    spread_scale: float = math.nan
    sigma1_rad: float = math.nan
    sigma2_rad: float = math.nan
    duration_s: float = math.nan
    runs_cut: int = 0
    frames_dropped: int = 0
    true_causes: tuple[str, ...] = ()
    outcome: Outcome = Outcome()
    terms: Mapping[str, TermOutcome] = field(default_factory=lambda: dict(NO_TERMS))
    status: Status = Status.ERROR
    note: str = ''
    elapsed_s: float = math.nan

    @property
    def ok(self) -> bool:
        """Return whether the data set was diagnosed (only such rows count in a rate)."""
        return self.status == Status.OK
