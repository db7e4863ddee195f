"""
How far the diagnosis's own simulations move the two criteria of a decision near its threshold.

A term is named when its held-out test passes (t = gain / its standard error above the step's
critical t) and its size bound clears its floor. Both are computed from the runs and from
simulated runs. On the same runs, with the halves kept (`split_seed`) and only the simulations
drawn again (the seed moved), this prints the term's criteria at the first step of the race,
draw by draw (a term screened there, neither refit nor scored, has no t; a term can be named
at a later step), and their spread over the draws: the simulations' share. The t is in units
of its own standard error over the held-out runs, which leaves the simulations out, so a
spread of 0.5 over draws means they add a quarter to the variance the test counts; the size
is in units of its reported standard error; the bound's margin is (lower bound - floor) /
standard error. These are the numbers a mend of the decision rule needs (docs/diagnosis.md,
section 5, "The same runs, another seed").

Data: the reference robot (Table II, Table III's spreads, `om.simulate`'s defaults) with the
term at `--size` (its family's parameter; run_mixture: the yaw rate of `--fraction` of the
runs), one data set per `--data-seeds` entry. The default sizes sit near the decision's
threshold on this robot, found by trying: at 4.75 deg/s (the limit a diagnosis of bags/
reports, whose runs carry a start-pose error as well) every draw named the mixture, t 4.3 to
6.4.

With `--study SPEC --replicates R...` the data sets are the study's instead (robots drawn over
its robot space, its run counts and damage): replicate r's null data set is diagnosed first,
with detection limits, exactly as the study does, and the term is put in at 1x the limit that
null reported (`study_replay.rebuilt`), so each data set sits near its own robot's threshold;
the draws then move the seed of the study's own settings. This says whether the reference
robot's spreads are typical of the robot space. With `--scoring-only` as well, the race's
first step is fitted once (`study_replay.race_step`) and only the simulated runs the held-out
half is scored against are drawn again: the scoring's share of the t's scatter, the rest
being the fits'.

`--close-call-factors 1 4` diagnoses every draw twice, its close calls not scored again and
scored again on four times the runs (the default, diagnose._settled), the null and the data
sets the same: whether scoring again makes the draws agree, and what it costs.

Run: .venv/bin/python benchmarks/bench_draw_margins.py [--family run_mixture] [--size 3.9]
     [--data-seeds 1 2 3] [--draws 4] [--runs 500] [--seed 0] [--workers 2]
     [--close-call-factors 1 4]
     .venv/bin/python benchmarks/bench_draw_margins.py --study studies/open_world.yaml
     --replicates 0 1 2 3 4 [--family heading_random_walk] [--draws 4] [--scoring-only]
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time
from typing import Any, Iterator, NamedTuple

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

DEFAULT_SIZES = {'run_mixture': 3.9, 'heading_random_walk': 1.0}
PARAMETERS = {'run_mixture': 'yaw_rate_deg_s', 'heading_random_walk': 'step_std_deg'}


class Criteria(NamedTuple):
    """One draw's decision on one data set, and the term's two criteria at the race's step 1."""

    data_set: int              # the data seed, or the study's replicate
    draw: int
    named: tuple[str, ...]
    t: float
    t_critical: float
    bound_margin: float        # (lower bound - floor) / standard error; clears above z
    bound_z: float             # the step's decision z the bound is taken at
    size: float                # the term's fitted size (its family's parameter)
    size_se: float             # its standard error
    screened: bool             # not refit nor scored: its bound or evidence out of reach (t nan)
    cpu_s: float
    factor: int                # close_call_factor of the diagnosis
    first_t: float             # the t before a close call was scored again (nan: not)


def diagnosed(family: str, size: float, fraction: float, runs: int, data_seed: int, seed: int,
              draw: int, factor: int) -> Criteria:
    """Simulate the data set, diagnose it at draw `draw` (halves of `seed`), read the criteria."""
    import octoroach_model as om
    from octoroach_model.diagnosis import diagnose, DiagnosisSettings
    from octoroach_model.diagnosis.diagnose import redraw_settings

    values: dict[str, Any] = {PARAMETERS[family]: size}
    if family == 'run_mixture':
        values['fraction'] = fraction
    measured = om.simulate(runs, seed=data_seed, extensions={family: values})
    started = time.process_time()
    report = diagnose(measured, redraw_settings(DiagnosisSettings(
        seed=seed, close_call_factor=factor), draw))
    return criteria(report, family, data_seed, draw, time.process_time() - started, factor)


def study_null(spec_path: str, replicate: int) -> tuple[Any, float]:
    """Diagnose replicate `replicate`'s null data set as the study does; its row and CPU s."""
    from octoroach_model.studies.replicate import run_task
    from octoroach_model.studies.spec import ArmKind

    spec = study_spec(spec_path, replicate)
    task = next(task for task in study_tasks(spec, replicate) if task.arm.kind == ArmKind.NULL)
    started = time.process_time()
    return run_task(task, spec), time.process_time() - started


