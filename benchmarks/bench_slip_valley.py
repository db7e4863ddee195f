"""
A slip against a robot's own crab: where each start of the path-cause refit ends.

studies/limits.yaml's replicate 3 (angles 48.7, 38.5, 41.7, 47.4 deg, 1.61 Hz, 200 Hz, 500
runs) with a lateral slip of -0.359 cm/s, twice the limit its null data set reported at
commit 38647f2: the robot's asymmetry crabs one way, the slip the other. The baseline, fitted
without a slip, bends its angles to the runs' net crab; the race then refits it with the slip
from each start of `geometry_starts` (current, equal angles). This prints where each ends
(cost, angles, slip), beside a start at Table II's angles (tried as a third start and not
kept: it mends this data set and worsens replicate 6's, docs/diagnosis.md section 3) and the
robot's own geometry, and the race's first step on lateral_slip (held-out gain, size): the
study misses this slip at twice its limit.

Run: .venv/bin/python benchmarks/bench_slip_valley.py   (about a minute on the two cores)
"""
from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path
import sys

REPO = Path(__file__).resolve().parents[1]
REPLICATE = 3
SLIP_CM_S = -0.359146797282138


def main() -> int:
    import numpy as np

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.diagnose import (
        choose_wobble_hz, evaluate_candidate, fit_baseline, halves_as_diagnosed,
        score_held_out, with_wobble)
    from octoroach_model.diagnosis.modelfit import fit_geometry, geometry_starts, Simulator
    from octoroach_model.model import ModelParameters
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks, draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(REPO / 'studies' / 'limits.yaml')
    task = next(task for task in build_tasks(spec) if task.replicate == REPLICATE
                and task.arm.cause == 'lateral_slip' and task.arm.limit_multiple == 2.0)
    draw = draw_robot(spec, REPLICATE)
    effects = {'lateral_slip': {'velocity_cm_s': SLIP_CM_S}}
    measured = study.simulate_data(spec, draw, task.runs(draw), effects).paths
    settings = study.task_settings(task, spec, draw.data_seed)
    halves = halves_as_diagnosed(measured, settings)
    baseline = fit_baseline(halves, settings).model
    halves = with_wobble(halves, choose_wobble_hz(halves.train, baseline, settings))
    fit = settings.fit()
    simulator = Simulator(halves.train, fit.seed)
    robot = draw.parameters()

    def angles(model) -> str:
        return ', '.join(f'{math.degrees(a):.1f}' for a in model.parameters.touchdown_angles)

    robot_angles = ', '.join(f'{angle:.1f}' for angle in draw.touchdown_angles_deg)
    print(f'replicate {REPLICATE}: robot angles {robot_angles} deg, slip {SLIP_CM_S:.3f} '
          f'cm/s; baseline angles {angles(baseline)} deg\n')
    print('| start | cost | angles, deg | slip, cm/s |')
    print('| --- | --- | --- | --- |')
    names = ('current geometry', 'equal angles')
    unslipped = baseline.with_effect('lateral_slip', {'velocity_cm_s': 0.0})
    starts = geometry_starts(simulator, unslipped, ['lateral_slip'], fit)
    paper = replace(unslipped, parameters=replace(
        unslipped.parameters, touchdown_angles=ModelParameters.nominal().touchdown_angles
    ).with_paper_liftoff())
    own = replace(baseline, parameters=replace(
        baseline.parameters, leg_length=robot.leg_length,
        touchdown_angles=robot.touchdown_angles).with_paper_liftoff()).with_effect(
        'lateral_slip', {'velocity_cm_s': SLIP_CM_S})
    for name, start in (*zip(names, starts), ("Table II's angles (not a start)", paper),
                        ("the robot's own (for comparison)", own)):
        model, estimates, uncertainty = fit_geometry(halves.train, start, ('lateral_slip',), fit)
        size = estimates['lateral_slip']
        print(f'| {name} | {uncertainty.cost:.1f} | {angles(model)} | '
              f'{size.size:+.3f} +- {size.se:.3f} |', flush=True)
    scores = score_held_out(Simulator(halves.test, settings.seed), baseline, halves, settings)
    evaluation = evaluate_candidate(halves, baseline, scores, 'lateral_slip', settings)
    estimate = evaluation.estimates['lateral_slip']
    floor = BY_NAME['lateral_slip'].floor(halves.run_scale)
    verdict = ('the slip is found, with its sign'
               if np.sign(estimate.size) == np.sign(SLIP_CM_S) and evaluation.gain.mean > 0
               else 'a fit of the other sign or a gain below 0 misses it')
    print(f'\nthe first race step: lateral_slip {estimate.size:+.3f} +- {estimate.se:.3f} '
          f'cm/s (floor {floor:.3f}), held-out gain {evaluation.gain.mean:+.3f} nats per run '
          f'(+- {evaluation.gain.standard_error:.3f}): {verdict}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
