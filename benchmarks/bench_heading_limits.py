"""
Why the limits of the heading terms lean low: a held-out test weighed on one data set.

Takes one replicate of studies/open_world.yaml and prints

- the detection limits of heading_random_walk and periodic_heading on its null data set, as
  the diagnosis reports them now, beside those in the study's table.csv (when the study ran
  into out/studies/open_world);
- on its data sets with each heading term at 1x the limit in that table: the geometry and
  spread of the two models the held-out test compares (as the race fits them) beside the
  robot's, and the held-out gain of the term as the diagnosis measured it (mean and spread
  over the held-out runs, the t that decided), beside the gain runs simulated as the limit
  simulates them show at the true size and at the fitted one (docs/diagnosis.md, section 8).

With `--fitted-pairs K`: on the null data set, as the limit sees it, heading_random_walk at
1x and 1.5x its table limit: the expected t the limit computes now, beside the t of K pairs of
models fitted as the race fits them (the baseline, then the model with the term) to K
calibration halves simulated with the term, each pair scored on the same simulated held-out
runs: how much the fits' own differences move the test.

With `--spread-part`: on the null data set, heading_random_walk at 1x its table limit, the
test's t for pairs that differ in one part each (the geometry of the model without the term
refit, both models fitted, the extended model's spread scale alone moved), and the spread
scale `fit_spread` reads with the term: the part that lowers the test is that scale, which
the limit now averages over (`limits.spread_averaged_t`).

Minutes on two idle cores (a diagnosis of 500 runs with its limits, two race steps; about 4 s
more per fitted pair).
Run: .venv/bin/python benchmarks/bench_heading_limits.py [--replicate 3] [--fitted-pairs 3]
     [--spread-part]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
from pathlib import Path
from typing import Any, NamedTuple

REPO = Path(__file__).resolve().parents[1]
SPEC = REPO / 'studies' / 'open_world.yaml'
TABLE = REPO / 'out' / 'studies' / 'open_world' / 'table.csv'
HEADING_TERMS = ('heading_random_walk', 'periodic_heading')


def study_rows(replicate: int) -> dict[str, Any]:
    """Return the study table's rows (StudyRow) of `replicate` by arm (empty when not run)."""
    from octoroach_model.studies.table import read_table

    if not TABLE.is_file():
        return {}
    rows, _ = read_table(TABLE)
    return {row.arm: row for row in rows if row.replicate == replicate}


def table_limit(row: Any, term: str) -> str:
    """Return the limit of `term` in a study row, as the table prints it."""
    limit = row.terms[term].limit if row is not None and term in row.terms else math.nan
    return f'{limit:.3g}' if math.isfinite(limit) else 'not run'


def null_limits(replicate: int, rows: dict[str, Any]) -> None:
    """Print the heading terms' limits on the replicate's null, now and in the table."""
    from octoroach_model.diagnosis import diagnose
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks, draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(SPEC)
    task = next(task for task in build_tasks(spec)
                if task.replicate == replicate and task.arm.kind == 'null')
    draw = draw_robot(spec, replicate)
    measured = study.simulate_data(spec, draw, task.runs_cell, {}).paths
    report = diagnose(measured, study.task_settings(task, spec, draw.data_seed))
    print(f'open_world replicate {replicate}, null data set: detection limits\n')
    print('| term | limit now | in the study table |')
    print('| --- | --- | --- |')
    for candidate in report.extension_candidates:
        if candidate.cause in HEADING_TERMS:
            (parameter, limit), = candidate.detectable.items()
            before = table_limit(rows.get('none'), candidate.cause)
            print(f'| {candidate.cause} | {parameter} = {limit:.3g} | {before} |')
    print()


