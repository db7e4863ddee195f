"""
What the diagnosis can do, measured by studies, and what a study costs to run.

Two parts:

- `--scale` (what `make bench` runs): studies/scale.yaml with 1 and with 2 local Dask workers;
  prints the wall times, the speed-up, the cost of one data set, and the data sets per hour a
  64-core cluster would diagnose, derived from these (64 workers at the measured per-worker
  efficiency). With `--limit-terms TERM ...` the null data sets compute those terms' detection
  limits alone (a study that reads no others), not every term's.
- `--studies` (hours on this machine): runs the studies of docs/measured.md (false_positives,
  power, limits, two_causes, wide_robots in studies/) into out/studies/NAME, resuming any that an
  earlier call left unfinished, and prints their tables from their summary.json. With
  `--report-only` it prints the tables of the studies already in out/studies, also of a study
  kept under another name after a change (`--studies ramp_limits_7358d86`: the spec named in
  its study.json, which must still be the one in studies/). With `--compare OTHER` it then
  sets each study's null limits beside OTHER's, data set by data set (the same spec run at
  another commit, say): how the limits moved, and which data sets were decided otherwise.

Run: .venv/bin/python benchmarks/bench_studies.py [--scale [--limit-terms TERM ...]]
     [--studies [NAME ...]]
     [--workers N | --scheduler ADDRESS] [--report-only [--compare OTHER]]
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import statistics
import sys
import tempfile
import time
from typing import TYPE_CHECKING

import yaml

if TYPE_CHECKING:
    from octoroach_model.studies.rows import StudyRow
    from octoroach_model.studies.spec import StudySpec
    from octoroach_model.studies.summary_records import (
        Estimation, InadequateOnNulls, Rate, RateByRuns, Recovery, StudySummary)

REPO = Path(__file__).resolve().parents[1]
SPECS = REPO / 'studies'
OUT = REPO / 'out' / 'studies'
README_STUDIES = ('false_positives', 'power', 'limits', 'two_causes', 'wide_robots', 'open_world',
                  'adequacy', 'ramp_limits', 'touchdown_limits', 'drift_confusion')
CLUSTER_CORES = 64


def measure_scale(workers: tuple[int, ...] = (1, 2), limit_terms: tuple[str, ...] = ()
                  ) -> dict[int, dict]:
    """
    Wall time of studies/scale.yaml with each number of local workers.

    With `limit_terms`, its null data sets compute those terms' detection limits alone
    (diagnosis.limit_terms), not every term's.
    """
    import octoroach_model as om

    spec = yaml.safe_load((SPECS / 'scale.yaml').read_text())
    if limit_terms:
        spec['diagnosis'] = {**spec.get('diagnosis', {}), 'limit_terms': list(limit_terms)}
    results = {}
    for count in workers:
        with tempfile.TemporaryDirectory() as folder:
            started = time.perf_counter()
            result = om.run_study(spec, Path(folder) / 'scale', workers=count, plots=False)
            total = time.perf_counter() - started
        timing = result.summary.timing
        results[count] = {'tasks': result.rows, 'wall_s': timing.wall_time_s,
                          'with_start_s': total, 'median_task_s': timing.median_task_s}
    return results


def print_scale(results: dict[int, dict], limit_terms: tuple[str, ...] = ()) -> None:
    """Print the README's scale table and the cluster figures derived from it."""
    one, two = results[1], results[2]
    per_data_set = one['wall_s'] / one['tasks']
    speed_up = one['wall_s'] / two['wall_s']
    efficiency = speed_up / 2
    per_hour = CLUSTER_CORES * efficiency * 3600 / per_data_set
    limits = (f', the nulls computing the detection limits of {", ".join(limit_terms)} alone'
              if limit_terms else '')
    print(f'studies/scale.yaml: {one["tasks"]} data sets of 500 runs (Table II robot)'
          f'{limits}\n')
    print('| local workers | wall time, s (cluster start-up) | per data set, s |')
    print('| --- | --- | --- |')
    for count, result in sorted(results.items()):
        start_up = result['with_start_s'] - result['wall_s']
        print(f'| {count} | {result["wall_s"]:.1f} ({start_up:.1f}) | '
              f'{result["wall_s"] / result["tasks"]:.1f} |')
    print(f'\nspeed-up with 2 workers: {speed_up:.2f} (efficiency {efficiency:.0%} per worker)')
    print(f'one data set on one worker: {per_data_set:.1f} s')
    print(f'a {CLUSTER_CORES}-core cluster at this efficiency: about {per_hour:,.0f} data sets '
          f'per hour ({CLUSTER_CORES} x {efficiency:.2f} x 3600 s / {per_data_set:.1f} s); '
          f'the 200 data sets of studies/false_positives.yaml in about '
          f'{200 / per_hour * 60:.0f} min (their runs vary: 150-1000)')


