"""
Do the baseline geometry's standard errors cover its error? One robot, many data sets.

Takes one replicate of a study spec (default: replicate 16 of studies/adequacy.yaml at 60
runs, the null data set whose heading to travel angle the adequacy check still calls off),
simulates its robot again under other data seeds (the study's damage kept), and fits the
baseline as the diagnosis does (calibration half; geometry from the quick fit's angles and
their swapped pairs, then geometry and spread scale refit). For each data set it prints the
fitted touchdown angles, their reported standard errors (the fit's covariance, which the
adequacy check carries into every statistic) and each error in those standard errors. Where
the errors run past 2-3 standard errors, the geometry's interval is too narrow and a
statistic the fit does not match can be called off on an exact model.

With `--basins`: for each data set the geometry is fitted again, at the fitted spread scale,
from the fitted geometry and from the robot's own, and both costs (half the sum of squared
residuals, in standard errors) are printed: a lower cost far from the robot says the fit's
objective, not its start, leaves the robot.

Minutes on two idle cores: 0.5-1.5 min a data set (a fast robot of long runs), twice that
with --basins.
Run: .venv/bin/python benchmarks/bench_geometry_coverage.py [--replicate 16] [--runs 60]
     [--data-sets 6] [--basins] [--spec studies/adequacy.yaml]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from octoroach_model.studies.design import RobotDraw, Task
    from octoroach_model.studies.spec import StudySpec

REPO = Path(__file__).resolve().parents[1]
ANGLES = slice(1, 5)        # the touchdown angles in the fit's vector (leg first)


def null_task(spec: StudySpec, replicate: int, runs: int) -> Task | None:
    """Return the study's null data set of `runs` runs in `replicate` (None if it has none)."""
    from octoroach_model.studies.design import build_tasks

    return next((task for task in build_tasks(spec) if task.replicate == replicate
                 and task.runs_cell == runs and task.arm.kind == 'null'), None)


def null_case(parser: argparse.ArgumentParser, spec_path: Path, replicate: int, runs: int
              ) -> tuple[StudySpec, Task, RobotDraw, np.ndarray]:
    """
    Return a study's null data set of `runs` runs in `replicate`: spec, task, robot, angles.

    The robot's touchdown angles in degrees; a spec without that data set ends the program
    through `parser` with one line naming what is missing.
    """
    from octoroach_model.studies.design import draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(spec_path)
    task = null_task(spec, replicate, runs)
    if task is None:
        parser.error(f'{spec_path.name} has no null data set of {runs} runs in replicate '
                     f'{replicate}')
    robot = draw_robot(spec, replicate)
    return spec, task, robot, np.degrees(robot.parameters().touchdown_angles)


def main(argv: list[str] | None = None) -> int:
    """Print one row per data set and the summary line; return the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--spec', type=Path, default=REPO / 'studies' / 'adequacy.yaml')
    parser.add_argument('--replicate', type=int, default=16)
    parser.add_argument('--runs', type=int, default=60)
    parser.add_argument('--data-sets', type=int, default=6)
    parser.add_argument('--basins', action='store_true')
    args = parser.parse_args(argv)

    from octoroach_model.diagnosis.diagnose import fit_baseline, halves_as_diagnosed
    from octoroach_model.diagnosis.modelfit import fit_geometry
    from octoroach_model.studies import replicate as study

    spec, task, robot, truth = null_case(parser, args.spec, args.replicate, args.runs)
    print(f'{spec.name} replicate {args.replicate}, {args.runs} runs: '
          f'{robot.stride_frequency_hz:.2f} Hz, {robot.cycles:.0f} cycles, '
          f'{robot.sample_rate_hz:.0f} Hz sampling, leg {robot.leg_length_cm:.2f} cm, spread x'
          f'{robot.spread_scale:.2f}; touchdown angles '
          f'{", ".join(f"{a:.2f}" for a in truth)} deg\n')
    header = ('| data seed | fitted leg, cm | fitted stride, Hz | fitted angles, deg '
              '| standard errors, deg | errors in standard errors |')
    if args.basins:
        header += ' cost from the fit | cost from the robot | angles from the robot, deg |'
    print(header)
    print('| --- ' * (header.count('|') - 1) + '|')
    z_rows: list[np.ndarray] = []
    frequency_errors = []
    for k in range(args.data_sets):
        seed = robot.data_seed + 1000 * (k + 1)
        draw = replace(robot, data_seed=seed)
        measured = study.simulate_data(spec, draw, args.runs, {}).paths
        settings = study.task_settings(task, spec, seed)
        halves = halves_as_diagnosed(measured, settings)
        fit = fit_baseline(halves, settings)
        parameters = fit.model.parameters
        fitted = np.degrees(parameters.touchdown_angles)
        assert fit.geometry is not None, 'the baseline fits the geometry'
        se = np.degrees(np.sqrt(np.diag(fit.geometry.covariance)[ANGLES]))
        z = (fitted - truth) / se
        z_rows.append(z)
        frequency_errors.append(abs(parameters.stride_frequency / robot.stride_frequency_hz - 1))
        row = (f'| {seed} | {parameters.leg_length * 100:.2f} | '
               f'{parameters.stride_frequency:.2f} | {", ".join(f"{a:.1f}" for a in fitted)} | '
               f'{", ".join(f"{s:.1f}" for s in se)} | {", ".join(f"{v:+.1f}" for v in z)} |')
        if args.basins:
            # both refit at the fitted spread scale: the cost depends on the spread too
            robot_start = replace(fit.model, parameters=replace(
                robot.parameters(), sample_rate=halves.train.paths.rate_hz))
            _, _, at_fit = fit_geometry(halves.train, fit.model, (), settings.fit())
            own, _, at_robot = fit_geometry(halves.train, robot_start, (), settings.fit())
            angles = np.degrees(own.parameters.touchdown_angles)
            row += (f' {at_fit.cost:.0f} | {at_robot.cost:.0f} | '
                    f'{", ".join(f"{a:.1f}" for a in angles)} |')
        print(row, flush=True)
    z_all = np.array(z_rows)
    rms = np.sqrt(np.mean(z_all ** 2, axis=0))
    print(f'\nroot mean square of the errors in standard errors, per angle: '
          f'{", ".join(f"{v:.2f}" for v in rms)} (1 where the errors are honest); '
          f'|error| past 3 standard errors in {int(np.sum(np.abs(z_all) > 3))} of {z_all.size}; '
          f"the stride frequency more than 2 % off the robot's in "
          f'{sum(error > 0.02 for error in frequency_errors)} of {len(frequency_errors)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
