"""
The diagnosis report's typed records: what a diagnosis found, and their JSON order.

Field names follow the report's documented form (docs/report.md): `paths`, `baseline`,
`discrepancies`, `candidates`, `cause`, `parameters`, `extended`, `gain`, `causes`,
`adequate`, `unexplained`, and more. Every number is plain data; the fitted models are kept
on the record (for plots and re-use) but written as their tables only. JSON is made at the
file edge only (`jsonio`, report_files.py); summary.py says the report in words.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any, TYPE_CHECKING, TypedDict

import numpy as np
from scipy import stats

from octoroach_model.diagnosis.causes import BY_NAME
from octoroach_model.diagnosis.discrepancies import Discrepancy
from octoroach_model.diagnosis.limits import Limit, METHOD as LIMIT_METHOD
from octoroach_model.jsonio import fields_jsonable, jsonable, OMIT_NONE
from octoroach_model.paths import Paths

if TYPE_CHECKING:
    from octoroach_model.diagnosis.decide import SizeVerdict
    from octoroach_model.diagnosis.misfit import Misfit
    from octoroach_model.diagnosis.modelfit import FittedModel, ModelTable
    from octoroach_model.diagnosis.redraws import DrawAgreement
    from octoroach_model.diagnosis.scoring import Scores
    from octoroach_model.validation.validate import SearchGrid


class LimitMethod(Enum):
    """How a candidate's detection limit (`detectable`) was found."""

    SIZE_BOUND = 'size bound only (before the limit of the whole decision is computed)'
    WHOLE_DECISION = LIMIT_METHOD


class SigmaSource(Enum):
    """Where a model summary's `sigma1`, `sigma2` come from."""

    VALIDATION = "paper's validation: widest admissible spreads (search 15)"
    FITTED = "fitted spreads (the paper's validation did not run"


@dataclass(frozen=True)
class RunLengths:
    """How many runs are complete and how many ended early (and when)."""

    samples: int
    complete: int
    ended_early: int
    ended_early_between_s: tuple[float, float] | None

    @classmethod
    def of(cls, paths: Paths) -> RunLengths:
        lengths = paths.lengths
        early = lengths[lengths < len(paths.t)]
        dt = float(paths.t[1] - paths.t[0]) if len(paths.t) > 1 else 0.0
        between = ((float(early.min() - 1) * dt, float(early.max() - 1) * dt)
                   if early.size else None)
        return cls(len(paths.t), int(np.count_nonzero(lengths == len(paths.t))),
                   int(early.size), between)


@dataclass(frozen=True)
class CandidateResult:
    """One cause at the last step it was weighed: its size, evidence and limit."""

    cause: str
    parameters: dict[str, float | str]   # fitted values (an extension: in its family's form)
    gain: float                  # held-out feature log score gain, nats per run
    gain_se: float
    p_value: float
    relative: float              # share of the current model's gap to the ideal closed
    gain_cm: float               # held-out position energy score gain, cm per run
    interval: dict[str, list[float]]   # main parameter: 95 % interval (calibration half)
    standard_error: float
    lower_bound: float           # one-sided, at the step's level
    floor: float
    detectable: dict[str, float | None]   # main parameter: 80 %-power limit (None: none found)
    detectable_method: LimitMethod
    detectable_power: dict[str, float]   # at the limit: P(size bound clears), P(held-out test)
    clears_floor: bool
    significant: bool
    named_here: bool
    step: int
    statistic: str
    family: str = ''             # the extension family ('' for a cause of the table)
    screened: bool = False       # its bound could not reach the floor: neither refit nor scored
    detectable_caveat: str = ''  # where studies found such a limit not to hold (Cause)
    t_scoring_se: float | None = None   # gain / gain_se: its error from the scored runs alone
    scored_runs: int = 0         # simulated runs per model its held-out test was scored on
    first_t: float | None = None    # a close call's t on the first scored runs (scored again)

    @property
    def held_out_t(self) -> float | None:
        """Return the held-out t, gain / gain_se (None: not scored, or a gain of no spread)."""
        if self.screened or not 0.0 < self.gain_se < float('inf'):
            return None
        return self.gain / self.gain_se

    def with_limit(self, limit: Limit) -> CandidateResult:
        """Return this result with the detection limit of the whole decision (limits.py)."""
        cause = BY_NAME[self.cause]
        return replace(self, detectable={cause.parameter: limit.size},
                       detectable_method=LimitMethod.WHOLE_DECISION,
                       detectable_caveat=cause.limit_caveat if limit.size is not None else '',
                       detectable_power={'size_bound': limit.size_bound_power,
                                         'held_out_test': limit.test_power,
                                         **({} if limit.two_groups_power is None else
                                            {'two_groups': limit.two_groups_power}),
                                         **({} if limit.screen_power is None else
                                            {'screen': limit.screen_power})})