def run_studies(names: list[str], workers: int | None, scheduler: str | None) -> None:
    """Run (or resume) each named study into out/studies/NAME."""
    import octoroach_model as om
    from octoroach_model.commands.study import ProgressBar

    for name in names:
        out = OUT / name
        resume = (out / 'study.json').exists()
        started = time.perf_counter()
        om.run_study(SPECS / f'{name}.yaml', out, workers=workers, scheduler=scheduler,
                     resume=resume, progress=ProgressBar(name))
        elapsed = time.perf_counter() - started
        (out / 'bench_wall_time_s.txt').write_text(f'{elapsed:.1f}\n')


def _rate(rate: Rate | None) -> str:
    if rate is None or rate.rate is None or rate.interval is None:
        return 'no data'
    low, high = rate.interval
    return f'{rate.successes}/{rate.trials} = {rate.rate:.0%} ({low:.0%}-{high:.0%})'


def pooled_rate(rates: list[Rate]) -> Rate:
    """Return the rate of several cells together, with its Wilson interval."""
    from octoroach_model.studies.summary import wilson

    return wilson(sum(rate.successes for rate in rates), sum(rate.trials for rate in rates))


def _error(value: float | None) -> str:
    return '-' if value is None else f'{100 * value:.1f} %'


def _median_error(errors: dict[tuple, Estimation], entry: Recovery, cause: str) -> str:
    """Return the median absolute relative error of `cause` in a two-cause entry's data sets."""
    error = errors.get((entry.arm, cause, entry.runs))
    return _error(error.median_abs_relative_error if error else None)


def _wall(name: str, summary: StudySummary) -> str:
    """
    Return the study's wall time, as this script or the summary measured it.

    A resumed or partial study has none: then the sum of its data sets' times.
    """
    path = OUT / name / 'bench_wall_time_s.txt'
    timing = summary.timing
    seconds = float(path.read_text()) if path.exists() else timing.wall_time_s
    if seconds is not None:
        return f'wall time {seconds / 60:.1f} min'
    if timing.total_task_s and timing.median_task_s is not None:
        return (f'{timing.total_task_s / 60:.0f} min of single-worker time over its data '
                f'sets (median {timing.median_task_s:.0f} s each)')
    return 'wall time unknown'


def table_summary(name: str) -> tuple[StudySummary, str | None, list[StudyRow]]:
    """
    Summarize the study's table as it stands (the table is the record; summary.json may be older).

    The wall time is the one the last finished run measured. Returns the summary, for a study
    stopped before its end a sentence saying how many data sets of how many it holds, and the
    table's rows.
    """
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.summary import summarize
    from octoroach_model.studies.table import read_table

    spec = spec_of(name)
    rows, _ = read_table(OUT / name / 'table.csv', earlier=True)
    earlier = OUT / name / 'summary.json'
    wall_time_s = (json.loads(earlier.read_text())['timing'].get('wall_time_s')
                   if earlier.exists() else None)
    total = len(build_tasks(spec))
    if len(rows) >= total:
        return summarize(spec, rows, wall_time_s), None, rows
    replicates = sorted({row.replicate for row in rows})
    return summarize(spec, rows), (
        f'{len(rows)} of the {total} data sets of the spec (replicates {replicates[0]}-'
        f'{replicates[-1]}, not all complete); `--studies {name}` resumes it'), rows


