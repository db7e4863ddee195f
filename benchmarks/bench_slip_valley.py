"""
A slip against a robot's own crab: where each start of the path-cause refit ends.

Two data sets of studies/limits.yaml (500 runs each), their slips sized off the limits their
null data sets reported at commit 38647f2:

- replicate 3 (angles 48.7, 38.5, 41.7, 47.4 deg, 1.61 Hz, 200 Hz), a slip of -0.359 cm/s,
  twice its limit: the robot's asymmetry crabs one way, the slip the other. The baseline,
  fitted without a slip, bends its angles to the runs' net crab, and from the current
  geometry and from equal angles the refit stays there (the study missed this slip).
- replicate 6 (angles 49.2, 35.5, 44.4, 43.4 deg), a slip of -0.236 cm/s, its limit: here
  Table II's start ends at a lower cost further from the robot.

For each, the race's refit with the slip from every start of `geometry_starts` (current,
equal angles, Table II's): where it ends (cost, angles, slip), its cost on other seeds of the
mean path and the calibration and held-out runs' log scores, each against the lowest cost's
end; which end `best_valley` keeps; the robot's own geometry for comparison; and the race's
first step on lateral_slip (held-out gain, size). docs/diagnosis.md section 3 quotes them.

Run: .venv/bin/python benchmarks/bench_slip_valley.py [--replicate 3|6]
     (about a minute per replicate on the two cores)
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
from pathlib import Path
import sys

REPO = Path(__file__).resolve().parents[1]
# replicate: (the slip in cm/s, its multiple of the null's reported limit)
CASES = {3: (-0.359146797282138, 2.0), 6: (-0.23623777779492236, 1.0)}
OTHER_SEEDS = 10


def show(replicate: int) -> None:
    """Print the table and the race's step for one replicate."""
    import numpy as np

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.diagnose import (
        choose_wobble_hz, evaluate_candidate, fit_baseline, halves_as_diagnosed,
        score_held_out, with_wobble)
    from octoroach_model.diagnosis.modelfit import (
        best_valley, calibration_log_scores, fit_geometry, geometry_residuals,
        geometry_starts, Simulator)
    from octoroach_model.diagnosis.scoring import PairedGain
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks, draw_robot
    from octoroach_model.studies.spec import load_spec

    slip, multiple = CASES[replicate]
    spec = load_spec(REPO / 'studies' / 'limits.yaml')
    task = next(task for task in build_tasks(spec) if task.replicate == replicate
                and task.arm.cause == 'lateral_slip' and task.arm.limit_multiple == multiple)
    draw = draw_robot(spec, replicate)
    effects = {'lateral_slip': {'velocity_cm_s': slip}}
    measured = study.simulate_data(spec, draw, task.runs(draw), effects).paths
    settings = study.task_settings(task, spec, draw.data_seed)
    halves = halves_as_diagnosed(measured, settings)
    baseline = fit_baseline(halves, settings).model
    halves = with_wobble(halves, choose_wobble_hz(halves.train, baseline, settings))
    fit = settings.fit()
    simulator = Simulator(halves.train, fit.seed)
    held_out = Simulator(halves.test, settings.seed)
    robot = draw.parameters()

    def angles(model) -> str:
        return ', '.join(f'{math.degrees(a):.1f}' for a in model.parameters.touchdown_angles)

    def other_costs(model) -> np.ndarray:
        return np.array([0.5 * float(np.sum(geometry_residuals(
            halves.train, model, ('lateral_slip',), replace(fit, seed=fit.seed + 1000 * k)
        ) ** 2)) for k in range(1, OTHER_SEEDS + 1)])

    robot_angles = ', '.join(f'{angle:.1f}' for angle in draw.touchdown_angles_deg)
    print(f'replicate {replicate}: robot angles {robot_angles} deg, slip {slip:.3f} cm/s '
          f'({multiple:g}x its limit); baseline angles {angles(baseline)} deg\n')
    print(f"| start | cost | cost on {OTHER_SEEDS} other seeds, minus the lowest cost end's "
          '(sd) | angles, deg | slip, cm/s | calibration score | held-out score |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    names = ('the current geometry', 'equal angles', "Table II's angles")
    unslipped = baseline.with_effect('lateral_slip', {'velocity_cm_s': 0.0})
    starts = geometry_starts(simulator, unslipped, ['lateral_slip'], fit)
    own = replace(baseline, parameters=replace(
        baseline.parameters, leg_length=robot.leg_length,
        touchdown_angles=robot.touchdown_angles).with_paper_liftoff()).with_effect(
        'lateral_slip', {'velocity_cm_s': slip})
    ends = [fit_geometry(halves.train, start, ('lateral_slip',), fit) for start in starts]
    lowest = min(ends, key=lambda end: end[2].cost)[0]
    costs = other_costs(lowest)
    calibration = calibration_log_scores(simulator, lowest, fit)
    tested = score_held_out(held_out, lowest, halves, settings).log
    robots_own = fit_geometry(halves.train, own, ('lateral_slip',), fit)
    for name, (model, estimates, uncertainty) in (
            *zip(names, ends), ("the robot's own (for comparison, not a start)", robots_own)):
        size = estimates['lateral_slip']
        gap = other_costs(model) - costs
        on_calibration = PairedGain.of(calibration_log_scores(simulator, model, fit)
                                       - calibration)
        on_held_out = PairedGain.of(score_held_out(held_out, model, halves, settings).log
                                    - tested)
        print(f'| {name} | {uncertainty.cost:.1f} | {gap.mean():+.1f} ({gap.std(ddof=1):.1f})'
              f' | {angles(model)} | {size.size:+.3f} +- {size.se:.3f} | '
              f'{on_calibration.mean:+.3f} +- {on_calibration.standard_error:.3f} | '
              f'{on_held_out.mean:+.3f} +- {on_held_out.standard_error:.3f} |', flush=True)
    print("(scores: nats per run against the lowest cost's end, paired standard errors)")
    kept = best_valley(simulator, ends, fit)
    chosen = next(name for name, end in zip(names, ends) if end is kept)
    print(f'best_valley keeps the end from {chosen}: slip '
          f"{kept[1]['lateral_slip'].size:+.3f} cm/s")
    scores = score_held_out(held_out, baseline, halves, settings)
    evaluation = evaluate_candidate(halves, baseline, scores, 'lateral_slip', settings)
    estimate = evaluation.estimates['lateral_slip']
    floor = BY_NAME['lateral_slip'].floor(halves.run_scale)
    verdict = ('the slip is found, with its sign'
               if np.sign(estimate.size) == np.sign(slip) and evaluation.gain.mean > 0
               else 'a fit of the other sign or a gain below 0 misses it')
    print(f'\nthe first race step: lateral_slip {estimate.size:+.3f} +- {estimate.se:.3f} '
          f'cm/s (floor {floor:.3f}), held-out gain {evaluation.gain.mean:+.3f} nats per run '
          f'(+- {evaluation.gain.standard_error:.3f}): {verdict}\n')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--replicate', type=int, choices=sorted(CASES), action='append',
                        help='one of the data sets (default: both)')
    for replicate in parser.parse_args().replicate or sorted(CASES):
        show(replicate)
    return 0


if __name__ == '__main__':
    sys.exit(main())