@dataclass(frozen=True)
class Rival:
    """
    A qualifying candidate the chosen one cannot be told apart from on these runs.

    Its fit, its gain, and the two-sided p-value of the paired difference of the two models'
    held-out log scores (not below the test's level: the data do not say which it is).
    """

    cause: str
    family: str
    parameters: dict[str, float | str]
    gain: float
    p_difference: float


@dataclass(frozen=True)
class StepResult:
    """One step of the forward selection: every remaining cause, and which one entered."""

    step: int
    candidates: tuple[CandidateResult, ...]
    chosen: str | None
    decision_z: float           # one-sided normal quantile of the size bounds
    test_level: float           # level of each held-out test
    rival: Rival | None = None  # of the other table (cause vs extension), if undecided


@dataclass(frozen=True)
class NamedCause:
    """A cause the diagnosis names: its sizes refit on all runs, with a 95 % interval."""

    cause: str
    parameters: dict[str, float]
    interval: dict[str, list[float]]
    standard_error: dict[str, float]
    gain: float
    p_value: float
    relative: float
    gain_cm: float
    step: int

    @classmethod
    def of(cls, cause: str, values: Mapping[str, float], verdict: SizeVerdict | None,
           entry: CandidateResult) -> NamedCause:
        parameter = BY_NAME[cause].parameter
        interval = {parameter: list(verdict.interval)} if verdict else entry.interval
        error = {parameter: verdict.standard_error if verdict else entry.standard_error}
        return cls(cause, dict(values), interval, error, entry.gain, entry.p_value,
                   entry.relative, entry.gain_cm, entry.step)


@dataclass(frozen=True)
class NamedExtension:
    """
    An extension family the diagnosis adds to the model: its fit on all runs, in words.

    `parameters` in the family's form (run_order_drift names what drifts), `interval` the 95 %
    interval of each fitted parameter, `description` what it is in the robot's terms, `rival`
    a cause of the table it cannot be told apart from on these runs (both fits reported).
    """

    family: str
    term: str
    parameters: dict[str, float | str]
    interval: dict[str, list[float]]
    standard_error: dict[str, float]
    gain: float
    p_value: float
    relative: float
    gain_cm: float
    step: int
    description: str
    rival: Rival | None = None


def named_by_term(causes: Sequence[NamedCause], extensions: Sequence[NamedExtension]
                  ) -> dict[str, NamedCause | NamedExtension]:
    """Return what a diagnosis names, by term: its causes of the table, then extension terms."""
    named: dict[str, NamedCause | NamedExtension] = {entry.cause: entry for entry in causes}
    named.update({entry.term: entry for entry in extensions})
    return named


class EnergyScores(TypedDict):
    """Held-out position energy scores, cm per run (lower is better), as the report has them."""

    metric: str
    baseline: float
    extended: float
    ideal: float
    relative: float


