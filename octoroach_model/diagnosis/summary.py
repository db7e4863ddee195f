"""
The diagnosis report in words: summary.md.

A one-line conclusion, what the paper's model gets wrong, the causes and extensions with their
sizes, what each adds, what is still unexplained, and how small an effect could have been
seen; every number is one the report (records.py) holds.
"""
from __future__ import annotations

from collections.abc import Collection
import math

from scipy import stats

from octoroach_model.diagnosis.causes import BY_NAME, Cause
from octoroach_model.diagnosis.decide import close_call, CLOSE_CALL_SE, POWER
from octoroach_model.diagnosis.discrepancies import STATISTICS
from octoroach_model.diagnosis.records import CandidateResult, DiagnosisReport, Rival
from octoroach_model.model.extensions import FAMILY_NAMES


def _percent(share: float) -> str:
    return f'{100 * share:.0f} %' if math.isfinite(share) else 'n/a'


BASELINE_GAP = "the baseline's gap"


def _gap_closed(share: float, gap: str) -> str:
    """
    Say how much of `gap` a model closes: a share past 100 % as 'all of it and more'.

    The ideal is the calibration runs themselves taken as the model (ScoreSummary); a model
    that scores the held-out runs better than they do closes more than the whole gap, which
    a bare '499 %' left a reader to puzzle out.
    """
    if not math.isfinite(share):
        return f'an unmeasured share of {gap}'
    if share > 1:
        return (f'all of {gap} and more ({_percent(share)}: it scores the held-out runs better '
                'than the calibration runs themselves, taken as the model, do)')
    return f'{_percent(share)} of {gap}'


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
    extended model closes, the position gain: positive when the extended model is better);
    where the extended model is not adequate, that what was named may stand in for part of
    an effect no named term explains.
    """
    added = [c.cause for c in report.causes] + [e.family for e in report.extensions]
    if not added and not report.adequate:
        # no term helps, yet statistics stay off: a turn that grows within each run, too small
        # for its family, shows so (benchmarks/bench_out_of_library.py); "explains these
        # runs" would contradict below
        count = len(report.unexplained)
        left = '1 statistic stays' if count == 1 else f'{count} statistics stay'
        return ("**Conclusion:** The paper's model does not explain these runs, and no cause "
                'of the table and no extension improves the prediction of held-out runs by a '
                f'size that matters: {left} off (below), an effect outside the table and the '
                'library, or one too small to be named.')
    if not added:
        head = "The paper's model explains these runs: no cause of the table and no extension"
        head += ' improves the prediction of held-out runs by a size that matters'
    else:
        closer = report.gain.energy_score_cm['baseline'] - report.gain.energy_score_cm['extended']
        head = (f"The paper's model misses {_and(added)}: the model extended with "
                f'{"it" if len(added) == 1 else "them"} closes '
                f'{_gap_closed(report.gain.relative, BASELINE_GAP + " to the data")} on '
                'held-out runs, positions '
                f'{_number(abs(closer), 2)} cm per run {"closer" if closer >= 0 else "further"}')
    tail = ('; it explains every statistic' if report.adequate else
            f'; it still misses {len(report.unexplained)} statistic'
            f'{"s" if len(report.unexplained) != 1 else ""} (below)')
    if added and not report.adequate:
        # an effect outside table and library leaves statistics off, and the terms named
        # beside it may only mimic the part of it they can (a gait speed that swings with a
        # period was named as five terms, none of them there: test_extensions.py)
        tail += (': the runs carry an effect no named term explains (outside the table and '
                 'the library, or too small to be named), and '
                 f'{"it" if len(added) == 1 else "what was named"} may stand in for part of it')
    return f'**Conclusion:** {head}{tail}.'


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ', '.join(names[:-1]) + ' and ' + names[-1]


# the plot of where an extended model that is not adequate misses, over the run (plots.py)
MISFIT_PLOT = 'misfit.png'
STATISTIC_BY_NAME = {statistic.name: statistic for statistic in STATISTICS}


def summary_text(report: DiagnosisReport, plots: Collection[str] = ()) -> str:
    """
    Write summary.md in words.

    summary.md: a one-line conclusion, what the model gets wrong, the causes and extensions
    with sizes, what each adds, what is still unexplained, and how small an effect could have
    been seen. `plots`: the names of the plot files written beside it, which it points to.
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
                     f'{named.p_value:.2g}), '
                     f'{_gap_closed(named.relative, "what the model lacked then")}; positions '
                     f'{_closer(named.gain_cm)} per run.')
        lines += _rival_lines(named.cause, _rival_of(report, named.cause))
    lines += ['', '## Beyond the table of causes', '']
    if not report.extensions:
        lines.append(f'**None.** No extension family ({_family_list()}) improves the '
                     'prediction of held-out runs with a size that clears its floor.')
    for number, extension in enumerate(report.extensions, 1):
        lines.append(f'{number}. **{extension.family}**: {extension.description}. Adding it '
                     f'improved the held-out log score by {_number(extension.gain)} nats per '
                     f'run (p = {extension.p_value:.2g}), '
                     f'{_gap_closed(extension.relative, "what the model lacked then")}; '
                     f'positions {_closer(extension.gain_cm)} '
                     'per run.')
        lines += _rival_lines(extension.family, extension.rival)
    gain = report.gain
    closer = gain.energy_score_cm['baseline'] - gain.energy_score_cm['extended']
    lines += ['', f'Held-out log score per run: baseline {_number(gain.baseline)}, extended '
                  f'{_number(gain.extended)}, the data themselves {_number(gain.ideal)} nats '
                  f'(higher is better): the extended model closes '
                  f'{_gap_closed(gain.relative, BASELINE_GAP)}. Positions: '
                  f"{_number(gain.energy_score_cm['baseline'])} -> "
                  f"{_number(gain.energy_score_cm['extended'])} cm (energy score, lower is "
                  f'better): {_closer(closer)} per run.']
    if report.simulation_draws is not None:
        lines += ['', report.simulation_draws.sentence()]
    lines += _close_call_lines(report)
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
        readers = _reader_lines(report)
        if readers:
            lines += ['', 'Terms that read these statistics, and why they were not named:']
            lines += readers
        if report.misfit is not None:
            lines += ['', 'Where to look:'] + report.misfit.words()
            if MISFIT_PLOT in plots:
                lines.append(f'- {MISFIT_PLOT} draws the runs over time, stride by stride: '
                             'the mean speed, the mean heading change since the first stride '
                             'and its spread across runs, the data beside both models.')
    for name, model in (('baseline', report.baseline), ('extended', report.extended)):
        checked = model.validation
        if checked is not None:
            lines.append('')
            lines.append(f"Paper's validation of the {name} model (rho = {checked.rho}): "
                         f'widest admissible spread sigma1 = {_number(checked.sigma1)}, '
                         f'sigma2 = {_number(checked.sigma2)} rad at E_k = '
                         f'{_number(checked.violation)}'
                         + ('' if checked.accepted else ' (no spread admissible)') + '.')
    lines += ['', '## What could have been seen', '']
    ceiling = spread_ceiling_line(report)
    if ceiling is not None:
        lines.append(ceiling)
    named_terms = set(report.named_terms)
    for candidate in (*report.candidates, *report.extension_candidates):
        if candidate.cause in named_terms:
            continue
        lines.append(_unseen_line(candidate, report.paths))
    if report.notes:
        lines += ['', '## Notes on the input', ''] + [f'- {note}' for note in report.notes]
    if report.stages_s:
        stages = ', '.join(f'{stage.replace("_", " ")} {seconds:.1f} s'
                           for stage, seconds in report.stages_s.items())
        lines += ['', f'Time: {stages} (wall time of each stage).']
    return '\n'.join(lines) + '\n'


