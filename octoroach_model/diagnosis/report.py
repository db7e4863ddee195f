"""
The diagnosis report: typed records, their JSON (report.json), and summary.md in words.

Field names follow the report's documented form (docs/report.md): `paths`, `baseline`,
`discrepancies`, `candidates`, `cause`, `parameters`, `extended`, `gain`, `causes`,
`adequate`, `unexplained`, and more. Every number is plain data; the fitted models are kept
on the record (for plots and re-use) but written as their tables only.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from pathlib import Path
from typing import Any, TYPE_CHECKING

import numpy as np

from octoroach_model.diagnosis.causes import BY_NAME, MIXTURE_FRACTION
from octoroach_model.diagnosis.discrepancies import Discrepancy
from octoroach_model.diagnosis.limits import Limit, METHOD as LIMIT_METHOD
from octoroach_model.jsonio import dumps, fields_jsonable, jsonable
from octoroach_model.model.extensions import family_form
from octoroach_model.paths import Paths

if TYPE_CHECKING:
    from octoroach_model.diagnosis.decide import SizeVerdict
    from octoroach_model.diagnosis.diagnose import DiagnosisSettings, Evaluation
    from octoroach_model.diagnosis.misfit import Misfit
    from octoroach_model.diagnosis.modelfit import FittedModel
    from octoroach_model.diagnosis.scoring import Scores


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
    parameters: dict
    gain: float                  # held-out feature log score gain, nats per run
    gain_se: float
    p_value: float
    relative: float              # share of the current model's gap to the ideal closed
    gain_cm: float               # held-out position energy score gain, cm per run
    interval: dict               # main parameter: 95 % interval (calibration half)
    standard_error: float
    lower_bound: float           # one-sided, at the step's level
    floor: float
    detectable: dict             # main parameter: 80 %-power limit (None: none found)
    detectable_method: str
    detectable_power: dict       # at the limit: P(size bound clears), P(held-out test)
    clears_floor: bool
    significant: bool
    named_here: bool
    step: int
    statistic: str
    family: str = ''             # the extension family ('' for a cause of the table)
    screened: bool = False       # its bound could not reach the floor: neither refit nor scored

    @classmethod
    def of(cls, evaluation: Evaluation, verdict: SizeVerdict, step: int, significant: bool,
           named_here: bool, relative: float) -> CandidateResult:
        cause = BY_NAME[evaluation.cause]
        values = dict(evaluation.model.effects[evaluation.cause])
        if cause.is_extension:
            values = family_form(evaluation.cause, values)[1]
        limit = verdict.limit
        if cause.kind == 'mixture' and limit is not None:
            # a limit of the spread it adds, stated as the yaw rate of MIXTURE_FRACTION's runs
            limit /= math.sqrt(MIXTURE_FRACTION * (1 - MIXTURE_FRACTION))
        return cls(evaluation.cause, values, evaluation.gain.mean, evaluation.gain.standard_error,
                   evaluation.gain.p_value, relative, evaluation.gain_cm,
                   {cause.parameter: list(verdict.interval)},
                   verdict.standard_error, verdict.lower_bound, verdict.floor,
                   {cause.parameter: limit}, 'size bound only (before the limit '
                   'of the whole decision is computed)', {}, verdict.clears_floor,
                   significant, named_here, step, cause.statistic_name, cause.family,
                   evaluation.screened)

    def with_limit(self, limit: Limit) -> CandidateResult:
        """Return this result with the detection limit of the whole decision (limits.py)."""
        return replace(self, detectable={BY_NAME[self.cause].parameter: limit.size},
                       detectable_method=LIMIT_METHOD,
                       detectable_power={'size_bound': limit.size_bound_power,
                                         'held_out_test': limit.test_power,
                                         **({} if limit.two_groups_power is None else
                                            {'two_groups': limit.two_groups_power})})


@dataclass(frozen=True)
class Rival:
    """
    A qualifying candidate the chosen one cannot be told apart from on these runs.

    Its fit, its gain, and the two-sided p-value of the paired difference of the two models'
    held-out log scores (not below the test's level: the data do not say which it is).
    """

    cause: str
    family: str
    parameters: dict
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
    parameters: dict
    interval: dict
    standard_error: dict
    gain: float
    p_value: float
    relative: float
    gain_cm: float
    step: int

    @classmethod
    def of(cls, cause: str, values: dict, verdict: SizeVerdict | None,
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
    parameters: dict
    interval: dict
    standard_error: dict
    gain: float
    p_value: float
    relative: float
    gain_cm: float
    step: int
    description: str
    rival: Rival | None = None


@dataclass(frozen=True)
class ScoreSummary:
    """Held-out scores of baseline and extended model, and of the data themselves."""

    metric: str
    baseline: float
    extended: float
    ideal: float
    relative: float
    energy_score_cm: dict

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
                   {'metric': 'held-out energy score of positions at 20/40/60/80/100 % of '
                              'each run, cm per run, lower is better',
                    'baseline': bc, 'extended': ec, 'ideal': ic, 'relative': share(bc, ec, ic)})


@dataclass(frozen=True)
class DiagnosisReport:
    """Everything a diagnosis found (JSON: `to_json`; words: `summary_text`)."""

    paths: int
    duration_s: float
    seed: int
    split: dict
    runs: RunLengths
    nominal: dict
    baseline: dict
    extended: dict
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
    settings: DiagnosisSettings = field(metadata={'json': False})
    baseline_model: FittedModel = field(metadata={'json': False})
    extended_model: FittedModel = field(metadata={'json': False})
    misfit: Misfit | None = None    # where the extended model misses (None when adequate)
    notes: tuple[str, ...] = ()
    elapsed_s: float = 0.0
    sources: tuple[str, ...] = ()

    @property
    def cause(self) -> str:
        """Return the leading cause, or 'none'."""
        return self.causes[0].cause if self.causes else 'none'

    @property
    def parameters(self) -> dict:
        """Return the parameters of the leading cause, empty when there is none."""
        return dict(self.causes[0].parameters) if self.causes else {}

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
        ordered['decision'] = jsonable(decision_rules(self.settings, self.adequacy_bound_z))
        ordered.update(plain)
        return ordered


def decision_rules(settings: DiagnosisSettings, adequacy_z: float) -> dict:
    """Return the rules the report was decided by, with their levels."""
    return {
        'selection': 'forward: each step adds the cause that qualifies with the largest '
                     'held-out gain, every included size refit together; stops when none '
                     'qualifies',
        'qualifies': "lower confidence bound of the main parameter above the cause's floor "
                     '(one-sided, level decision_alpha / m), held-out gain significant '
                     '(one-sided paired t-test, level alpha / m) and at least min_gain; m = '
                     'causes still in the race at that step',
        'alpha': settings.alpha, 'decision_alpha': settings.decision_alpha,
        'min_gain': settings.min_gain,
        'adequacy': f'a statistic is unexplained when |z| > {adequacy_z:.2f} (Bonferroni at '
                    f'{settings.adequacy_alpha} over the statistics) and the difference is '
                    'material',
        'adequacy_alpha': settings.adequacy_alpha,
    }


def _percent(share: float) -> str:
    return f'{100 * share:.0f} %' if math.isfinite(share) else 'n/a'


def _unit(unit: str) -> str:
    return f' {unit}' if unit else ''


def _number(value: float | None, digits: int = 3) -> str:
    """
    Format a number as a reader wants it.

    0 where it is below resolution, else `digits` significant
    digits.
    """
    if value is None or not math.isfinite(value):
        return 'n/a'
    if abs(value) < 1e-9:
        return '0'
    return f'{value:.{digits}g}'


def conclusion(report: DiagnosisReport) -> str:
    """
    Return the summary's first line: what to conclude, in plain words.

    Its numbers are the ones the summary gives below (the share of the baseline's gap the
    extended model closes, the position gain: positive when the extended model is better).
    """
    added = [c.cause for c in report.causes] + [e.family for e in report.extensions]
    if not added:
        head = "The paper's model explains these runs: no cause of the table and no extension"
        head += ' improves the prediction of held-out runs by a size that matters'
    else:
        closer = report.gain.energy_score_cm['baseline'] - report.gain.energy_score_cm['extended']
        head = (f"The paper's model misses {_and(added)}: the model extended with "
                f'{"it" if len(added) == 1 else "them"} closes {_percent(report.gain.relative)} '
                "of the baseline's gap to the data on held-out runs, positions "
                f'{_number(abs(closer), 2)} cm per run {"closer" if closer >= 0 else "further"}')
    tail = ('; it explains every statistic' if report.adequate else
            f'; it still misses {len(report.unexplained)} statistic'
            f'{"s" if len(report.unexplained) != 1 else ""} (below)')
    return f'**Conclusion:** {head}{tail}.'


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ', '.join(names[:-1]) + ' and ' + names[-1]


def summary_text(report: DiagnosisReport) -> str:
    """
    Write summary.md in words.

    summary.md: a one-line conclusion, what the model gets wrong, the causes and extensions
    with sizes, what each adds, what is still unexplained, and how small an effect could have
    been seen.
    """
    lines = ['# What the simulation gets wrong', '', conclusion(report), '']
    runs = report.runs
    early = ''
    if runs.ended_early_between_s is not None:
        first, last = runs.ended_early_between_s
        early = (f'; {runs.ended_early} ended early (between {first:.2f} and {last:.2f} s) '
                 'and were used to their end')
    lines.append(f'{report.paths} measured runs of up to {report.duration_s:.2f} s{early}. '
                 f"The paper's model was calibrated on {report.split['calibration']} of them "
                 f"and judged on the other {report.split['held_out']}.")
    lines += ['', "## Where the paper's model disagrees with the data", '']
    off = [row for row in report.discrepancies
           if abs(row.z) > report.adequacy_bound_z and row.material][:6]
    if off:
        for row in off:
            lines.append(f'- {row.statistic}: data {_number(row.data, 4)}{_unit(row.unit)}, '
                         f'model {_number(row.model, 4)}{_unit(row.unit)} (z = {row.z:+.1f})')
    else:
        lines.append('No statistic disagrees materially beyond the adequacy bound '
                     f'(|z| > {report.adequacy_bound_z:.1f}).')
    lines += ['', '## Causes', '']
    if not report.causes:
        lines.append('**None.** No cause of the table improves the prediction of held-out '
                     'runs with a size that clears its floor.')
    for number, named in enumerate(report.causes, 1):
        parameter = BY_NAME[named.cause].parameter
        low, high = named.interval[parameter]
        values = ', '.join(f'{key} = {_number(value)}' for key, value in named.parameters.items())
        lines.append(f'{number}. **{named.cause}** ({values}; 95 % interval of {parameter}: '
                     f'{_number(low)} to {_number(high)}). Adding it improved the held-out '
                     f'log score by {_number(named.gain)} nats per run (p = '
                     f'{named.p_value:.2g}), {_percent(named.relative)} of what the model '
                     f'lacked then; positions {_closer(named.gain_cm)} per run.')
        lines += _rival_lines(named.cause, _rival_of(report, named.cause))
    lines += ['', '## Beyond the table of causes', '']
    if not report.extensions:
        lines.append('**None.** No extension family (run-order drift, heading random walk, '
                     'periodic heading, change point, run mixture) improves the prediction of '
                     'held-out runs with a size that clears its floor.')
    for number, extension in enumerate(report.extensions, 1):
        lines.append(f'{number}. **{extension.family}**: {extension.description}. Adding it '
                     f'improved the held-out log score by {_number(extension.gain)} nats per '
                     f'run (p = {extension.p_value:.2g}), {_percent(extension.relative)} of '
                     f'what the model lacked then; positions {_closer(extension.gain_cm)} '
                     'per run.')
        lines += _rival_lines(extension.family, extension.rival)
    gain = report.gain
    closer = gain.energy_score_cm['baseline'] - gain.energy_score_cm['extended']
    lines += ['', f'Held-out log score per run: baseline {_number(gain.baseline)}, extended '
                  f'{_number(gain.extended)}, the data themselves {_number(gain.ideal)} nats '
                  f'(higher is better): the extended model closes '
                  f"{_percent(gain.relative)} of the baseline's gap. Positions: "
                  f"{_number(gain.energy_score_cm['baseline'])} -> "
                  f"{_number(gain.energy_score_cm['extended'])} cm (energy score, lower is "
                  f'better): {_closer(closer)} per run.']
    lines += ['', '## What the extended model still misses', '']
    if report.adequate:
        lines.append('Nothing material: every statistic of the data agrees with the extended '
                     f'model within the adequacy bound (|z| <= {report.adequacy_bound_z:.1f}).')
    else:
        lines.append('**The extended model is not adequate**: these statistics are still off, '
                     'so the data carry an effect that neither the table of causes nor the '
                     'library of extensions explains (or explains only in part):')
        for row in report.unexplained:
            lines.append(f'- {row.statistic}: data {_number(row.data, 4)}{_unit(row.unit)}, '
                         f'model {_number(row.model, 4)}{_unit(row.unit)} (z = {row.z:+.1f})')
        if report.misfit is not None:
            lines += ['', 'Where to look:'] + report.misfit.words()
    for name, model in (('baseline', report.baseline), ('extended', report.extended)):
        if 'violation' in model:
            lines.append('')
            lines.append(f"Paper's validation of the {name} model (rho = {model['rho']}): "
                         f"widest admissible spread sigma1 = {_number(model['sigma1'])}, "
                         f"sigma2 = {_number(model['sigma2'])} rad at E_k = "
                         f"{_number(model['violation'])}"
                         + ('' if model.get('accepted') else ' (no spread admissible)') + '.')
    lines += ['', '## What could have been seen', '']
    named_terms = {c.cause for c in report.causes} | {e.term for e in report.extensions}
    for candidate in (*report.candidates, *report.extension_candidates):
        if candidate.cause in named_terms:
            continue
        lines.append(_unseen_line(candidate, report.paths))
    if report.notes:
        lines += ['', '## Notes on the input', ''] + [f'- {note}' for note in report.notes]
    return '\n'.join(lines) + '\n'


def _closer(gain_cm: float) -> str:
    """Say a position gain in words: positive when the extended model is better."""
    return f'{_number(abs(gain_cm), 2)} cm ' + ('closer' if gain_cm >= 0 else 'further')


def _rival_of(report: DiagnosisReport, cause: str) -> Rival | None:
    step = next((s for s in report.steps if s.chosen == cause), None)
    return step.rival if step else None


def _rival_lines(chosen: str, rival: Rival | None) -> list[str]:
    if rival is None:
        return []
    values = ', '.join(f'{key} = {_number(value) if isinstance(value, float) else value}'
                       for key, value in rival.parameters.items())
    return [f'   These runs cannot tell it from **{rival.family}** ({values}; held-out gain '
            f'{_number(rival.gain)} nats per run, p = {rival.p_difference:.2g} for the '
            f'difference): {chosen} entered for its larger gain, but either may be what is '
            'there; more runs, or runs that separate the two, would decide.']


def _unseen_line(candidate: CandidateResult, paths: int) -> str:
    """One line of 'What could have been seen' for a cause or family not named."""
    cause = BY_NAME[candidate.cause]
    parameter = cause.parameter
    limit = candidate.detectable[parameter]
    words = [_number(limit), cause.unit, 'from 1' if cause.null != 0 else '']
    text = ('below ' + ' '.join(word for word in words if word) if limit is not None
            else 'of any size on the grid')
    label = cause.label + (f' ({cause.name.split(":", 1)[1]})' if ':' in cause.name else '')
    name = label.replace('_', ' ')
    article = 'an' if name[0] in 'aeiou' else 'a'
    estimate = candidate.parameters.get(parameter)
    shown = _number(estimate) if isinstance(estimate, (int, float)) else 'n/a'
    return (f'- {article} {name} ({parameter}) {text} would go unseen in {paths} runs like '
            f'these (80 % power; estimate here {shown}).')


def write_report(report: DiagnosisReport, out_dir: Path | str, measured: Paths | None = None,
                 plots: bool = True) -> dict[str, Path]:
    """
    Write report.json, summary.md and (with `measured`) the PNG plots into out_dir.

    All at once: they are written into a temporary folder beside out_dir that then takes its
    name (`fileio.atomic_directory`), so an interrupted call leaves the whole report or
    nothing; out_dir must be new or an empty directory. A plot that cannot be drawn is said
    in summary.md, never at the cost of the report.
    """
    from octoroach_model.fileio import atomic_directory, write_text_atomic

    out = Path(out_dir)
    with atomic_directory(out, what='report folder') as folder:
        written: dict[str, Any] = {'report': folder / 'report.json',
                                   'summary': folder / 'summary.md'}
        write_text_atomic(written['report'], dumps(report, indent=2) + '\n')
        summary = summary_text(report)
        if plots and measured is not None:
            from octoroach_model.diagnosis.plots import write_plots
            drawn, errors = write_plots(report, measured, folder)
            written.update(drawn)
            if errors:
                summary += '\n## Plots not drawn\n\n' + ''.join(
                    f'- {name}: {reason}\n' for name, reason in errors.items())
        write_text_atomic(written['summary'], summary)
    return {name: out / Path(path).relative_to(folder) for name, path in written.items()}
