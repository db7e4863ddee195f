"""
Where the baseline's starts end, and whether the runs tell those valleys apart.

Takes one null data set of a study spec (default: replicate 21 of
studies/adequacy_few_runs.yaml at 40 runs, a data set the adequacy check once called off),
fits the geometry on its calibration half from each of the baseline's starts (the quick fit's
angles and their swapped pairs, at the runs' spread, as `diagnose.fit_baseline` does) and from
the robot's own geometry, and prints each fit's cost, angles and their errors in standard
errors of the fit; then each pair's cost gap with its standard error over resamples of the
runs (`covariance.cost_gap_se`): a gap within about two standard errors is a valley the runs
do not rule out. With `--diagnose` the data set is diagnosed as its study would (one
process) and the adequacy check's verdict, its largest |z| and the report's notes printed,
then those statistics on the data, the model and the robot itself (`print_robot_values`):
whether an alarm is the data's chance or the fit's error.

Minutes on one idle core: 2-4 for the fits of a fast robot of long runs, 5-8 more with
--diagnose.
Run: .venv/bin/python benchmarks/bench_geometry_valleys.py
     [--spec studies/adequacy_few_runs.yaml] [--replicate 21] [--runs 40] [--diagnose]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import time
from typing import Sequence, TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from octoroach_model.diagnosis import DiagnosisReport
    from octoroach_model.diagnosis.discrepancies import Discrepancy
    from octoroach_model.diagnosis.modelfit import RunData
    from octoroach_model.paths import Paths
    from octoroach_model.studies.design import RobotDraw

REPO = Path(__file__).resolve().parents[1]
ANGLES = slice(1, 5)        # the touchdown angles in the fit's vector (leg first)


def main(argv: list[str] | None = None) -> int:
    """Print one row per start, one per pair of fits, and the diagnosis; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--spec', type=Path,
                        default=REPO / 'studies' / 'adequacy_few_runs.yaml')
    parser.add_argument('--replicate', type=int, default=21)
    parser.add_argument('--runs', type=int, default=40)
    parser.add_argument('--diagnose', action='store_true')
    args = parser.parse_args(argv)

    from bench_geometry_coverage import null_case
    from octoroach_model.diagnosis import diagnose
    from octoroach_model.diagnosis.diagnose import baseline_starts, halves_as_diagnosed
    from octoroach_model.diagnosis.modelfit import (
        fit_geometry, FittedModel, GAIT_COLUMNS, geometry_residuals, RIVAL_BOOTSTRAP,
        spread_statistic)
    from octoroach_model.diagnosis.discrepancies import SPREAD, STATISTICS
    from octoroach_model.fitting.covariance import cost_gap_se, target_changes
    from octoroach_model.studies import replicate as study

    spec, task, robot, truth = null_case(parser, args.spec, args.replicate, args.runs)
    print(f'{spec.name} replicate {args.replicate}, {args.runs} runs: '
          f'{robot.stride_frequency_hz:.2f} Hz, {robot.cycles:.0f} cycles, '
          f'{robot.sample_rate_hz:.0f} Hz sampling, spread x{robot.spread_scale:.2f}; '
          f'touchdown angles {", ".join(f"{a:.1f}" for a in truth)} deg\n')
    measured = study.simulate_data(spec, robot, args.runs, {}).paths
    settings = replace(study.task_settings(task, spec, robot.data_seed), workers=1)
    prepared = halves_as_diagnosed(measured, settings)
    train = prepared.train
    fit = settings.fit()

    starts = [(f'start {number}', start)
              for number, start in enumerate(baseline_starts(train, settings), 1)]
    at_spread = starts[0][1]          # every start shares the start pose and spread scale
    starts.append(('the robot', FittedModel(replace(
        robot.parameters(), sample_rate=train.paths.rate_hz), at_spread.start_pose,
        at_spread.sigma_scale, {})))

    print('| from | cost | fitted angles, deg | standard errors, deg '
          '| errors in standard errors |')
    print('| --- | --- | --- | --- | --- |')
    fits = []
    for name, start in starts:
        model, _, uncertainty = fit_geometry(train, start, (), fit)
        angles = np.degrees(model.parameters.touchdown_angles)
        errors = np.degrees(np.sqrt(np.diag(uncertainty.covariance)[ANGLES]))
        print(f'| {name} | {uncertainty.cost:.0f} | {", ".join(f"{a:.1f}" for a in angles)} '
              f'| {", ".join(f"{e:.1f}" for e in errors)} '
              f'| {", ".join(f"{z:+.1f}" for z in (angles - truth) / errors)} |', flush=True)
        fits.append((name, geometry_residuals(train, model, (), fit)))

    changes = target_changes(train.target, train.features[:, GAIT_COLUMNS],
                             fit.heading_weight_m, train.scales,
                             np.random.default_rng([fit.seed, 19]), RIVAL_BOOTSTRAP)
    print('\n| fits | cost gap (second minus first) | its standard error | gap / error |')
    print('| --- | --- | --- | --- |')
    for first in range(len(fits)):
        for second in range(first + 1, len(fits)):
            (one, residuals), (other, rival) = fits[first], fits[second]
            gap = 0.5 * float(rival @ rival - residuals @ residuals)
            error = cost_gap_se(residuals, rival, changes)
            print(f'| {one} / {other} | {gap:+.0f} | {error:.0f} | '
                  f'{gap / error if error > 0 else float("nan"):+.2f} |')

    if args.diagnose:
        started = time.perf_counter()
        report = diagnose(measured, settings)
        worst = sorted(report.extended_discrepancies, key=lambda row: -abs(row.z))[:3]
        print(f'\ndiagnosis ({time.perf_counter() - started:.0f} s): '
              f'{"adequate" if report.adequate else "not adequate"}; largest |z|: '
              + '; '.join(f'{row.statistic} {row.z:+.2f}' for row in worst))
        for note in report.notes:
            print(f'note: {note}')
        # the spread statistic over the feature the spread scale is read off (a mean
        # statistic may name the same feature: its materiality reads that feature's spread)
        spread_name = next(statistic.name for statistic in STATISTICS
                           if statistic.kind == SPREAD
                           and statistic.feature == spread_statistic(report.extended_model))
        spread_row = next(row for row in report.extended_discrepancies
                          if row.statistic == spread_name)
        print_robot_values(measured, robot, prepared.every, report,
                           [*worst, *([spread_row] if spread_row not in worst else [])])
    return 0