def spec_of(name: str) -> StudySpec:
    """
    Return the spec of the study in out/studies/NAME: studies/NAME.yaml, or its folder's own.

    A study kept under another name after a change (out/studies/ramp_limits_7358d86, the
    rows before the ramp's signature was scored) has no spec file of that name: its manifest
    (study.json) names the spec it was run with, which must still be the one in studies/.
    """
    from octoroach_model.studies.spec import load_spec
    from octoroach_model.studies.table import read_manifest

    if (SPECS / f'{name}.yaml').exists():
        return load_spec(SPECS / f'{name}.yaml')
    manifest = read_manifest(OUT / name)
    spec = load_spec(SPECS / f'{manifest["spec"]["name"]}.yaml')
    if spec.spec_hash != manifest['spec_hash']:
        raise SystemExit(f'error: out/studies/{name} was run with another spec than '
                         f'studies/{spec.name}.yaml holds now')
    return spec


def print_close_calls(rows: list[StudyRow]) -> None:
    """
    Print each close call at 1x a limit: its held-out t on the first scored runs and on all.

    Where the term is there, a test picked for a t near its critical value is expected to
    move towards its data's t (above it on average at a limit) when scored again.
    """
    calls = [(term, row.replicate, row.terms[term]) for row in rows
             if row.ok and row.limit_multiple == 1.0 for term in row.true_causes
             if math.isfinite(row.terms[term].first_t)]
    if not calls:
        return
    print('close calls at 1x, held-out t on the first scored runs -> on all of them (critical '
          't): ' + '; '.join(f'{term} replicate {replicate} {o.first_t:.2f} -> {o.t:.2f} '
                             f'({o.t_critical:.2f})' for term, replicate, o in calls))
    changes = [o.t - o.first_t for _, _, o in calls]
    print(f't rose in {sum(change > 0 for change in changes)} of {len(changes)} (change '
          f'{min(changes):+.2f} to {max(changes):+.2f}, median {statistics.median(changes):+.2f})'
          '\n')


def print_scoring_error(rows: list[StudyRow]) -> None:
    """
    Print the scoring error of the held-out t at 1x a limit, and the power it leaves there.

    The limits take the test's power as Phi(T - z) (docs/diagnosis.md, section 8): t's spread
    over the held-out runs alone. The simulated runs that score them add an error of their own
    (`t_scoring_se`, of the t each decision used); with it the power at a limit the test
    decides is Phi(z_POWER / sqrt(1 + se^2)) instead of POWER (decide.py).
    """
    from scipy import stats

    from octoroach_model.diagnosis.decide import POWER

    errors = sorted(row.terms[term].t_scoring_se for row in rows
                    if row.ok and row.limit_multiple == 1.0 for term in row.true_causes
                    if math.isfinite(row.terms[term].t_scoring_se))
    if not errors:
        return
    z_power = float(stats.norm.ppf(POWER))

    def power(se: float) -> str:
        return f'{stats.norm.cdf(z_power / math.sqrt(1.0 + se * se)):.3f}'

    median, high = statistics.median(errors), errors[int(0.9 * (len(errors) - 1))]
    print(f'scoring error of the held-out t at 1x: median {median:.2f}, 90th percentile '
          f'{high:.2f}, largest {errors[-1]:.2f} ({len(errors)} data sets); power at a limit '
          f'the test decides, with that error: {power(median)}, {power(high)}, '
          f'{power(errors[-1])} ({POWER:.2f} without it)\n')