def spread_ceiling_line(report: DiagnosisReport) -> str | None:
    """
    Say where the held-out runs are too few for a spread to be named at any size (else None).

    A cause that only widens the spread of one statistic, r times the model's, gains
    -log r + (r^2 - 1) z^2 / 2 in a run's log score (z standard normal): its paired t over n
    held-out runs tends to sqrt(n / 2) however wide it is (docs/diagnosis.md, section 12).
    Below the first step's critical t it is never named; below that plus z(POWER), not with
    POWER. The line says which, and about how many runs in all would let it.
    """
    if not report.steps:
        return None
    held_out, level = int(report.split['held_out']), report.steps[0].test_level
    power_z = float(stats.norm.ppf(POWER))

    def short(runs: int) -> bool:
        return math.sqrt(runs / 2) < float(stats.t.isf(level, runs - 1)) + power_z

    if held_out < 2 or not short(held_out):
        return None
    # the fewest held-out runs that are not short (short falls away as the runs grow: the
    # ceiling rises, the critical t falls), by bisection between held_out and MAX_HELD_OUT
    low, needed = held_out, MAX_HELD_OUT
    if not short(needed):
        while needed - low > 1:
            middle = (low + needed) // 2
            low, needed = (middle, needed) if short(middle) else (low, middle)
    ceiling, critical = math.sqrt(held_out / 2), float(stats.t.isf(level, held_out - 1))
    power = f'{POWER * 100:.0f} % power'
    reach = 'be named at any size' if ceiling < critical else f'reach {power} at any size'
    return (f'- In {held_out} held-out runs, a cause seen only as a wider spread of one '
            f'statistic (as a start heading spread is in short runs) cannot {reach}: its '
            f'held-out t tends to sqrt({held_out} / 2) = {ceiling:.1f} however wide it is, '
            f'against a critical {critical:.2f}; with about {2 * needed} runs in all a wide '
            f'enough one is named with {power}. A cause seen in several statistics, each with '
            f'noise of its own, can pass with fewer (docs/diagnosis.md, section 12).')


