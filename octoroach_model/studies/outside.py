"""
Effects made outside the model: data for testing the instrument on what it was not built from.

A swinging gait speed is described by no table cause and no extension family: the diagnosis
must report it as what it cannot explain (not adequate), and the terms it names beside it as
possible stand-ins. A yaw ramp was such an effect until the family yaw_rate_ramp described
it; made here, by turning the runs after they are simulated, it checks the family on data the
family's own code did not make. Both are the same in every run, for the suite's tests
(test_extensions.py) and for benchmarks/bench_out_of_library.py, which measures what the
reports say over robots. A leg that wears over the session is not: it changes the stride's
shape from run to run, which the family run_order_drift describes for each of the four legs
(touchdown_angle_1 .. _4); made here run by run, it checks that family as the ramp checks
its own.
"""
from __future__ import annotations

from dataclasses import replace
import math
from typing import Any

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.model.effects import perturb_heading
from octoroach_model.model.extensions import positions_in_order
from octoroach_model.model.parameters import ModelParameters
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


# the leg that wears by default, counted 1-4 as the terms count them (phi3, the left pair's
# rear leg): on Table II's robot 6 deg more turns a 5 s run by 10 deg less, where phi1 and
# phi2 move it by about 1 deg
WORN_LEG = 3


def leg_wear(n_runs: int, drift_deg: float, *, parameters: ModelParameters, seed: int,
             leg: int = WORN_LEG, **simulate_args: Any) -> Paths:
    """
    Return runs of a robot with a leg that wears over the session: a touchdown angle drifts.

    Run i of n, at its place q_i = i / (n - 1) in the session, strides with the touchdown
    angle phi_k + drift q_i (k = `leg`, 1-4; WORN_LEG, phi3, by default; the liftoff
    angles follow by the paper's eqs. 7-8), on a stream of its own (`SeedSequence([seed,
    i])`): the gait's shape moves from run to run. Made run by run with the model's own runs
    of each geometry, not by the family run_order_drift:touchdown_angle_k's code (which moves
    phi_k about the session's middle run and draws all runs at once).
    """
    if leg not in (1, 2, 3, 4):
        raise ValueError(f'leg must be 1, 2, 3 or 4 (phi1-phi4), not {leg!r}')
    runs = []
    for place, run in zip(positions_in_order(n_runs), range(n_runs)):
        phi = list(parameters.touchdown_angles)
        phi[leg - 1] += math.radians(drift_deg) * place
        worn = replace(parameters, touchdown_angles=(phi[0], phi[1], phi[2], phi[3]))
        stream = int(np.random.SeedSequence([seed, run]).generate_state(1)[0])
        runs.append(simulate(1, seed=stream, parameters=worn.with_paper_liftoff(),
                             **simulate_args))
    return Paths(runs[0].t, np.concatenate([paths.poses for paths in runs]))


def yaw_ramp(paths: Paths, final_yaw_rate_deg_s: float) -> Paths:
    """
    Return `paths` turned by a yaw rate rising from 0 to `final_yaw_rate_deg_s` (a motor heating).

    The heading gains 0.5 k t^2 (k the rate's rise per second over the grid's last time) and
    each sample step is turned with it.
    """
    ramp = math.radians(final_yaw_rate_deg_s) / float(paths.t[-1])
    heading = np.broadcast_to(0.5 * ramp * paths.t ** 2, paths.poses.shape[:2])
    return Paths(paths.t, perturb_heading(paths.poses, np.ascontiguousarray(heading)))


__all__ = ['leg_wear', 'speed_wobble', 'yaw_ramp']