def _at_limit(rows: list[StudyRow], multiple: float | None, missed: bool) -> list[str]:
    """
    Say each term put in at a limit multiple that was missed, or named with an interval off.

    `missed`: the terms at `multiple` x their limit not named (their robot's spread, their
    held-out t and what it had to pass); else the terms named at any multiple whose reported
    95 % interval does not hold the truth.
    """
    from octoroach_model.studies.spec import ArmKind

    said = []
    for row in rows:
        if not row.ok or row.kind == ArmKind.NULL or (
                multiple is not None and row.limit_multiple != multiple):
            continue
        for term in row.true_causes:
            o = row.terms[term]
            if missed and not o.named:
                test = (f't {o.t:.2f} for {o.t_critical:.2f}' if math.isfinite(o.t)
                        else 'screened')
                said.append(f'{term} replicate {row.replicate} (spread x{row.spread_scale:.2f}'
                            f'): {test}')
            elif not missed and o.named and not o.low <= o.true <= o.high:
                said.append(f'{term} replicate {row.replicate} at {row.limit_multiple:g}x: '
                            f'{o.true:.4g} outside {o.low:.4g} to {o.high:.4g}')
    return said


def print_limit_parts(rows: list[StudyRow]) -> None:
    """
    Print, per term at 1x its limit, what each part of the decision did beside its prediction.

    A limit is where P(size bound clears) x P(held-out test significant) reaches 80 %
    (docs/diagnosis.md, "Detection limits"); the null data set's report gives the two at the
    limit (`bound_power_<term>`, `test_power_<term>`), the data set with the term at that
    limit what came of each (`clears_floor_<term>`; t above `t_critical`, of the data sets
    whose test was scored). A named-rate near 80 % can hide two parts wrong in opposite
    directions: this says which part decides the misses.
    """
    from octoroach_model.studies.spec import ArmKind
    from octoroach_model.studies.summary import wilson

    nulls = {(row.replicate, row.runs): row for row in rows if row.ok
             and row.kind == ArmKind.NULL}
    parts: dict[str, dict[str, list[tuple[float, bool]]]] = {}
    for row in rows:
        null = nulls.get((row.replicate, row.runs))
        if not (row.ok and row.limit_multiple == 1.0 and null is not None):
            continue
        for term in row.true_causes:
            predicted, outcome = null.terms[term], row.terms[term]
            mine = parts.setdefault(term, {'bound': [], 'test': []})
            if math.isfinite(predicted.bound_power) and outcome.clears_floor is not None:
                mine['bound'].append((predicted.bound_power, outcome.clears_floor))
            if math.isfinite(predicted.test_power) and math.isfinite(outcome.t) \
                    and math.isfinite(outcome.t_critical):
                mine['test'].append((predicted.test_power, outcome.t > outcome.t_critical))

    def said(pairs: list[tuple[float, bool]], what: str) -> str:
        if not pairs:
            return f'{what}: no data set'
        held = sum(outcome for _, outcome in pairs)
        mean = statistics.mean(power for power, _ in pairs)
        return f'{what} {_rate(wilson(held, len(pairs)))} where {mean:.2f} was predicted'

    for term, mine in parts.items():
        limits = [row.terms[term].limit for row in nulls.values()
                  if math.isfinite(row.terms[term].limit)]
        if mine['bound'] or mine['test']:
            print(f'the parts of the decision at 1x, {term} (limits on the nulls '
                  f'{min(limits):.4g}-{max(limits):.4g}): '
                  f'{said(mine["bound"], "size bound cleared its floor")}; '
                  f'{said(mine["test"], "held-out test passed (of those scored)")}\n')