# where `spread_ceiling_line` stops looking (the held-out runs a spread needs are ~40)
MAX_HELD_OUT = 10_000


def close_calls(report: DiagnosisReport) -> list[tuple[CandidateResult, float, float]]:
    """
    Return the candidates whose held-out test ended within reach of the simulation's error.

    Those scored again as close calls (`first_t` given: diagnose._settled), and those with a
    `t_scoring_se` (given only where the test decides) whose t = gain / gain_se ended within
    CLOSE_CALL_SE of it of the critical t at their step's level: each with its t and that
    critical value.
    """
    calls = []
    for candidate in (*report.candidates, *report.extension_candidates):
        t = candidate.held_out_t
        if candidate.t_scoring_se is None or t is None:
            continue
        critical = report.critical_t(candidate)
        if candidate.first_t is not None or still_close(candidate, t, critical):
            calls.append((candidate, t, critical))
    return calls


def still_close(candidate: CandidateResult, t: float, critical: float) -> bool:
    """Whether `t` is within CLOSE_CALL_SE of the candidate's scoring error of `critical`."""
    spread = candidate.t_scoring_se
    return spread is not None and close_call(t, critical, spread)


def _close_call_lines(report: DiagnosisReport) -> list[str]:
    """Say which decisions were close to the simulation's error, and how they were settled."""
    calls = close_calls(report)
    if not calls:
        return []
    again = any(candidate.first_t is not None for candidate, _, _ in calls)
    lines = ['', '**Decided close to the threshold**: the held-out test of these terms ended '
                 f'within {CLOSE_CALL_SE:g} standard errors of its critical value, counting '
                 "only the error of t that comes from the models' simulated runs (the held-out "
                 'runs fixed)' + ('; where it says "scored again", the test was then decided on '
                                  'that many simulated runs of both models:' if again else ':')]
    named = report.named_terms
    unsettled = 0
    for candidate, t, critical in calls:
        verdict = 'named' if candidate.cause in named else 'not named'
        first = ('' if candidate.first_t is None else
                 f'{candidate.first_t:.2f} at first, scored again on '
                 f'{candidate.scored_runs} runs: ')
        close = still_close(candidate, t, critical)
        unsettled += close
        lines.append(f'- {candidate.cause} ({verdict}): t = {first}{t:.2f} against '
                     f'{critical:.2f}, simulation error {candidate.t_scoring_se:.2f}'
                     + (' (still close)' if close else ''))
    if unsettled:
        lines.append('Other simulated runs could decide those still close the other way: '
                     '`--simulation-draws 4` shows how often; more runs settle them.')
    return lines


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