def held_out_gain(replicate: int, rows: dict[str, Any], term: str) -> None:
    """
    Print the held-out gain measured and simulated on the data set with `term` at 1x.

    Beside it, the geometry and spread scale of the two models the held-out test compares,
    as fitted to the calibration half, and the robot's own: the limit simulates the term at
    the geometry and spread of the model without it; the race refits them with the term.
    """
    import numpy as np

    from octoroach_model.diagnosis.causes import BY_NAME
    from study_replay import race_step

    from octoroach_model.diagnosis.limits import (
        _features, limit_base, MODEL_PURPOSE, PSEUDO_PURPOSE, simulated_gains)
    from octoroach_model.diagnosis.modelfit import FittedModel
    from octoroach_model.diagnosis.scoring import feature_log_score

    null_row = rows.get('none')
    if table_limit(null_row, term) == 'not run':
        print('(the held-out gain needs the limit of the study table: run studies/open_world.yaml '
              'into out/studies/open_world first)')
        return
    draw, effects, settings, halves, baseline, evaluation, simulator = race_step(
        SPEC, replicate, term, null_row)
    held_out = halves.test.n
    spread = evaluation.gain.standard_error * math.sqrt(held_out)
    parameter = BY_NAME[term].parameter
    true_size = effects[term][parameter]
    fitted_size = evaluation.estimates[term].size
    print(f'{term} at 1x its limit ({parameter} = {true_size:.3g}), {held_out} held-out runs\n')
    print('| model | leg, cm | touchdown angles, deg | spread scale |')
    print('| --- | --- | --- | --- |')
    for label, parameters, scale in (
            ('the robot (truth)', draw.parameters(), draw.spread_scale),
            ('without the term (baseline)', baseline.parameters, baseline.sigma_scale),
            ('with the term (as the race fits it)', evaluation.model.parameters,
             evaluation.model.sigma_scale)):
        angles = ', '.join(f'{math.degrees(angle):.2f}' for angle in parameters.touchdown_angles)
        print(f'| {label} | {parameters.leg_length * 100:.3f} | {angles} | {scale:.3f} |')
    print()
    print('| held-out gain | size, deg | mean, nats/run | spread, nats/run | t |')
    print('| --- | --- | --- | --- | --- |')
    print(f'| measured by the diagnosis | fitted {fitted_size:.3g} | {evaluation.gain.mean:.3f} | '
          f'{spread:.2f} | {evaluation.gain.mean / spread * math.sqrt(held_out):.2f} |')
    base = limit_base(simulator, baseline, halves.scales, settings.score_runs)
    for label, size in (('true', true_size), ('fitted', fitted_size)):
        gains, _ = simulated_gains(simulator, baseline, base, BY_NAME[term], size,
                                   halves.scales, settings.score_runs,
                                   dict(evaluation.model.effects[term]), settings.fit())
        sd = float(np.std(gains, ddof=1))
        print(f'| simulated as the limit does | {label} {size:.3g} | {gains.mean():.3f} | '
              f'{sd:.2f} | {gains.mean() / sd * math.sqrt(held_out):.2f} |')
    # runs of the robot itself with the term, scored by two pairs of models: the race's
    # fitted pair, and the robot with and without the term (no fit at all)
    truth = FittedModel(draw.parameters(), baseline.start_pose, draw.spread_scale,
                        {term: dict(effects[term])})
    robot_runs = simulator.features(truth, 1000, PSEUDO_PURPOSE) / halves.scales
    pairs = (("the race's two fitted models", evaluation.model, baseline),
             ('the robot with and without the term', truth, replace(truth, effects={})))
    for label, extended, without in pairs:
        gains = (feature_log_score(_features(simulator, extended, settings.score_runs,
                                             MODEL_PURPOSE, halves.scales), robot_runs)
                 - feature_log_score(_features(simulator, without, settings.score_runs,
                                               MODEL_PURPOSE, halves.scales), robot_runs))
        sd = float(np.std(gains, ddof=1))
        print(f'| {label}, on runs of the robot | true {true_size:.3g} | {gains.mean():.3f} | '
              f'{sd:.2f} | {gains.mean() / sd * math.sqrt(held_out):.2f} |')
    print()


class NullAsLimited(NamedTuple):
    """A replicate's null data set prepared as the race prepares it, its baseline fitted."""

    settings: Any
    halves: Any
    baseline: Any
    simulator: Any
    base: Any        # the scored runs of the baseline (limits.limit_base)


def has_limit(null_row: Any, term: str, option: str) -> bool:
    """Return whether the study table has the term's limit; if not, say what `option` needs."""
    if table_limit(null_row, term) == 'not run':
        print(f'({option} needs the limit of the study table)')
        return False
    return True