def print_comparison(name: str, other: str) -> None:
    """
    Print each term's null limits in study `name` beside those in `other`, and the decisions.

    The rows are matched by key (the same spec: the same robots and seeds, common random
    numbers), so the ratios are the change's, not the draws'; a data set named or not in one
    and not the other is listed.
    """
    from octoroach_model.studies.spec import ArmKind
    from octoroach_model.studies.table import read_table
    from octoroach_model.studies.terms import TERMS

    missing = [study for study in (name, other) if not (OUT / study / 'table.csv').is_file()]
    if missing:
        print(f'\n{name} beside {other}: no table in {OUT / missing[0]}')
        return
    tables = [{row.key: row for row in read_table(OUT / study / 'table.csv', earlier=True)[0]
               if row.ok} for study in (name, other)]
    mine, theirs = tables
    common = [key for key in mine if key in theirs]
    print(f'\n{name} beside {other} ({len(common)} data sets in both):')
    for term in TERMS:
        ratios = [mine[key].terms[term].limit / theirs[key].terms[term].limit
                  for key in common if mine[key].kind == ArmKind.NULL
                  and math.isfinite(mine[key].terms[term].limit)
                  and theirs[key].terms[term].limit > 0]
        turned = [key for key in common if term in mine[key].true_causes
                  and mine[key].terms[term].named != theirs[key].terms[term].named]
        if not ratios:
            continue
        print(f'  {term}: null limits {statistics.median(ratios):.3f} times those there '
              f'(median; {min(ratios):.3f}-{max(ratios):.3f} over {len(ratios)} nulls); '
              f'decided otherwise: ' + (', '.join(
                  f'{key} ({"named" if mine[key].terms[term].named else "not named"} here)'
                  for key in turned) or 'none'))


def print_tables(names: list[str]) -> None:
    """Print the README tables of every study of `names` found in out/studies."""
    for name in names:
        if not (OUT / name / 'table.csv').exists():
            print(f'\n{name}: no table in {OUT / name} (run --studies {name})')
            continue
        summary, partial, rows = table_summary(name)
        command = (f'python -m octoroach_model study studies/{summary.study}.yaml '
                   f'--out out/studies/{name}')
        print(f'\n### {name} (`{command}`, {_wall(name, summary)} on this machine)\n')
        if partial:
            print(f'**Partial**: {partial}\n')
        counts = summary.status.counts
        if set(counts) - {'ok'}:
            print(f'data sets without a diagnosis: {dict(counts)}\n')
        fp = summary.false_positive
        if fp.overall.trials:
            print('| null data sets | any cause named (95 % interval) | causes named |')
            print('| --- | --- | --- |')
            named = ', '.join(f'{k} {v}' for k, v in fp.causes_named.items()) or 'none'
            print(f'| {fp.overall.trials} | {_rate(fp.overall)} | {named} |\n')
            inadequate = summary.inadequate_on_nulls
            if inadequate.overall.trials:
                print(f'adequacy check false alarms (null data sets called inadequate): '
                      f'{_rate(inadequate.overall)}\n')
                print_by_runs(fp.by_runs, inadequate)
        if summary.power:
            errors = {(e.arm, e.runs): e for e in summary.estimation}
            print('| cause | size | data sets | named (95 % interval) | median abs. rel. error |'
                  ' median rel. error |')
            print('| --- | --- | --- | --- | --- | --- |')
            for entry in summary.power:
                sign = '+-' if entry.sign == 'both' else ''
                arm = f'{entry.cause}={sign}{entry.size:g}'
                error = errors.get((arm, entry.runs))
                print(f'| {entry.cause} | {entry.parameter} = {sign}{entry.size:g} | '
                      f'{entry.named.trials} | {_rate(entry.named)} | '
                      f'{_error(error.median_abs_relative_error if error else None)} | '
                      f'{_error(error.median_relative_error if error else None)} |')
            print()
        if summary.power_at_limit_multiples:
            limits = {(e.cause, e.runs): e for e in summary.detection_limits}
            print('| cause | median reported limit | named at 1x the limit | at 2x | named or '
                  'undecided at 1x | baseline inadequate at 2x |')
            print('| --- | --- | --- | --- | --- | --- |')
            entries = summary.power_at_limit_multiples
            for cause in dict.fromkeys(e.cause for e in entries):
                mine = {e.limit_multiple: e for e in entries if e.cause == cause}
                limit = limits.get((cause, mine[min(mine)].runs))
                median = limit.median_limit if limit else None
                shown = f'{limit.parameter} = {median:.3g}' if limit and median is not None \
                    else '-'
                once, twice = mine.get(1.0), mine.get(2.0)
                print(f'| {cause} | {shown} | {_rate(once.named if once else None)} | '
                      f'{_rate(twice.named if twice else None)} | '
                      f'{_rate(once.named_or_undecided if once else None)} | '
                      f'{_rate(twice.baseline_inadequate if twice else None)} |')
            pooled = [_rate(pooled_rate([e.named for e in entries
                                         if e.limit_multiple == multiple]))
                      for multiple in (1.0, 2.0)]
            either = _rate(pooled_rate([e.named_or_undecided for e in entries
                                        if e.limit_multiple == 1.0]))
            print(f'| all causes | | {pooled[0]} | {pooled[1]} | {either} | |')
            print()
            margins = [e for e in entries if e.limit_multiple == 1.0 and e.median_t_margin
                       is not None]
            if margins:
                print('held-out t at 1x, median margin over the t it had to pass (data sets '
                      'within two scoring errors of it: close calls, scored again; turned: '
                      'decided the other way on the runs scored again): ' + '; '.join(
                          f'{e.cause} {e.median_t_margin:+.2f} ({e.close_calls} of '
                          f'{e.named.trials}, turned {e.turned})' for e in margins) + '\n')
            print_close_calls(rows)
            print_scoring_error(rows)
            print_limit_parts(rows)
            for multiple in (1.0, 2.0):
                chosen = [e for e in entries if e.limit_multiple == multiple]
                missed = sum(e.missed for e in chosen)
                flagged = sum(e.missed_not_adequate for e in chosen)
                if missed:
                    print(f'missed at {multiple:g}x the limit: {missed}, of which reported not '
                          f'adequate (the miss is not silent): {flagged}; '
                          + '; '.join(_at_limit(rows, multiple, missed=True)) + '\n')
            wide = _at_limit(rows, None, missed=False)
            if wide:
                print('named at a limit multiple, the 95 % interval not holding the truth: '
                      + '; '.join(wide) + '\n')
        if summary.two_cause_recovery:
            by_cause = {(e.arm, e.cause, e.runs): e for e in summary.estimation}
            print('| causes | data sets | both named (95 % interval) | each named (median abs. '
                  'rel. error) | a third cause named |')
            print('| --- | --- | --- | --- | --- |')
            for recovery in summary.two_cause_recovery:
                each = ', '.join(
                    f'{cause} {_rate(rate)} ({_median_error(by_cause, recovery, cause)})'
                    for cause, rate in recovery.each_named.items())
                print(f'| {recovery.arm} | {recovery.all_named.trials} | '
                      f'{_rate(recovery.all_named)} | {each} | '
                      f'{_rate(recovery.other_named)} |')
            print()
        print_estimation_at_limits(summary)
        print_confusion(summary)
        print_coverage(summary)