def study_diagnosed(spec_path: str, replicate: int, family: str, null_row: Any,
                    draw: int, factor: int) -> Criteria:
    """Diagnose replicate `replicate`'s data set with `family` at 1x its limit, at `draw`."""
    from dataclasses import replace

    from study_replay import at_its_limit, rebuilt

    from octoroach_model.diagnosis import diagnose
    from octoroach_model.diagnosis.diagnose import redraw_settings

    spec = study_spec(spec_path, replicate)
    task = next(task for task in study_tasks(spec, replicate) if at_its_limit(task, family))
    data = rebuilt(spec, task, null_row)
    started = time.process_time()
    report = diagnose(data.measured, redraw_settings(
        replace(data.settings, close_call_factor=factor), draw))
    return criteria(report, family, replicate, draw, time.process_time() - started, factor)


def scoring_draws(spec_path: str, replicate: int, family: str, null_row: Any,
                  draws: int, score_runs: int | None = None
                  ) -> tuple[int, list[float], float]:
    """
    Return the term's t at the race's first step with the fits held, the scored runs redrawn.

    The baseline and the extended model are fitted once (the study's seed, as draw 0); each
    draw then scores both on the held-out runs against their simulated runs from seed + draw.
    Draw 0 is the diagnosis's own t (at the study's `score_runs`); the spread over draws is
    the scoring's share of the simulations' scatter, which `study_diagnosed`'s draws show
    whole. `score_runs` replaces the study's number of scored runs. Returns the replicate,
    the t of each draw and the CPU seconds of one scoring (a model's runs simulated, their
    features, the held-out runs scored).
    """
    from dataclasses import replace

    from study_replay import race_step

    from octoroach_model.diagnosis.diagnose import score_held_out
    from octoroach_model.diagnosis.modelfit import Simulator
    from octoroach_model.diagnosis.scoring import PairedGain

    step = race_step(study_spec(spec_path, replicate), replicate, family, null_row)
    if step.evaluation.screened:
        return replicate, [math.nan] * draws, math.nan
    settings = replace(step.settings, score_runs=score_runs or step.settings.score_runs)
    ts = []
    started = time.process_time()
    for draw in range(draws):
        simulator = Simulator(step.halves.test, settings.seed + draw)
        gain = PairedGain.of(
            score_held_out(simulator, step.evaluation.model, step.halves, settings).log
            - score_held_out(simulator, step.baseline, step.halves, settings).log)
        ts.append(gain.mean / gain.standard_error if gain.standard_error > 0 else math.nan)
    return replicate, ts, (time.process_time() - started) / (2 * draws)


def study_spec(spec_path: str, replicate: int) -> Any:
    """Return the study's spec with at least `replicate` + 1 replicates (robots drawn alike)."""
    from dataclasses import replace

    from octoroach_model.studies.spec import load_spec

    spec = load_spec(spec_path)
    return replace(spec, replicates=max(spec.replicates, replicate + 1))


def study_tasks(spec: Any, replicate: int) -> list[Any]:
    from octoroach_model.studies.design import build_tasks

    return [task for task in build_tasks(spec) if task.replicate == replicate]


def criteria(report: Any, family: str, data_id: int, draw: int, cpu_s: float,
             factor: int) -> Criteria:
    """Read the term's criteria at the race's first step off a report."""
    from scipy import stats

    first = report.steps[0]
    entry = next(c for c in first.candidates if c.cause == family)
    held_out = report.split['held_out']
    t = entry.gain / entry.gain_se if entry.gain_se > 0 else math.nan
    t_critical = float(stats.t.isf(first.test_level, held_out - 1))
    margin = ((entry.lower_bound - entry.floor) / entry.standard_error
              if entry.standard_error > 0 else math.nan)
    size = entry.parameters[PARAMETERS[family]]
    return Criteria(data_id, draw, tuple(report.named_terms), t, t_critical, margin,
                    first.decision_z,
                    float(size) if isinstance(size, (int, float)) else math.nan,
                    entry.standard_error, entry.screened, cpu_s, factor,
                    math.nan if entry.first_t is None else entry.first_t)


def _t(row: Criteria) -> str:
    return 'screened' if row.screened else f'{row.t:.2f}'


def _spread(values: Any) -> float:
    """Return the standard deviation of the finite values (nan with fewer than two)."""
    import numpy as np

    finite = values[np.isfinite(values)]
    return float(np.std(finite, ddof=1)) if len(finite) > 1 else math.nan