def null_as_limited(replicate: int) -> NullAsLimited:
    """Return the replicate's null data set as its detection limits see it."""
    from octoroach_model.diagnosis.diagnose import (
        choose_wobble_hz, fit_baseline, halves_as_diagnosed, with_wobble)
    from octoroach_model.diagnosis.limits import limit_base
    from octoroach_model.diagnosis.modelfit import Simulator
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks, draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(SPEC)
    task = next(task for task in build_tasks(spec)
                if task.replicate == replicate and task.arm.kind == 'null')
    draw = draw_robot(spec, replicate)
    measured = study.simulate_data(spec, draw, task.runs_cell, {}).paths
    settings = study.task_settings(task, spec, draw.data_seed)
    halves = halves_as_diagnosed(measured, settings)
    baseline = fit_baseline(halves, settings).model
    halves = with_wobble(halves, choose_wobble_hz(halves.train, baseline, settings))
    simulator = Simulator(halves.test, settings.seed)
    return NullAsLimited(settings, halves, baseline, simulator,
                         limit_base(simulator, baseline, halves.scales, settings.score_runs))


def fitted_pairs(replicate: int, rows: dict[str, Any], pairs: int) -> None:
    """Print the limit's expected t beside that of pairs fitted as the race fits them."""
    import numpy as np
    from scipy import stats

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.diagnose import CANDIDATES
    from octoroach_model.diagnosis.limits import _features, MODEL_PURPOSE, simulated_gains
    from octoroach_model.diagnosis.modelfit import at_size, fit_causes, RunData, spread_statistic
    from octoroach_model.diagnosis.scoring import feature_log_score

    term = 'heading_random_walk'
    null_row = rows.get('none')
    if not has_limit(null_row, term, '--fitted-pairs'):
        return
    settings, halves, baseline, simulator, base = null_as_limited(replicate)
    data = halves.test
    held_out, fit = data.n, settings.fit()

    def scored(model: Any) -> Any:
        return _features(simulator, model, settings.score_runs, MODEL_PURPOSE, halves.scales)

    # the held-out test's critical z at the first step, every candidate in the race
    critical = float(stats.norm.isf(settings.alpha / len(CANDIDATES)))
    print(f'{term} on the null data set, {held_out} held-out runs: expected t (the test '
          f'names at z {critical:.2f})\n')
    print('| size | the limit now | pairs fitted as the race fits them | test power over '
          'the pairs |')
    print('| --- | --- | --- | --- |')
    for multiple in (1.0, 1.5):
        size = multiple * null_row.terms[term].limit
        gains, runs = simulated_gains(simulator, baseline, base, BY_NAME[term], size,
                                      halves.scales, settings.score_runs, None, fit)
        now = gains.mean() / np.std(gains, ddof=1) * math.sqrt(held_out)
        extended = baseline.with_effect(term, at_size(BY_NAME[term], size, None, data))
        fitted = []
        for pair in range(pairs):
            paths, positions = simulator.runs(extended, held_out, 60 + pair)
            calibration = RunData(paths, data.stride_frequency, data.reference_heading,
                                  positions, data.wobble_hz, data.wobble_interval)
            without = fit_causes(calibration, baseline, baseline.causes, fit, rounds=1).model
            causes = (*without.causes, term)
            model = fit_causes(calibration, without, causes, fit, geometry=False,
                               rounds=1).model
            if spread_statistic(model) != spread_statistic(without):
                model = fit_causes(calibration, model, causes, fit, rounds=1).model
            gain = (feature_log_score(scored(model), runs / halves.scales)
                    - feature_log_score(scored(without), runs / halves.scales))
            fitted.append(gain.mean() / np.std(gain, ddof=1) * math.sqrt(held_out))
        power = float(np.mean(stats.norm.cdf(np.array(fitted) - critical)))
        print(f'| {multiple:g}x = {size:.3g} deg | {now:.2f} | '
              f'{", ".join(f"{t:.2f}" for t in fitted)} (mean {np.mean(fitted):.2f}) | '
              f'{power:.2f} |')
    print()