def print_by_runs(named: tuple[RateByRuns, ...], inadequate: InadequateOnNulls) -> None:
    """Print the null data sets' rates per run count, where a study has several."""
    cells = {cell.runs: cell.rate for cell in named}
    alarms = {cell.runs: cell.rate for cell in inadequate.by_runs}
    if len(cells) < 2:
        return
    print('| runs | null data sets | a cause or extension named | called inadequate |')
    print('| --- | --- | --- | --- |')
    for runs, rate in cells.items():
        print(f'| {runs} | {rate.trials} | {_rate(rate)} | {_rate(alarms.get(runs))} |')
    print()
    if inadequate.unexplained:
        which = ', '.join(f'{name} {count}' for name, count in sorted(
            inadequate.unexplained.items(), key=lambda item: -item[1]))
        print(f'statistics left unexplained on the null data sets: {which}\n')


def print_estimation_at_limits(summary: StudySummary) -> None:
    """Print, per cause and limit multiple, the size error and interval coverage where named."""
    entries = [e for e in summary.estimation if '@' in e.arm and e.named]
    if not entries:
        return
    print('| cause | multiple | named | median abs. rel. error | median rel. error | '
          'intervals that held the truth |')
    print('| --- | --- | --- | --- | --- | --- |')
    for entry in entries:
        multiple = entry.arm.split('@', 1)[1].lstrip('+-')
        print(f'| {entry.cause} | {multiple} | {entry.named} | '
              f'{_error(entry.median_abs_relative_error)} | '
              f'{_error(entry.median_relative_error)} | '
              f'{_rate(entry.interval_coverage)} |')
    print()