def _reader_lines(report: DiagnosisReport) -> list[str]:
    """
    Say which unnamed term is sized from a statistic still off, and why it was not named.

    A statistic left off is often the one a term of the table or the library reads (the
    heading rate against run order is run_order_drift's, yaw rate). Its estimate beside what
    the runs can show, and its held-out test, tell a term the runs show too little from one
    they show but that describes them only in part: on a leg that wears over the session the
    drifts' estimates passed their limits and their tests failed (docs/measured.md). The
    term that alone reads the statistic as its own always gets a line; where others read it
    too (the four worn legs read the distance's trend as their own, and the heading rate's
    beside the yaw rate's drift), they get one only past their limit: four legs within
    theirs say nothing new.
    """
    last = {candidate.cause: candidate
            for candidate in report.candidates + report.extension_candidates}
    lines = []
    for row in report.unexplained:
        statistic = STATISTIC_BY_NAME.get(row.statistic)
        if statistic is None:
            continue
        readers = statistic.read_by()
        own = [cause for cause in readers if statistic.reads(cause.statistic, cause.signature)]
        for cause in readers:
            candidate = last.get(cause.name)
            if candidate is None or cause.name in report.named_terms:
                continue
            if own == [cause] or _past_limit(cause, candidate):
                lines.append(_reader_line(row.statistic, cause, candidate, report))
    return lines


def _past_limit(cause: Cause, candidate: CandidateResult) -> bool:
    """Return whether a candidate's estimate is past what would go unseen in runs like these."""
    estimate = candidate.parameters.get(cause.parameter)
    limit = candidate.detectable.get(cause.parameter)
    return (isinstance(estimate, (int, float)) and math.isfinite(estimate)
            and limit is not None and math.isfinite(limit)
            and abs(estimate - cause.null) >= limit)


def _reader_line(statistic: str, cause: Cause, candidate: CandidateResult,
                 report: DiagnosisReport) -> str:
    """One line of `_reader_lines`: the term, its estimate and limit, its test."""
    estimate = candidate.parameters.get(cause.parameter)
    limit = candidate.detectable.get(cause.parameter)
    size = ''
    past = _past_limit(cause, candidate)
    if isinstance(estimate, (int, float)) and math.isfinite(estimate):
        size = f'its estimate here is {_number(estimate)}{_unit(cause.unit)}'
        if limit is not None and math.isfinite(limit):
            size += (f', {"past" if past else "within"} the {_number(limit)}{_unit(cause.unit)}'
                     f'{" from 1" if cause.null != 0 else ""} that would go unseen in runs like '
                     'these (80 % power); ')
        else:
            size += '; '
    t = candidate.held_out_t
    if t is None or not candidate.clears_floor:
        test = 'its size bound did not clear the floor of a size that matters'
    else:
        critical = report.critical_t(candidate)
        test = (f'adding it did not improve the prediction of held-out runs enough (t = '
                f'{t:.2f} for {critical:.2f})')
        if past:
            test += ': the runs show something it describes only in part'
    return f'- {statistic} is what {_term_words(cause)} reads: {size}{test}.'


def _term_words(cause: Cause) -> str:
    """Return a term as a reader says it: 'run order drift (yaw rate)', 'lateral slip'."""
    label = cause.label + (f' ({cause.name.split(":", 1)[1]})' if ':' in cause.name else '')
    return label.replace('_', ' ')


def _unseen_line(candidate: CandidateResult, paths: int) -> str:
    """One line of 'What could have been seen' for a cause or family not named."""
    cause = BY_NAME[candidate.cause]
    parameter = cause.parameter
    limit = candidate.detectable[parameter]
    words = [_number(limit), cause.unit, 'from 1' if cause.null != 0 else '']
    text = ('below ' + ' '.join(word for word in words if word) if limit is not None
            else 'of any size')
    if cause.limit_stated:
        text += f' ({cause.limit_stated})'
    name = _term_words(cause)
    article = 'an' if name[0] in 'aeiou' else 'a'
    estimate = candidate.parameters.get(parameter)
    shown = _number(estimate) if isinstance(estimate, (int, float)) else 'n/a'
    caveat = f' This limit is {candidate.detectable_caveat}.' if candidate.detectable_caveat \
        else ''
    return (f'- {article} {name} ({parameter}) {text} would go unseen in {paths} runs like '
            f'these (80 % power; estimate here {shown}).{caveat}')


def _family_list() -> str:
    """Name the library's families in words: 'run order drift, ..., yaw rate ramp'."""
    return ', '.join(name.replace('_', ' ') for name in FAMILY_NAMES)