def spread_part(replicate: int, rows: dict[str, Any]) -> None:
    """
    Print which part of the fitted pair lowers the test: the spread scale fitted with the term.

    On the null data set, heading_random_walk at 1x its table limit: t of the pair the limit
    simulated before (the term at the true scale, against the spread refit without it), with
    the model without the term refit with its geometry too, with both models fitted as the
    race fits them to 1000 runs, and with only the extended model's scale moved to what that
    fit found; then t at the true scale moved by its standard error (`spread_error` on 250
    runs), and the scale fit_spread reads off runs with the term at 400 and 1600 simulated runs.
    """
    import numpy as np

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.limits import limit_base, simulated_pair, t_statistic
    from octoroach_model.diagnosis.modelfit import (
        fit_causes, fit_spread, RunData, spread_error, spread_statistic)

    term = 'heading_random_walk'
    null_row = rows.get('none')
    if not has_limit(null_row, term, '--spread-part'):
        return
    settings, halves, baseline, simulator, base = null_as_limited(replicate)
    data = halves.test
    held_out, fit, scales = data.n, settings.fit(), halves.scales
    size = null_row.terms[term].limit
    pair = simulated_pair(simulator, baseline, base, BY_NAME[term], size, scales,
                          settings.score_runs, None, fit)

    def t_of(extended: Any, without: Any = None) -> str:
        """t, mean and spread of `extended`'s gains over `without` (default: the pair's)."""
        weighed = pair if without is None else replace(
            pair, without=without,
            without_features=limit_base(simulator, without, scales, settings.score_runs))
        gains = weighed.gains(simulator, scales, settings.score_runs, extended)
        return (f'{t_statistic(gains, held_out):.2f} | {gains.mean():.3f} | '
                f'{np.std(gains, ddof=1):.2f}')

    paths, positions = simulator.runs(pair.extended, 1000, 90)
    many = RunData(paths, data.stride_frequency, data.reference_heading, positions,
                   data.wobble_hz, data.wobble_interval)
    refit_without = fit_causes(many, baseline, baseline.causes, fit, rounds=1).model
    causes = (*refit_without.causes, term)
    fitted = fit_causes(many, refit_without, causes, fit, geometry=False, rounds=1).model
    if spread_statistic(fitted) != spread_statistic(refit_without):
        fitted = fit_causes(many, fitted, causes, fit, rounds=1).model
    scale = pair.extended.sigma_scale
    print(f'{term} at 1x its table limit ({size:.3g} deg) on the null of replicate {replicate}, '
          f'{held_out} held-out runs; true spread scale {scale:.3f}\n')
    print('| pair scored | t | mean gain, nats/run | spread, nats/run |')
    print('| --- | --- | --- | --- |')
    print(f'| the term at the true scale, against the spread refit without it | '
          f'{t_of(pair.extended)} |')
    print(f'| the same, the model without it refit with its geometry (1000 runs) | '
          f'{t_of(pair.extended, refit_without)} |')
    print(f'| both fitted as the race fits them (1000 runs; scale with the term '
          f'{fitted.sigma_scale:.3f}) | {t_of(fitted, refit_without)} |')
    print(f'| the true model at that fitted scale, against the same refit | '
          f'{t_of(replace(pair.extended, sigma_scale=fitted.sigma_scale), refit_without)} |')
    se = spread_error(simulator, pair.extended, fit, pair.runs, held_out)
    for node in (-2.0, -1.0, 1.0, 2.0):
        moved = replace(pair.extended, sigma_scale=scale + node * se)
        print(f'| the term at the true scale {node:+g} se ({scale + node * se:.3f}), against '
              f'the spread refit without it | {t_of(moved)} |')
    print(f'\nThe standard error of the scale on {held_out} runs: {se:.4f} '
          f'({100 * se / scale:.1f} %).')
    for runs in (fit.moment_runs, 4 * fit.moment_runs):
        read = [fit_spread(simulator, pair.extended, replace(fit, moment_runs=runs),
                           simulator.features(pair.extended, 1000, 700 + seed))
                for seed in range(3)]
        print(f'fit_spread on three sets of 1000 runs with the term, matched with {runs} '
              f'simulated runs: {", ".join(f"{value:.4f}" for value in read)} '
              f'(true {scale:.4f})')
    print()


def main() -> None:
    """Print the tables for one replicate."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--replicate', type=int, default=3)
    parser.add_argument('--fitted-pairs', type=int, default=0, metavar='K',
                        help='also fit K pairs of models as the race does (about 4 s each)')
    parser.add_argument('--spread-part', action='store_true',
                        help='also show that the spread fitted with the term lowers the test')
    args = parser.parse_args()
    rows = study_rows(args.replicate)
    null_limits(args.replicate, rows)
    for term in HEADING_TERMS:
        held_out_gain(args.replicate, rows, term)
    if args.fitted_pairs > 0:
        fitted_pairs(args.replicate, rows, args.fitted_pairs)
    if args.spread_part:
        spread_part(args.replicate, rows)


if __name__ == '__main__':
    main()