def print_confusion(summary: StudySummary) -> None:
    """Print which cause or family was named for which (data sets with one true term)."""
    confusion = summary.confusion
    table = confusion.named
    if len(table) < 2:
        return
    columns = sorted({label for counts in (*table.values(), *confusion.undecided.values())
                      for label in counts}, key=lambda label: (label == 'nothing', label))
    print('| true \\ named | data sets | ' + ' | '.join(columns) + ' |')
    print('| --- ' * (len(columns) + 2) + '|')
    for true in sorted(table, key=lambda label: (label != 'none', label)):
        counts = table[true]
        beside = confusion.undecided.get(true, {})
        cells = ' | '.join(_confusion_cell(counts.get(label, 0), beside.get(label, 0))
                           for label in columns)
        print(f'| {true} | {confusion.data_sets[true]} | {cells} |')
    print('(+k: in k more data sets reported beside the named term as what the runs cannot '
          'tell it from)\n')


def _confusion_cell(named: int, undecided: int) -> str:
    text = str(named) if named else '.'
    return f'{text} (+{undecided})' if undecided else text


def print_coverage(summary: StudySummary) -> None:
    """Print how often the reported 95 % intervals held the truth, pooled and per cause."""
    from octoroach_model.studies.summary import wilson

    held: dict[str, list[int]] = {}
    for entry in summary.estimation:
        counts = held.setdefault(entry.cause, [0, 0])
        counts[0] += entry.interval_coverage.successes
        counts[1] += entry.interval_coverage.trials
    if not sum(total for _, total in held.values()):
        return
    pooled = wilson(sum(c for c, _ in held.values()), sum(t for _, t in held.values()))
    by_cause = ', '.join(f'{cause} {count}/{total}' for cause, (count, total) in held.items()
                         if total)
    print(f'reported 95 % intervals that held the truth (where the cause was named): '
          f'{_rate(pooled)}; {by_cause}\n')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--scale', action='store_true', help='1 vs 2 local workers')
    parser.add_argument('--limit-terms', nargs='+', default=(), metavar='TERM',
                        help='with --scale: the null data sets compute the detection limits '
                             'of these terms alone (diagnosis.limit_terms of the spec)')
    parser.add_argument('--studies', nargs='*', default=None, metavar='NAME',
                        help=f'run the README studies (default all: {", ".join(README_STUDIES)})')
    parser.add_argument('--report-only', action='store_true',
                        help='print the tables of the studies in out/studies, run nothing')
    parser.add_argument('--workers', type=int, default=None)
    parser.add_argument('--scheduler', default=None)
    parser.add_argument('--compare', default=None, metavar='OTHER',
                        help='with --report-only: each null limit beside the one in '
                             'out/studies/OTHER, data set by data set')
    args = parser.parse_args(argv)
    if args.compare and not args.report_only:
        parser.error('--compare compares tables already run: give it with --report-only')
    names = list(args.studies or README_STUDIES) if args.studies is not None else []
    if args.report_only:
        print_tables(names or list(README_STUDIES))
        for name in (names or list(README_STUDIES)) if args.compare else []:
            print_comparison(name, args.compare)
        return 0
    if not args.scale and args.studies is None:
        args.scale = True
    if args.scale:
        from octoroach_model.errors import ParameterError
        from octoroach_model.limit_setting import check_term_names

        terms = tuple(args.limit_terms)
        try:
            check_term_names(terms, '--limit-terms')
        except ParameterError as error:
            parser.error(str(error))
        print_scale(measure_scale(limit_terms=terms), terms)
    if names:
        run_studies(names, args.workers, args.scheduler)
        print_tables(names)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