def _pooled(spreads: list[float]) -> float:
    """Return the root mean square of the finite spreads (data sets weigh alike)."""
    finite = [value for value in spreads if math.isfinite(value)]
    return math.sqrt(sum(value * value for value in finite) / len(finite)) if finite \
        else math.nan


def main() -> int:
    """Diagnose each data set at each draw, side by side, and print the criteria's spread."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--family', choices=sorted(PARAMETERS), default='run_mixture')
    parser.add_argument('--size', type=float, help='default: the reference limit (docstring)')
    parser.add_argument('--fraction', type=float, default=0.3,
                        help="run_mixture's share of turning runs (default 0.3)")
    parser.add_argument('--data-seeds', type=int, nargs='+', default=[1, 2, 3])
    parser.add_argument('--study', help="a study spec: its robots, the term at 1x each null's "
                        'limit (docstring)')
    parser.add_argument('--replicates', type=int, nargs='+', default=[0, 1, 2],
                        help="with --study: the study's replicates to use (default 0 1 2)")
    parser.add_argument('--draws', type=int, default=4)
    parser.add_argument('--runs', type=int, default=500)
    parser.add_argument('--seed', type=int, default=0, help='the seed of the halves')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--scoring-only', action='store_true',
                        help='with --study: hold the fits, draw only the scored runs again')
    parser.add_argument('--close-call-factors', type=int, nargs='+', default=[4],
                        help='diagnose every draw with each of these close_call_factor '
                        '(1: a close call is not scored again; default 4, the default)')
    parser.add_argument('--score-runs', type=int,
                        help='with --scoring-only: score against this many simulated runs '
                        "(default: the study's)")
    args = parser.parse_args()
    if args.study and args.scoring_only:
        scoring_rows(args)
        return 0
    if args.study:
        found, data_sets = study_rows(args)
    else:
        found, data_sets = reference_rows(args)
    report(found, data_sets)
    return 0


def reference_rows(args: argparse.Namespace) -> tuple[list[Criteria], list[int]]:
    """Diagnose the reference robot's data sets at every draw."""
    from octoroach_model.workers import process_pool

    size = DEFAULT_SIZES[args.family] if args.size is None else args.size
    jobs = [(data_seed, draw, factor) for data_seed in args.data_seeds
            for draw in range(args.draws) for factor in args.close_call_factors]
    print(f'{args.family} at {size:g} ({PARAMETERS[args.family]}), {args.runs} runs: '
          f'{len(args.data_seeds)} data sets x {args.draws} draws x '
          f'{len(args.close_call_factors)} close-call factors = {len(jobs)} diagnoses, '
          f'{args.workers} processes', flush=True)
    with process_pool(args.workers, command=True) as pool:
        futures = [pool.submit(diagnosed, args.family, size, args.fraction, args.runs,
                               data_seed, args.seed, draw, factor)
                   for data_seed, draw, factor in jobs]
        return collected(futures), list(args.data_seeds)


def study_rows(args: argparse.Namespace) -> tuple[list[Criteria], list[int]]:
    """Diagnose each replicate's null, then its data set with the term at 1x, at every draw."""
    from octoroach_model.workers import process_pool

    print(f'{args.family} at 1x the limit each null reports, robots of {args.study}: '
          f'{len(args.replicates)} nulls, then {len(args.replicates)} data sets x {args.draws} '
          f'draws x {len(args.close_call_factors)} close-call factors, {args.workers} '
          'processes', flush=True)
    futures = []
    with process_pool(args.workers, command=True) as pool:
        kept = []
        for replicate, row in study_nulls(args, pool):
            kept.append(replicate)
            futures += [pool.submit(study_diagnosed, args.study, replicate, args.family, row,
                                    draw, factor) for draw in range(args.draws)
                        for factor in args.close_call_factors]
        return collected(futures), sorted(kept)


def study_nulls(args: argparse.Namespace, pool: Any) -> Iterator[tuple[int, Any]]:
    """Diagnose the replicates' nulls; yield each one that reports a limit for the family."""
    from concurrent.futures import as_completed

    from octoroach_model.studies.rows import Status

    nulls = {pool.submit(study_null, args.study, replicate): replicate
             for replicate in args.replicates}
    for future in as_completed(nulls):
        replicate = nulls[future]
        row, cpu_s = future.result()
        limit = row.terms[args.family].limit if args.family in row.terms else math.nan
        print(f'null of replicate {replicate}: {row.status}, named '
              f'{", ".join(row.outcome.named) or "nothing"}; '
              f'{args.family} limit {limit:.3g} ({cpu_s:.0f} s)', flush=True)
        if row.status != Status.OK or not math.isfinite(limit) or limit <= 0:
            print(f'  replicate {replicate} left out: no limit to put the term at')
            continue
        yield replicate, row