@dataclass(frozen=True)
class ScoreSummary:
    """Held-out scores of baseline and extended model, and of the data themselves."""

    metric: str
    baseline: float
    extended: float
    ideal: float
    relative: float
    energy_score_cm: EnergyScores

    @classmethod
    def of(cls, baseline: Scores, extended: Scores, ideal: Scores) -> ScoreSummary:
        def share(before: float, after: float, best: float) -> float:
            gap = best - before
            return float((after - before) / gap) if abs(gap) > 1e-12 else 0.0

        b, e, i = (float(np.mean(s.log)) for s in (baseline, extended, ideal))
        bc, ec, ic = (float(np.mean(s.energy_cm)) for s in (baseline, extended, ideal))
        return cls('held-out log score of the run features (each in units of its spread in '
                   'the calibration half, a normal for each under the model, summed), nats '
                   'per run, higher is better. ideal: the calibration runs themselves as the '
                   "model. relative: the share of the baseline's gap to the ideal that the "
                   'extended model closes',
                   b, e, i, share(b, e, i),
                   EnergyScores(metric='held-out energy score of positions at 20/40/60/80/100 '
                                       '% of each run, cm per run, lower is better',
                                baseline=bc, extended=ec, ideal=ic, relative=share(bc, ec, ic)))


@dataclass(frozen=True)
class DecisionRules:
    """The rules a report was decided by, with their levels (the report's `decision`)."""

    alpha: float
    decision_alpha: float
    min_gain: float
    adequacy_alpha: float
    adequacy_z: float

    def to_json(self) -> dict[str, Any]:
        rules: dict[str, Any] = jsonable({
            'selection': 'forward: each step adds the cause that qualifies with the largest '
                         'held-out gain, every included size refit together; stops when none '
                         'qualifies',
            'qualifies': "lower confidence bound of the main parameter above the cause's "
                         'floor (one-sided, level decision_alpha / m), held-out gain '
                         'significant (one-sided paired t-test, level alpha / m) and at least '
                         'min_gain; m = causes still in the race at that step',
            'alpha': self.alpha, 'decision_alpha': self.decision_alpha,
            'min_gain': self.min_gain,
            'adequacy': f'a statistic is unexplained when |z| > {self.adequacy_z:.2f} '
                        f'(Bonferroni at {self.adequacy_alpha} over the statistics) and the '
                        'difference is material',
            'adequacy_alpha': self.adequacy_alpha,
        })
        return rules


@dataclass(frozen=True)
class PaperValidation:
    """
    The paper's search (15) for one model on the measured runs (validation/validate.py).

    The widest admissible spreads [rad], E_k there, n x k, rho, whether any spread was
    admissible, the duration and runs compared, the grid searched, and notes on what was
    left out or lowered.
    """

    sigma1: float
    sigma2: float
    violation: float
    n: int
    k: int
    rho: float
    accepted: bool
    duration_s: float
    grid: SearchGrid | None
    paths_used: int
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        plain = fields_jsonable(self)
        if not self.notes:
            del plain['notes']
        return plain


@dataclass(frozen=True)
class ModelSummary:
    """
    A model as the report shows it (`baseline`, `extended`).

    `sigma1`, `sigma2` are the paper's validation (the widest admissible spreads, search 15)
    when it ran, else the fitted spreads (`sigma_source` says which; `not_validated` why it
    did not run, when it was tried); the fitted spreads are always there too.
    """

    fitted_sigma1: float
    fitted_sigma2: float
    sigma_scale: float
    effects: dict[str, dict[str, float]]
    validation: PaperValidation | None = None
    not_validated: str | None = None

    @property
    def sigma_source(self) -> SigmaSource:
        return SigmaSource.FITTED if self.validation is None else SigmaSource.VALIDATION

    @property
    def sigmas(self) -> tuple[float, float]:
        """Return (sigma1, sigma2) [rad] as the report states them (`sigma_source`)."""
        if self.validation is None:
            return self.fitted_sigma1, self.fitted_sigma2
        return self.validation.sigma1, self.validation.sigma2

    def to_json(self) -> dict[str, Any]:
        summary: dict[str, Any] = {
            'fitted_sigma1': self.fitted_sigma1, 'fitted_sigma2': self.fitted_sigma2,
            'sigma_scale': self.sigma_scale, 'effects': self.effects}
        checked = self.validation
        if checked is not None:
            summary.update(sigma1=checked.sigma1, sigma2=checked.sigma2,
                           violation=checked.violation, accepted=checked.accepted,
                           n=checked.n, k=checked.k, rho=checked.rho,
                           sigma_source=self.sigma_source, validation=checked)
        else:
            reason = f': {self.not_validated})' if self.not_validated is not None else ')'
            summary.update(sigma1=self.fitted_sigma1, sigma2=self.fitted_sigma2,
                           sigma_source=self.sigma_source.value + reason)
        plain: dict[str, Any] = jsonable(summary)
        return plain


