"""
Throughput of the model: closed-form, vectorised kinematics against a numeric reference.

Two references run the switching four-bar sample by sample. The straightforward one solves
closure (3) as the paper writes it, two equations in (q1, phi2), with scipy's fsolve from the
touchdown configuration; a tuned one reduces (3) to |O2 - O1| = aR in phi2 alone and brackets
it for brentq. Both then apply the same pose formulas (rear foot fixed in the world, heading
from the foot-to-foot segment) and chain the stances. All run on the same seeded angle draws;
the benchmark checks that they agree, then prints pose samples per second for each and their
ratio, and times `om.simulate(20000, seed=2)` (10 cycles, 251 samples per run: the issue's
target, ~1 s).

Run: .venv/bin/python benchmarks/bench_model.py [--runs N] [--seed S]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import brentq, fsolve

import octoroach_model as om
from octoroach_model.model.kinematics import integrate_stances, stance_angles
from octoroach_model.model.parameters import ModelParameters, nominal_sigmas

START = (0.0, 0.0, math.pi / 2)


def reference_front_angle(rear_angle, span, branch, leg, hips):
    """
    phi2 with |O2 - O1| = span, by brentq on the touchdown branch (pair's own frame).

    O1 = A + l(-cos phi1, sin phi1), O2 = B + l(cos phi2, sin phi2), A = (0, -d/2),
    B = (0, d/2). Along the branch the distance runs monotonically between the collinear
    configurations (front leg along or against P = B - O1); where the span is out of reach
    the closest configuration is taken, as the model does.
    """
    rear_x, rear_y = -leg * math.cos(rear_angle), -0.5 * hips + leg * math.sin(rear_angle)

    def gap(front_angle):
        front_x = leg * math.cos(front_angle)
        front_y = 0.5 * hips + leg * math.sin(front_angle)
        return math.hypot(front_x - rear_x, front_y - rear_y) - span

    collinear = math.atan2(0.5 * hips - rear_y, -rear_x)
    low, high = collinear, collinear + branch * math.pi
    gap_low, gap_high = gap(low), gap(high)
    if gap_low * gap_high > 0:
        return low if abs(gap_low) < abs(gap_high) else high
    return brentq(gap, low, high, xtol=1e-14, rtol=4 * np.finfo(float).eps)


def fsolve_front_angle(rear_angle, span, rear_td, front_td, branch, leg, hips):
    """phi2 from closure (3) as two equations in (q1, phi2), by fsolve from touchdown."""
    def closure(unknowns):
        q, front_angle = unknowns
        return (-leg * math.cos(rear_angle) + span * math.cos(q - rear_angle)
                - leg * math.cos(front_angle),
                leg * math.sin(rear_angle) + span * math.sin(q - rear_angle) - hips
                - leg * math.sin(front_angle))

    rear_x, rear_y = -leg * math.cos(rear_td), leg * math.sin(rear_td)
    front_x, front_y = leg * math.cos(front_td), hips + leg * math.sin(front_td)
    q_touchdown = math.atan2(front_y - rear_y, front_x - rear_x) + rear_td
    solution, _, converged, _ = fsolve(closure, (q_touchdown, front_td), full_output=True,
                                       xtol=1e-13)
    collinear = math.atan2(hips - leg * math.sin(rear_angle), leg * math.cos(rear_angle))
    side = math.remainder(float(solution[1]) - collinear, 2 * math.pi)
    if converged != 1 or max(abs(v) for v in closure(solution)) > 1e-12 or side * branch < 0:
        # out of reach, or the mirror root: the model keeps the touchdown branch and holds
        # the closest configuration, as the tuned solver does
        return reference_front_angle(rear_angle, span, branch, leg, hips)
    return float(solution[1])


def reference_stance(rear_td, front_td, rear_lo, mirror, within, leg, hips,
                     solver='brentq'):
    """dx, dy (touchdown body frame) and dheading of G at a fraction of one stance."""
    def feet(rear_angle, front_angle):
        return ((-mirror * leg * math.cos(rear_angle), -0.5 * hips + leg * math.sin(rear_angle)),
                (mirror * leg * math.cos(front_angle), 0.5 * hips + leg * math.sin(front_angle)))

    rear0, front0 = feet(rear_td, front_td)
    span = math.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
    collinear = math.atan2(hips - leg * math.sin(rear_td), leg * math.cos(rear_td))
    branch = 1.0 if front_td >= collinear else -1.0
    rear_angle = rear_td + within * (rear_lo - rear_td)
    if solver == 'fsolve':
        front_angle = fsolve_front_angle(rear_angle, span, rear_td, front_td, branch, leg, hips)
    else:
        front_angle = reference_front_angle(rear_angle, span, branch, leg, hips)
    rear, front = feet(rear_angle, front_angle)
    dheading = (math.atan2(front0[1] - rear0[1], front0[0] - rear0[0])
                - math.atan2(front[1] - rear[1], front[0] - rear[0]))
    dheading = math.remainder(dheading, 2 * math.pi)
    cos_h, sin_h = math.cos(dheading), math.sin(dheading)
    return (rear0[0] - (cos_h * rear[0] - sin_h * rear[1]),
            rear0[1] - (sin_h * rear[0] + cos_h * rear[1]), dheading)


def reference_run(angles, phase, leg, hips, solver='brentq'):
    """(T, 3) poses of one run, (S, 6) angles, one sample at a time."""
    n_stances = len(angles)

    def stance(k, within):
        pair = k % 2
        return reference_stance(angles[k, 2 * pair], angles[k, 2 * pair + 1],
                                angles[k, 4 + pair], 1.0 if pair == 0 else -1.0, within,
                                leg, hips, solver)

    def compose(pose, motion):
        x, y, heading = pose
        dx, dy, dheading = motion
        sin_h, cos_h = math.sin(heading), math.cos(heading)
        return (x + sin_h * dx + cos_h * dy, y - cos_h * dx + sin_h * dy, heading + dheading)

    starts = [START]
    for k in range(n_stances - 1):
        starts.append(compose(starts[-1], stance(k, 1.0)))
    poses = np.empty((len(phase), 3))
    for j, value in enumerate(phase):
        k = min(max(int(math.floor(value)), 0), n_stances - 1)
        poses[j] = compose(starts[k], stance(k, min(max(value - k, 0.0), 1.0)))
    return poses


def best_time(function, repeats):
    times = []
    for _ in range(repeats):
        begin = time.perf_counter()
        function()
        times.append(time.perf_counter() - begin)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--runs', type=int, default=400,
                        help='runs for the reference comparison (default 400)')
    parser.add_argument('--seed', type=int, default=2)
    args = parser.parse_args()

    parameters = ModelParameters.nominal()
    sigma1, sigma2 = nominal_sigmas()
    cycles = 10
    t = parameters.time_grid(cycles)
    phase = 2 * parameters.stride_frequency * t
    normals = np.random.default_rng(args.seed).standard_normal((args.runs, 2 * cycles, 6))
    angles = stance_angles(parameters.nominal_angles, normals, sigma1, sigma2)
    leg, hips = parameters.leg_length, parameters.hip_distance
    samples = args.runs * len(t)

    begin = time.perf_counter()
    reference = np.stack([reference_run(run, phase, leg, hips) for run in angles])
    reference_seconds = time.perf_counter() - begin
    fsolve_runs = max(1, args.runs // 4)      # the slow reference: a quarter of the runs
    begin = time.perf_counter()
    straightforward = np.stack([reference_run(run, phase, leg, hips, 'fsolve')
                                for run in angles[:fsolve_runs]])
    fsolve_seconds = time.perf_counter() - begin
    fsolve_samples = fsolve_runs * len(t)

    model = integrate_stances(angles, phase, START, leg, hips)
    model_seconds = best_time(lambda: integrate_stances(angles, phase, START, leg, hips), 20)
    difference = float(np.abs(model - reference).max())
    fsolve_difference = float(np.abs(model[:fsolve_runs] - straightforward).max())
    if not (difference < 1e-9 and fsolve_difference < 1e-9):
        raise SystemExit(f'model and numeric references disagree by {difference:.3g}, '
                         f'{fsolve_difference:.3g}')

    om.simulate(10, seed=args.seed)  # warm-up (imports, config)
    big_runs = 20000
    big_seconds = best_time(lambda: om.simulate(big_runs, seed=args.seed, cycles=cycles), 3)
    big_samples = big_runs * len(t)

    rows = [
        ('scipy fsolve on (3) per sample', fsolve_samples, fsolve_seconds),
        ('scipy brentq per sample (tuned)', samples, reference_seconds),
        ('closed form, integrate_stances', samples, model_seconds),
        (f'om.simulate({big_runs}, seed={args.seed})', big_samples, big_seconds),
    ]
    print(f'{"method":<38} {"samples":>10} {"seconds":>9} {"samples/s":>12}')
    for name, count, seconds in rows:
        print(f'{name:<38} {count:>10d} {seconds:>9.4f} {count / seconds:>12.3g}')
    print(f'agreement with the references: max |difference| = {fsolve_difference:.2g} '
          f'(fsolve), {difference:.2g} (brentq) (m and rad, sigma = {sigma1}, {sigma2})')
    for name, rate in (('fsolve', fsolve_samples / fsolve_seconds),
                       ('brentq', samples / reference_seconds)):
        print(f'ratio closed form / {name}: {samples / model_seconds / rate:.0f}x '
              f'(same runs), {big_samples / big_seconds / rate:.0f}x (om.simulate)')


if __name__ == '__main__':
    main()