def scoring_rows(args: argparse.Namespace) -> None:
    """Print each data set's t with the fits held and only the scored runs drawn again."""
    from concurrent.futures import as_completed

    import numpy as np

    from octoroach_model.workers import process_pool

    print(f'{args.family} at 1x the limit each null reports, robots of {args.study}: the '
          f"race's first step fitted once, its scored runs drawn {args.draws} times, "
          f'{args.workers} processes', flush=True)
    with process_pool(args.workers, command=True) as pool:
        futures = [pool.submit(scoring_draws, args.study, replicate, args.family, row,
                               args.draws, args.score_runs)
                   for replicate, row in study_nulls(args, pool)]
        found = {replicate: (ts, cpu_s) for replicate, ts, cpu_s in
                 (future.result() for future in as_completed(futures))}
    print('\n| data set | t over draws of the scored runs (fits held) | its SD | '
          'CPU s a scoring |')
    print('| --- | --- | --- | --- |')
    spreads = []
    for replicate in sorted(found):
        ts, cpu_s = np.array(found[replicate][0]), found[replicate][1]
        spreads.append(_spread(ts))
        print(f'| {replicate} | {" ".join(f"{t:.2f}" for t in ts)} | {spreads[-1]:.2f} | '
              f'{cpu_s:.2f} |')
    print(f'\npooled SD of t over draws of the scored runs alone: {_pooled(spreads):.2f}'
          f' ({args.score_runs or study_spec(args.study, 0).diagnosis_settings(0).score_runs} '
          'scored runs a model)')


def collected(futures: list[Any]) -> list[Criteria]:
    """Wait for the diagnoses, printing each as it ends."""
    from concurrent.futures import as_completed

    found: list[Criteria] = []
    for done, future in enumerate(as_completed(futures), 1):
        row = future.result()
        found.append(row)
        print(f'[{done}/{len(futures)}] data {row.data_set} draw {row.draw} '
              f'(close-call factor {row.factor}): '
              f'{", ".join(row.named) or "nothing"}; t {_t(row)} (critical '
              f'{row.t_critical:.2f}), bound margin {row.bound_margin:.2f} (needs '
              f'{row.bound_z:.2f}) ({row.cpu_s:.0f} s)', flush=True)
    return found


def report(found: list[Criteria], data_sets: list[int]) -> None:
    """Print, for each close-call factor, the criteria draw by draw and their pooled spreads."""
    for factor in sorted({row.factor for row in found}):
        report_factor([row for row in found if row.factor == factor], data_sets, factor)


def report_factor(found: list[Criteria], data_sets: list[int], factor: int) -> None:
    """Print the criteria draw by draw for each data set, and their pooled spreads."""
    import numpy as np

    print(f'\nclose_call_factor {factor} (a close call '
          + ('not scored again' if factor == 1 else f'scored again on {factor}x the runs') + ')')
    print('\n| data set | named the same at every draw | t over draws (* scored again) | '
          'its SD | bound margin over draws | its SD | size over draws | its SD / its SE |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- |')
    t_sd, margin_sd, size_sd, same_count = [], [], [], 0
    for data_set in data_sets:
        rows = sorted((row for row in found if row.data_set == data_set),
                      key=lambda row: row.draw)
        ts = np.array([row.t for row in rows])
        margins = np.array([row.bound_margin for row in rows])
        sizes = np.array([row.size for row in rows])
        t_sd.append(_spread(ts))
        margin_sd.append(_spread(margins))
        size_sd.append(_spread(sizes) / float(np.mean([row.size_se for row in rows])))
        same = len({frozenset(row.named) for row in rows}) == 1
        same_count += same
        print(f'| {data_set} | {"yes" if same else "no"} | '
              f'{" ".join(_t(row) + ("*" if math.isfinite(row.first_t) else "") for row in rows)}'
              f' | {t_sd[-1]:.2f} | '
              f'{" ".join(f"{value:.2f}" for value in margins)} | {margin_sd[-1]:.2f} | '
              f'{" ".join(f"{value:.3g}" for value in sizes)} | {size_sd[-1]:.2f} |')
    pooled_t, pooled_margin, pooled_size = (_pooled(sds) for sds in (t_sd, margin_sd, size_sd))
    cpu_s = sum(row.cpu_s for row in found)
    again = sum(math.isfinite(row.first_t) for row in found)
    print(f'\npooled SD over draws, same runs: t {pooled_t:.2f}, bound margin '
          f"{pooled_margin:.2f}, size {pooled_size:.2f} of its standard error (the data's "
          f'own: 1 each); named the same at every draw on {same_count} of {len(data_sets)} '
          f'data sets; {again} of {len(found)} first-step tests scored again; CPU '
          f'{cpu_s:.0f} s of the draws')


if __name__ == '__main__':
    raise SystemExit(main())
