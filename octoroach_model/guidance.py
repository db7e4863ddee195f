"""
The validator's live guidance, without ROS: what is known so far, and how many runs to go.

A lab recording runs wants to know, run by run, what its question's answer is so far and
when it may stop. The validator node (nodes/validator.py) names the question in parameters
and hands every new state of its runs to a `Guide`, which answers with a `GuidanceAnswer`
(written as JSON through jsonio; docs/ros.md, "Live guidance"). Two kinds of question:

- **a term** (a cause of the table or an extension term) and the size that matters: the
  term is decided again at every look by diagnosis/live.py (nested halves, a held baseline,
  anytime-valid boundaries: naming it at some look when it is not there stays below the
  test's level however often one looks); `runs_needed` is how many more runs the live
  decision needs to name it at that size with the requested power (with a 95 % interval).
  The question is settled when the term is named, or when the 95 % confidence sequence of
  its size lies wholly below the size that matters (`ruled_out`: if it is there, it is
  smaller than what matters).
- **validation at the paper's settings**: n x k runs (eq. 16 with the node's epsilon, delta
  and k), so `runs_needed` is exact.

Either way, the causes and extensions the last full diagnosis (`~/diagnose`) named are listed
beside the live decision, with the run count they were named on.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from datetime import datetime
from enum import StrEnum
import math
import time
from typing import Any, TYPE_CHECKING

from octoroach_model.diagnosis.causes import CANDIDATES
from octoroach_model.errors import OctoroachError, ParameterError
from octoroach_model.jsonio import fields_jsonable, OMIT_NONE
from octoroach_model.paths import Paths
from octoroach_model.settings import setting

if TYPE_CHECKING:
    from octoroach_model.diagnosis.live import Look
    from octoroach_model.diagnosis.records import DiagnosisReport


class QuestionKind(StrEnum):
    """What the parameter `question` asks: nothing (''), the paper's validation, or a term."""

    NONE = ''
    VALIDATION = 'validation'
    TERM = 'term'

    @classmethod
    def of(cls, question: str) -> QuestionKind:
        """Return the kind of the parameter's value (any other value names a term)."""
        return cls(question) if question in (cls.NONE, cls.VALIDATION) else cls.TERM


class GuidanceStatus(StrEnum):
    """Where an answer stands (docs/ros.md, "Live guidance")."""

    WAITING = 'waiting'
    FITTING = 'fitting'
    COLLECTING = 'collecting'
    NAMED = 'named'
    RULED_OUT = 'ruled_out'
    ENOUGH_RUNS = 'enough_runs'


class NamedBy(StrEnum):
    """Which decision named a term: the live decision or the last full diagnosis."""

    LIVE = 'live'
    DIAGNOSIS = 'diagnosis'


@dataclass(frozen=True)
class AskedQuestion:
    """
    The question in an answer: {} (none), {validation: {runs}} or the term and its size.

    Fields that do not belong to the question asked are None and left out of the JSON.
    """

    validation: ValidationTarget | None = field(default=None, metadata=OMIT_NONE)
    term: str | None = field(default=None, metadata=OMIT_NONE)
    parameter: str | None = field(default=None, metadata=OMIT_NONE)
    size: float | None = field(default=None, metadata=OMIT_NONE)
    power: float | None = field(default=None, metadata=OMIT_NONE)
    planned_runs: int | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class ValidationTarget:
    """The runs the paper's validation needs (n x k)."""

    runs: int


@dataclass(frozen=True)
class NamedTerm:
    """
    A term named so far: by the live decision (`since_runs`) or by a diagnosis (`runs`).

    `estimate` and `interval_95` of its main parameter (None where the report has none).
    """

    term: str
    parameter: str
    estimate: float | str | None          # an extension's form may hold words
    interval_95: Sequence[float] | None
    source: NamedBy
    since_runs: int | None = field(default=None, metadata=OMIT_NONE)
    runs: int | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class LastDiagnosis:
    """The last full diagnosis: on how many runs, adequate or not, and what it named."""

    runs: int
    adequate: bool
    named: tuple[NamedTerm, ...] = field(default=(), metadata={'json': False})


