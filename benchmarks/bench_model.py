"""Throughput of the model: closed-form, vectorised kinematics against a numeric reference.

The reference is the straightforward way to run the switching four-bar: for every sample,
solve closure (3), |O2 - O1| = aR, for the front angle phi2 with scipy's brentq, then apply
the same pose formulas (rear foot fixed in the world, heading from the foot-to-foot segment)
and chain the stances. Both run on the same seeded angle draws; the benchmark checks that
they agree, then prints pose samples per second for each and their ratio, and times
`om.simulate(20000, seed=2)` (10 cycles, 251 samples per run: the issue's target, ~1 s).

Run: .venv/bin/python benchmarks/bench_model.py [--runs N] [--seed S]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import brentq

import octoroach_model as om
from octoroach_model.model.kinematics import integrate_stances, stance_angles
from octoroach_model.model.parameters import ModelParameters, nominal_sigmas

START = (0.0, 0.0, math.pi / 2)


def reference_front_angle(rear_angle, span, branch, leg, hips):
    """phi2 with |O2 - O1| = span, by brentq on the touchdown branch (pair's own frame).

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


def reference_stance(rear_td, front_td, rear_lo, mirror, within, leg, hips):
    """dx, dy (touchdown body frame) and dheading of G at a fraction of one stance."""
    def feet(rear_angle, front_angle):
        return ((-mirror * leg * math.cos(rear_angle), -0.5 * hips + leg * math.sin(rear_angle)),
                (mirror * leg * math.cos(front_angle), 0.5 * hips + leg * math.sin(front_angle)))

    rear0, front0 = feet(rear_td, front_td)
    span = math.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
    collinear = math.atan2(hips - leg * math.sin(rear_td), leg * math.cos(rear_td))
    branch = 1.0 if front_td >= collinear else -1.0
    rear_angle = rear_td + within * (rear_lo - rear_td)
    front_angle = reference_front_angle(rear_angle, span, branch, leg, hips)
    rear, front = feet(rear_angle, front_angle)
    dheading = (math.atan2(front0[1] - rear0[1], front0[0] - rear0[0])
                - math.atan2(front[1] - rear[1], front[0] - rear[0]))
    dheading = math.remainder(dheading, 2 * math.pi)
    cos_h, sin_h = math.cos(dheading), math.sin(dheading)
    return (rear0[0] - (cos_h * rear[0] - sin_h * rear[1]),
            rear0[1] - (sin_h * rear[0] + cos_h * rear[1]), dheading)


def reference_run(angles, phase, leg, hips):
    """(T, 3) poses of one run, (S, 6) angles, one sample at a time."""
    n_stances = len(angles)

    def stance(k, within):
        pair = k % 2
        return reference_stance(angles[k, 2 * pair], angles[k, 2 * pair + 1],
                                angles[k, 4 + pair], 1.0 if pair == 0 else -1.0, within,
                                leg, hips)

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
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
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

    model = integrate_stances(angles, phase, START, leg, hips)
    model_seconds = best_time(lambda: integrate_stances(angles, phase, START, leg, hips), 20)
    difference = float(np.abs(model - reference).max())
    if not difference < 1e-9:
        raise SystemExit(f'model and numeric reference disagree by {difference:.3g}')

    om.simulate(10, seed=args.seed)  # warm-up (imports, config)
    big_runs = 20000
    big_seconds = best_time(lambda: om.simulate(big_runs, seed=args.seed, cycles=cycles), 3)
    big_samples = big_runs * len(t)

    rows = [
        ('scipy brentq per sample (reference)', samples, reference_seconds),
        ('closed form, integrate_stances', samples, model_seconds),
        (f'om.simulate({big_runs}, seed={args.seed})', big_samples, big_seconds),
    ]
    print(f'{"method":<38} {"samples":>10} {"seconds":>9} {"samples/s":>12}')
    for name, count, seconds in rows:
        print(f'{name:<38} {count:>10d} {seconds:>9.4f} {count / seconds:>12.3g}')
    reference_rate = samples / reference_seconds
    print(f'agreement with the reference: max |difference| = {difference:.2g} '
          f'(m and rad, {args.runs} runs x {len(t)} samples, sigma = {sigma1}, {sigma2})')
    print(f'ratio closed form / reference: {samples / model_seconds / reference_rate:.0f}x '
          f'(same runs), {big_samples / big_seconds / reference_rate:.0f}x (om.simulate)')


if __name__ == '__main__':
    main()
