"""
Effects made outside the model: data for testing the instrument on what it was not built from.

A swinging gait speed is described by no table cause and no extension family: the diagnosis
must report it as what it cannot explain (not adequate), and the terms it names beside it as
possible stand-ins. A yaw ramp was such an effect until the family yaw_rate_ramp described
it; made here, by turning the runs after they are simulated, it checks the family on data the
family's own code did not make. Both are the same in every run, for the suite's tests
(test_extensions.py) and for benchmarks/bench_out_of_library.py, which measures what the
reports say over robots.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.model.effects import perturb_heading
from octoroach_model.model.simulate import simulate
from octoroach_model.paths import Paths


def speed_wobble(t: FloatArray, n_runs: int, amplitude: float, period_s: float,
                 **simulate_args: Any) -> Paths:
    """
    Return runs whose gait clock speeds up and slows down with a period (a controller hunting).

    tau(t) = t + A P / (2 pi) (1 - cos(2 pi t / P)): the speed swings by +-A around its mean.
    The model (`simulate_args`: seed, robot, spreads) is sampled at the warped times `tau` and
    its poses set on `t`.
    """
    swing = 1 - np.cos(2 * np.pi * t / period_s)
    tau = t + amplitude * period_s / (2 * np.pi) * swing
    return Paths(t, simulate(n_runs, t=tau, **simulate_args).poses)


def yaw_ramp(paths: Paths, final_yaw_rate_deg_s: float) -> Paths:
    """
    Return `paths` turned by a yaw rate rising from 0 to `final_yaw_rate_deg_s` (a motor heating).

    The heading gains 0.5 k t^2 (k the rate's rise per second over the grid's last time) and
    each sample step is turned with it.
    """
    ramp = math.radians(final_yaw_rate_deg_s) / float(paths.t[-1])
    heading = np.broadcast_to(0.5 * ramp * paths.t ** 2, paths.poses.shape[:2])
    return Paths(paths.t, perturb_heading(paths.poses, np.ascontiguousarray(heading)))


__all__ = ['speed_wobble', 'yaw_ramp']