@dataclass(frozen=True)
class GuidanceAnswer:
    """
    One answer of the guide (docs/ros.md, "Live guidance"); JSON through jsonio.

    Optional fields are left out while None: `reason` (waiting, fitting), the live look's
    (`decision` and the runs and power it was taken on), `ruled_out_at_runs`, `refitting`
    (True while a baseline is fitted apart) and `diagnosis` (after a full diagnosis). A
    diagnosis that arrives after the answer was made is written last (`diagnosis_last`), where
    it joined the answer.
    """

    question: AskedQuestion
    runs: int
    status: GuidanceStatus
    named: tuple[NamedTerm, ...]
    runs_needed: int | None
    runs_needed_interval_95: tuple[int | None, int | None]
    error: str | None
    reason: str | None = field(default=None, metadata=OMIT_NONE)
    decision: Look | None = field(default=None, metadata=OMIT_NONE)
    calibration_runs: int | None = field(default=None, metadata=OMIT_NONE)
    held_out_runs: int | None = field(default=None, metadata=OMIT_NONE)
    power_now: float | None = field(default=None, metadata=OMIT_NONE)
    ruled_out_at_runs: int | None = field(default=None, metadata=OMIT_NONE)
    refitting: bool | None = field(default=None, metadata=OMIT_NONE)
    decision_runs: int = 0
    diagnosis: LastDiagnosis | None = field(default=None, metadata=OMIT_NONE)
    statement: str = ''
    decided_in_s: float = 0.0
    decided_at: str = ''
    diagnosis_last: bool = field(default=False, metadata={'json': False})

    def to_json(self) -> dict[str, Any]:
        plain = fields_jsonable(self)
        if self.diagnosis_last and 'diagnosis' in plain:
            plain['diagnosis'] = plain.pop('diagnosis')
        return plain


QUESTIONS = (QuestionKind.NONE.value, QuestionKind.VALIDATION.value,
             *(cause.name for cause in CANDIDATES))


@dataclass(frozen=True)
class GuidanceSettings:
    """
    The validator's parameters of live guidance: the one source of their help, unit and range.

    The node's parameters and config/validator.yaml are made from these fields;
    `GuidanceQuestion.from_values` reads the values in force, with these defaults.
    """

    question: str = setting(QuestionKind.NONE.value, 'live guidance on ~/guidance: a cause or '
                            'extension term (with question_size), validation (runs for the '
                            "paper's validation), or empty: none", choices=QUESTIONS)
    question_size: float = setting(0.0, "the size that matters: the term's main parameter "
                                   '(its distance from no effect; run_mixture: the yaw rate of '
                                   '30 % of the runs), in its unit', unit='as the term',
                                   low=0.0, high=1000.0)
    question_power: float = setting(0.8, 'probability with which runs_needed names the term at '
                                    'question_size', low=0.5, high=0.99)
    planned_runs: int = setting(500, 'runs the session is planned to reach: where the live '
                                'decision is least strict (any count stays valid)', low=40,
                                high=1000000)
    guidance_period_s: float = setting(0.25, 'how often the files behind bags are looked at '
                                       'for new runs', unit='s', low=0.05, high=10.0)


DEFAULTS = GuidanceSettings()


@dataclass(frozen=True)
class GuidanceQuestion:
    """The question the node's parameters name (docs/ros.md, "Live guidance")."""

    kind: QuestionKind
    term: str = ''               # the term asked about (kind TERM)
    size: float = 0.0            # the size that matters (terms)
    power: float = 0.8
    planned_runs: int = 500      # where the live boundaries are tightest
    seed: int = 0
    validation_runs: int = 495   # n x k (validation)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> GuidanceQuestion:
        """Make the question from parameter values; ParameterError where they do not fit."""
        from octoroach_model.diagnosis.live import Question
        from octoroach_model.validation import chernoff_sample_size

        asked = str(values.get('question', DEFAULTS.question))
        kind = QuestionKind.of(asked)
        term = asked if kind == QuestionKind.TERM else ''
        size = float(values.get('question_size', DEFAULTS.question_size))
        power = float(values.get('question_power', DEFAULTS.question_power))
        if kind == QuestionKind.TERM:
            Question(term, size if size > 0 else math.nan, power)   # raises with the reason
        n = chernoff_sample_size(float(values['epsilon']), float(values['delta']))
        return cls(kind, term, size, power, int(values.get('planned_runs', DEFAULTS.planned_runs)),
                   int(values.get('seed', 0)), n * int(values['k']))

    @property
    def asked(self) -> bool:
        return self.kind != QuestionKind.NONE


