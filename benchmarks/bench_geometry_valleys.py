"""
Where the baseline's starts end, and whether the runs tell those valleys apart.

Takes one null data set of a study spec (default: replicate 21 of
studies/adequacy_few_runs.yaml at 40 runs, a data set the adequacy check once called off),
fits the geometry on its calibration half from each of the baseline's starts (the quick fit's
angles and their swapped pairs, at the runs' spread, as `diagnose._baseline` does) and from
the robot's own geometry, and prints each fit's cost, angles and their errors in standard
errors of the fit; then each pair's cost gap with its standard error over resamples of the
runs (`covariance.cost_gap_se`): a gap within about two standard errors is a valley the runs
do not rule out. With `--diagnose` the data set is diagnosed as its study would (one
process) and the adequacy check's verdict, its largest |z| and the report's notes printed.

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

import numpy as np

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

    from bench_geometry_coverage import null_task
    from octoroach_model.diagnosis import diagnose
    from octoroach_model.diagnosis.diagnose import _prepare, baseline_starts, decimated
    from octoroach_model.diagnosis.modelfit import (
        fit_geometry, FittedModel, GAIT_COLUMNS, geometry_residuals, RIVAL_BOOTSTRAP)
    from octoroach_model.fitting.covariance import cost_gap_se, target_changes
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(args.spec)
    task = null_task(spec, args.replicate, args.runs)
    if task is None:
        parser.error(f'{args.spec.name} has no null data set of {args.runs} runs in replicate '
                     f'{args.replicate}')
    robot = draw_robot(spec, args.replicate)
    truth = np.degrees(robot.parameters().touchdown_angles)
    print(f'{spec.name} replicate {args.replicate}, {args.runs} runs: '
          f'{robot.stride_frequency_hz:.2f} Hz, {robot.cycles:.0f} cycles, '
          f'{robot.sample_rate_hz:.0f} Hz sampling, spread x{robot.spread_scale:.2f}; '
          f'touchdown angles {", ".join(f"{a:.1f}" for a in truth)} deg\n')
    measured = study.simulate_data(spec, robot, args.runs, {}).paths
    settings = replace(study.task_settings(task, spec, robot.data_seed), workers=1)
    train = _prepare(decimated(measured)[0], settings).train
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
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
