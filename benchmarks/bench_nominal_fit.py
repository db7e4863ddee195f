"""
Why the diagnosis fits the mean of simulated runs, not the paper's deterministic path.

For robots around Table II (touchdown angles within 5 deg, spreads 0.5-1.2 x Table III), 2000
runs each: the error of the fitted touchdown angles when eq. 9 matches the deterministic path
(every angle at its nominal value) to the average path, and when the mean of simulated runs
at the true spreads is matched instead, as the diagnosis does (with the sway within a stride,
in the data's standard errors). Prints the table of docs/speed.md, "The nominal fit".

A second table: the paper's fit as `validate` makes it (`fit_nominal`'s defaults) on runs of
Table II/III of growing length (LENGTHS cycles, RUNS_BY_LENGTH runs, three data seeds each):
the fitted leg and the largest touchdown-angle error, and whether the fit ended on a bound
(docs/validation.md, "Where eq. (9) fails").

Run: .venv/bin/python benchmarks/bench_nominal_fit.py [--table angles|lengths|both]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
import sys

import numpy as np

ROBOTS = 4
RUNS = 2000
LENGTHS = (5, 10, 15, 20, 30)
RUNS_BY_LENGTH = 500


def main(argv: list[str] | None = None) -> int:
    """Print the tables asked for."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--table', choices=('angles', 'lengths', 'both'), default='both')
    table = parser.parse_args(argv).table
    if table in ('angles', 'both'):
        angle_errors()
    if table in ('lengths', 'both'):
        print()
        by_run_length()
    return 0


def largest_angle_error(fit, angles: tuple[float, ...]) -> float:
    """Return the largest error of the fit's four touchdown angles, deg."""
    return float(np.max(np.abs(np.degrees(np.subtract(fit.parameters.touchdown_angles,
                                                      angles)))))


def by_run_length() -> None:
    """Fit eq. (9) as `validate` does to Table II/III runs of each length; print the ends."""
    import octoroach_model as om
    from octoroach_model.fitting import fit_nominal

    nominal = om.ModelParameters.nominal()
    print(f'| cycles | fitted leg, cm (Table II: {nominal.leg_length * 100:.1f}), data seeds '
          '1-3 | largest touchdown-angle error, deg | fits on a bound |')
    print('| --- | --- | --- | --- |')
    for cycles in LENGTHS:
        fits = [fit_nominal(om.simulate(RUNS_BY_LENGTH, seed=seed, cycles=cycles))
                for seed in (1, 2, 3)]
        legs = ', '.join(f'{fit.parameters.leg_length * 100:.2f}' for fit in fits)
        errors = ', '.join(f'{largest_angle_error(fit, nominal.touchdown_angles):.1f}'
                           for fit in fits)
        bounded = sum(bool(fit.at_bounds) for fit in fits)
        print(f'| {cycles} | {legs} | {errors} | {bounded} of 3 |', flush=True)


def angle_errors() -> None:
    """Fit each robot both ways and print the angle errors."""
    import octoroach_model as om
    from octoroach_model.diagnosis.modelfit import RunData
    from octoroach_model.fitting import (
        fit_nominal, MeanPathSettings, mean_start_pose, NominalFitSettings)
    from octoroach_model.fitting.gait import stride_frequency_estimate

    nominal = om.ModelParameters.nominal()
    direction = om.model.nominal_sigmas()
    print('| robot | spread x Table III | deterministic path: max angle error, deg | '
          'mean of simulated runs: max angle error, deg |')
    print('| --- | --- | --- | --- |')
    for robot in range(ROBOTS):
        rng = np.random.default_rng(robot)
        angles = tuple(a + math.radians(rng.uniform(-5, 5)) for a in nominal.touchdown_angles)
        scale = rng.uniform(0.5, 1.2)
        truth = replace(nominal, touchdown_angles=angles).with_paper_liftoff()
        sigmas = (scale * direction[0], scale * direction[1])
        runs = om.simulate(RUNS, seed=robot, sigma1=sigmas[0], sigma2=sigmas[1],
                           parameters=truth)
        start = mean_start_pose(runs)
        data = RunData(runs, stride_frequency_estimate(runs.poses[..., 2], runs.t), start[2])
        deterministic = fit_nominal(runs, settings=NominalFitSettings(
            heading_weight_m=nominal.hip_distance, align_gait=True), start_pose=start)
        mean = fit_nominal(runs, deterministic.parameters, NominalFitSettings(
            multistart=False, refine=True, tolerance=1e-6,
            mean=MeanPathSettings(sigmas, 300, 5, gait=data.gait, scales=data.scales)),
            start_pose=start, target=data.target)
        errors = [largest_angle_error(fit, angles) for fit in (deterministic, mean)]
        print(f'| {robot} | {scale:.2f} | {errors[0]:.2f} | {errors[1]:.2f} |')


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