class Guide:
    """
    Answers the question for each new state of the runs (module docstring).

    `refits`: an executor the live decision fits its baselines on while looks go on (a
    process pool in the node); None fits them at the look.
    """

    def __init__(self, question: GuidanceQuestion, refits: Executor | None = None) -> None:
        from octoroach_model.diagnosis.live import LiveDecision, Question

        self.question = question
        self.refits = refits
        self.live = None
        if question.kind == QuestionKind.TERM:
            self.live = LiveDecision(Question(question.term, question.size, question.power),
                                     _settings(question.seed), _levels(question))
        self.diagnosis: LastDiagnosis | None = None
        self.ruled_out_at_runs: int | None = None
        self.latest: GuidanceAnswer | None = None

    def diagnosed(self, report: DiagnosisReport, runs: int) -> None:
        """Keep what a full diagnosis of `runs` runs named, to list beside the live answer."""
        named = []
        for cause in report.causes:
            parameter = next(iter(cause.interval or cause.parameters or {}), '')
            named.append(NamedTerm(cause.cause, parameter, cause.parameters.get(parameter),
                                   cause.interval.get(parameter), NamedBy.DIAGNOSIS, runs=runs))
        for extension in report.extensions:
            parameter = next(iter(extension.interval), '')
            named.append(NamedTerm(extension.term, parameter,
                                   extension.parameters.get(parameter),
                                   extension.interval.get(parameter), NamedBy.DIAGNOSIS,
                                   runs=runs))
        self.diagnosis = LastDiagnosis(runs, bool(report.adequate), tuple(named))
        if self.latest is not None:
            self.latest = self._with_diagnosis(self.latest, late=True)

    def _with_diagnosis(self, answer: GuidanceAnswer, late: bool = False) -> GuidanceAnswer:
        """
        Return the answer with the last diagnosis's named terms after the live ones.

        `late`: the answer was made before the diagnosis, which is then written last (where
        it joined the answer) unless the answer already told of an earlier one.
        """
        named = tuple(entry for entry in answer.named if entry.source != NamedBy.DIAGNOSIS)
        if self.diagnosis is None:
            return replace(answer, named=named)
        return replace(answer, named=named + self.diagnosis.named, diagnosis=self.diagnosis,
                       diagnosis_last=answer.diagnosis_last
                       or late and answer.diagnosis is None)

    def update(self, measured: Paths | None, problem: str | None = None) -> GuidanceAnswer:
        """Return the guidance for the runs so far (None and `problem`: they cannot be read)."""
        started = time.monotonic()
        runs = measured.n_paths if measured is not None else 0
        answer = GuidanceAnswer(self._asked(), runs, GuidanceStatus.WAITING, (), None,
                                (None, None), problem)
        if measured is not None and self.question.kind == QuestionKind.VALIDATION:
            answer = self._validation(answer)
        elif measured is not None and self.live is not None:
            try:
                answer = self._term(answer, measured)
            except OctoroachError as error:
                answer = self._too_few(answer, ' '.join(str(error).split()))
        answer = self._with_diagnosis(replace(answer, decision_runs=runs))
        answer = replace(answer, statement=statement(answer),
                         decided_in_s=round(time.monotonic() - started, 3),
                         decided_at=datetime.now().astimezone().isoformat(
                             timespec='milliseconds'))
        self.latest = answer
        return answer

    def refresh(self, runs: int) -> GuidanceAnswer | None:
        """
        Return the last answer carried to `runs` runs at once, before their look is taken.

        The runs needed in all do not depend on how many are recorded, so `runs_needed` is
        that total less `runs`; what is named stays what the last look decided
        (`decision_runs` says on how many runs). None where there is nothing to carry (no
        decision yet, or a validation question, whose next answer is immediate).
        """
        latest = self.latest
        if latest is None or self.live is None or latest.runs == runs \
                or latest.status not in (GuidanceStatus.COLLECTING, GuidanceStatus.NAMED,
                                         GuidanceStatus.RULED_OUT):
            return None
        total = latest.runs + (latest.runs_needed or 0)
        low, high = latest.runs_needed_interval_95
        answer = replace(
            latest, runs=runs,
            runs_needed=None if latest.runs_needed is None else max(total - runs, 0),
            runs_needed_interval_95=(_carried(latest.runs, low, runs),
                                     _carried(latest.runs, high, runs)))
        return replace(answer, statement=statement(answer) + (
            f' (decided on {latest.decision_runs} runs; the look on {runs} is under way)'),
            decided_at=datetime.now().astimezone().isoformat(timespec='milliseconds'),
            decided_in_s=0.0)

    def _asked(self) -> AskedQuestion:
        question = self.question
        if question.kind == QuestionKind.VALIDATION:
            return AskedQuestion(validation=ValidationTarget(question.validation_runs))
        if not question.asked:
            return AskedQuestion()
        from octoroach_model.diagnosis.causes import BY_NAME

        return AskedQuestion(term=question.term, parameter=BY_NAME[question.term].parameter,
                             size=question.size, power=question.power,
                             planned_runs=question.planned_runs)

    def _validation(self, answer: GuidanceAnswer) -> GuidanceAnswer:
        needed = max(self.question.validation_runs - answer.runs, 0)
        return replace(answer, status=GuidanceStatus.ENOUGH_RUNS if needed == 0
                       else GuidanceStatus.COLLECTING,
                       runs_needed=needed, runs_needed_interval_95=(needed, needed))

    def _too_few(self, answer: GuidanceAnswer, reason: str) -> GuidanceAnswer:
        from octoroach_model.diagnosis.diagnose import MIN_RUNS

        needed = max(MIN_RUNS - answer.runs, 0)
        return replace(answer, status=GuidanceStatus.WAITING, reason=reason,
                       runs_needed=needed or None, runs_needed_interval_95=(needed or None, None))

    def _term(self, answer: GuidanceAnswer, measured: Paths) -> GuidanceAnswer:
        assert self.live is not None
        look = self.live.update(measured, self.refits)
        runs = measured.n_paths
        if look is None:
            return replace(answer, status=GuidanceStatus.FITTING,
                           reason='fitting the baseline on the first runs')
        named_at = self.live.named_at_runs
        if named_at is None and self.ruled_out_at_runs is None \
                and _reach(look) < self.question.size:
            self.ruled_out_at_runs = runs
        answer = replace(answer, decision=look, calibration_runs=look.calibration_runs,
                         held_out_runs=look.held_out_runs, power_now=look.power_now,
                         refitting=True if self.live.fitting else None)
        if named_at is not None:
            return replace(answer, status=GuidanceStatus.NAMED, runs_needed=0,
                           runs_needed_interval_95=(0, 0), named=(NamedTerm(
                               look.term, look.parameter, look.estimate,
                               list(look.interval_95), NamedBy.LIVE, since_runs=named_at),))
        if self.ruled_out_at_runs is not None:
            return replace(answer, status=GuidanceStatus.RULED_OUT, runs_needed=0,
                           runs_needed_interval_95=(0, 0),
                           ruled_out_at_runs=self.ruled_out_at_runs)
        low, high = look.runs_for_power_interval
        return replace(answer, status=GuidanceStatus.COLLECTING,
                       runs_needed=_more(look.runs_for_power, runs),
                       runs_needed_interval_95=(_more(low, runs), _more(high, runs)))

    def close(self) -> None:
        """Nothing to release but the caller's executor (the node shuts it down)."""