TRUTH_RUNS = 4000
TRUTH_BYTES = 500e6


def print_robot_values(measured: Paths, robot: RobotDraw, ruler: RunData,
                       report: DiagnosisReport, rows: Sequence[Discrepancy]) -> None:
    """
    Print each statistic of `rows` on the data, the model and the robot itself.

    `rows`: the largest |z| and the statistic the spread scale is read off. The robot's value
    is that of TRUTH_RUNS runs of the robot (fewer where their poses would pass TRUTH_BYTES),
    cut to the data's lengths and measured with the diagnosis's `ruler`. The data's distance
    from it, in the data's standard errors, is the data's chance; the model's, in the model's,
    is what the fit took from that chance (the spread scale is read off one of the data's
    statistics) or got wrong. Then the spread scale, fitted and true.
    """
    from octoroach_model.diagnosis.diagnose import decimated
    from octoroach_model.diagnosis.discrepancies import statistic_values, STATISTICS
    from octoroach_model.model import simulate

    sigma1, sigma2 = robot.sigmas()
    parameters = robot.parameters()
    # at most TRUTH_BYTES of poses (x, y, heading): fewer runs for a long, finely sampled run
    samples = len(parameters.time_grid(robot.cycles))
    count = max(200, min(TRUTH_RUNS, int(TRUTH_BYTES // (24 * samples))))
    runs = simulate(count, seed=robot.data_seed + 1, cycles=robot.cycles,
                    parameters=parameters, sigma1=sigma1, sigma2=sigma2)
    runs = runs.cut_to(np.resize(measured.lengths, count))
    truth = dict(zip((s.name for s in STATISTICS), statistic_values(
        ruler.features_of(decimated(runs)[0], None))))
    print(f'\n| statistic | data | model | robot ({count} runs) | data - robot, data se '
          '| model - robot, model se |')
    print('| --- | --- | --- | --- | --- | --- |')
    for row in rows:
        robot_value = truth[row.statistic]
        print(f'| {row.statistic} | {row.data:.4g} | {row.model:.4g} | {robot_value:.4g} | '
              f'{(row.data - robot_value) / row.data_se:+.2f} | '
              f'{(row.model - robot_value) / row.model_se:+.2f} |')
    print(f'spread scale: fitted {report.extended_model.sigma_scale:.4f}, true '
          f'{robot.spread_scale:.4f}')


if __name__ == '__main__':
    raise SystemExit(main())