@dataclass(frozen=True)
class DiagnosisReport:
    """Everything a diagnosis found (JSON: `to_json`; words: `summary_text`)."""

    paths: int
    duration_s: float
    seed: int
    split: dict[str, int]
    runs: RunLengths
    nominal: ModelTable
    baseline: ModelSummary
    extended: ModelSummary
    discrepancies: tuple[Discrepancy, ...]
    candidates: tuple[CandidateResult, ...]
    causes: tuple[NamedCause, ...]
    extensions: tuple[NamedExtension, ...]
    extension_candidates: tuple[CandidateResult, ...]
    steps: tuple[StepResult, ...]
    gain: ScoreSummary
    extended_discrepancies: tuple[Discrepancy, ...]
    adequate: bool
    unexplained: tuple[Discrepancy, ...]
    adequacy_bound_z: float
    decision: DecisionRules = field(metadata={'json': False})
    baseline_model: FittedModel = field(metadata={'json': False})
    extended_model: FittedModel = field(metadata={'json': False})
    misfit: Misfit | None = None    # where the extended model misses (None when adequate)
    notes: tuple[str, ...] = ()
    # the terms named by other draws of the simulations on the same halves (None: one draw)
    simulation_draws: DrawAgreement | None = field(default=None, metadata=OMIT_NONE)
    stages_s: dict[str, float] = field(default_factory=dict)  # wall time per stage (stages.py)
    elapsed_s: float = 0.0
    sources: tuple[str, ...] = ()

    @property
    def cause(self) -> str:
        """Return the leading cause, or 'none'."""
        return self.causes[0].cause if self.causes else 'none'

    @property
    def parameters(self) -> dict[str, float | str]:
        """Return the parameters of the leading cause, empty when there is none."""
        return dict(self.causes[0].parameters) if self.causes else {}

    @property
    def named_terms(self) -> dict[str, NamedCause | NamedExtension]:
        """Return what the report names, by term (`named_by_term`)."""
        return named_by_term(self.causes, self.extensions)

    def critical_t(self, candidate: CandidateResult) -> float:
        """Return the held-out t `candidate` had to pass at its step (one-sided, its level)."""
        level = self.steps[candidate.step - 1].test_level
        return float(stats.t.isf(level, self.split['held_out'] - 1))

    def to_json(self) -> dict[str, Any]:
        plain = fields_jsonable(self)
        ordered = {key: plain.pop(key) for key in ('paths', 'duration_s', 'seed', 'split',
                                                   'runs', 'nominal', 'baseline')}
        ordered['discrepancies'] = plain.pop('discrepancies')
        ordered['candidates'] = plain.pop('candidates')
        ordered['cause'] = self.cause
        ordered['parameters'] = jsonable(self.parameters)
        ordered['causes'] = plain.pop('causes')
        ordered['extensions'] = plain.pop('extensions')
        ordered['extended'] = plain.pop('extended')
        ordered['gain'] = plain.pop('gain')
        ordered['adequate'] = plain.pop('adequate')
        ordered['unexplained'] = plain.pop('unexplained')
        ordered['misfit'] = plain.pop('misfit')
        ordered['decision'] = jsonable(self.decision)
        ordered.update(plain)
        return ordered