def _reach(look: Any) -> float:
    """Return how far from no effect the look's confidence sequence reaches (a size)."""
    from octoroach_model.diagnosis.causes import BY_NAME

    null = BY_NAME[look.term].null
    low, high = look.interval_95
    return max(abs(low - null), abs(high - null))


def _carried(decided_on: int, value: int | None, runs: int) -> int | None:
    """Return runs still needed, decided on `decided_on` runs, now that there are `runs`."""
    return None if value is None else max(decided_on + value - runs, 0)


def _more(total: float | None, runs: int) -> int | None:
    """Return the runs still to record to reach `total` (None: beyond any count)."""
    return None if total is None else max(int(math.ceil(total)) - runs, 0)


def _settings(seed: int) -> Any:
    from octoroach_model.diagnosis import DiagnosisSettings

    return DiagnosisSettings(seed=seed, validate_models=False, detection_limits=False,
                             workers=1)


def _levels(question: GuidanceQuestion) -> Any:
    from octoroach_model.diagnosis.live import Levels

    return Levels.live(_settings(question.seed), question.planned_runs)


def statement(answer: GuidanceAnswer) -> str:
    """Say the guidance in one line, as the latched status's message."""
    runs, status, question = answer.runs, answer.status, answer.question
    if question.validation is not None:
        target = question.validation.runs
        return (f"{runs} runs: enough for the paper's validation (n x k = {target})"
                if status == GuidanceStatus.ENOUGH_RUNS else
                f'{runs} runs: {answer.runs_needed} more for the paper' + "'s validation "
                f'(n x k = {target})')
    if question.term is None or question.size is None or question.power is None:
        return f'{runs} runs; no question asked (set the parameter question)'
    term, size = question.term, question.size
    what = f'{term} at {question.parameter} = {size:g}'
    if status == GuidanceStatus.NAMED:
        live = next(entry for entry in answer.named if entry.source == NamedBy.LIVE)
        assert live.interval_95 is not None
        low, high = live.interval_95
        return (f'{runs} runs: {term} named (since run {live.since_runs}), '
                f'{live.parameter} {live.estimate:.3g} (95 % {low:.3g} to {high:.3g})')
    if status == GuidanceStatus.RULED_OUT:
        assert answer.decision is not None
        low, high = answer.decision.interval_95
        return (f'{runs} runs: {term}, if there, is smaller than {size:g} (95 % '
                f'{low:.3g} to {high:.3g}): the size that matters is ruled out')
    if status in (GuidanceStatus.WAITING, GuidanceStatus.FITTING):
        return f'{runs} runs: {answer.reason or "waiting for runs"}'
    needed, (low_runs, high_runs) = answer.runs_needed, answer.runs_needed_interval_95
    if needed is None:
        return f'{runs} runs: {what} is out of reach of any number of runs here'
    span = f'{low_runs} to {high_runs}' if high_runs is not None else f'at least {low_runs}'
    return (f'{runs} runs: about {needed} more ({span}) to name {what} with '
            f'{question.power:.0%} power')


def guidance_fields(answer: GuidanceAnswer) -> list[tuple[str, str]]:
    """Return the guidance as key/value pairs (the latched DiagnosticStatus's values)."""
    values: list[tuple[str, str]] = [('status', str(answer.status)),
                                     ('runs', str(answer.runs))]
    question = answer.question
    if question.term is not None:
        values += [('question', question.term),
                   (f'question.{question.parameter}', repr(float(question.size or 0.0))),
                   ('question.power', repr(float(question.power or 0.0)))]
    elif question.validation is not None:
        values.append(('question', 'validation'))
    values.append(('runs_needed', _text(answer.runs_needed)))
    low, high = answer.runs_needed_interval_95
    values.append(('runs_needed_interval_95', f'[{_text(low)}, {_text(high)}]'))
    if answer.power_now is not None:
        values.append(('power_now', f'{answer.power_now:.3f}'))
    for number, entry in enumerate(answer.named, 1):
        interval: Sequence[float | None] = entry.interval_95 or (None, None)
        values += [(f'named_{number}', str(entry.term)),
                   (f'named_{number}.{entry.parameter}', _text(entry.estimate)),
                   (f'named_{number}.interval_95', f'[{_text(interval[0])}, '
                                                   f'{_text(interval[1])}]'),
                   (f'named_{number}.source', str(entry.source))]
    decision = answer.decision
    if decision is not None:
        values += [('estimate', _text(decision.estimate)),
                   ('interval_95', f'[{_text(decision.interval_95[0])}, '
                                   f'{_text(decision.interval_95[1])}]'),
                   ('bound_z', f'{decision.bound_z:.3f}'),
                   ('bound_critical_z', f'{decision.bound_critical_z:.3f}'),
                   ('test_z', _text(decision.test_z)),
                   ('test_critical_z', f'{decision.test_critical_z:.3f}')]
    if answer.error:
        values.append(('error', str(answer.error)))
    values += [('decision_runs', str(answer.decision_runs)),
               ('decided_at', str(answer.decided_at)),
               ('decided_in_s', f'{answer.decided_in_s:.3f}')]
    return values


def _text(value: Any) -> str:
    if value is None:
        return 'none'
    if isinstance(value, float):
        return f'{value:.6g}' if math.isfinite(value) else 'none'
    return str(value)


def check_question(values: Mapping[str, Any]) -> str | None:
    """Why the question parameters do not fit together, or None."""
    try:
        GuidanceQuestion.from_values(values)
    except ParameterError as error:
        return f'question: {error}'
    return None
