"""
The model extensions of the table of causes (docs/causes.md), exactly as defined there.

Two kinds: time warps act on the gait phase before the kinematics are evaluated
(`gait_frequency_variation`, `speed_decay`); the others transform finished runs
(`persistent_turning`, `lateral_slip`, `initial_pose_error`, `measurement_noise`). Parameter
names and units are the table's (cm, deg where the key says so). Each effect draws its own
random numbers from its own generator, so adding one leaves every other draw unchanged
(common random numbers across models).
"""
from __future__ import annotations

from collections.abc import Mapping
import math
from typing import Protocol

import numpy as np

from octoroach_model.errors import ParameterError

# Canonical order of application; also the order of their random streams.
EFFECT_PARAMETERS: dict[str, tuple[str, ...]] = {
    'gait_frequency_variation': ('relative_std',),
    'speed_decay': ('fraction',),
    'persistent_turning': ('yaw_rate_std_deg_s',),
    'lateral_slip': ('velocity_cm_s',),
    'initial_pose_error': ('heading_std_deg', 'position_std_cm'),
    'measurement_noise': ('position_std_cm',),
}
EFFECT_NAMES = tuple(EFFECT_PARAMETERS)
TIME_WARPS = ('gait_frequency_variation', 'speed_decay')

# Ranges accepted for each parameter (inclusive), in the parameter's own unit.
PARAMETER_RANGES: dict[str, tuple[float, float]] = {
    'relative_std': (0.0, 0.5),
    'fraction': (-0.9, 0.9),
    'yaw_rate_std_deg_s': (0.0, 90.0),
    'velocity_cm_s': (-50.0, 50.0),
    'heading_std_deg': (0.0, 90.0),
    'position_std_cm': (0.0, 50.0),
}

Effects = Mapping[str, Mapping[str, float]]


def check_effects(effects: Effects | None) -> dict[str, dict[str, float]]:
    """Check an effects mapping {name: {parameter: value}}; return a copy, missing ones 0."""
    checked: dict[str, dict[str, float]] = {}
    for name, params in (effects or {}).items():
        if name not in EFFECT_PARAMETERS:
            raise ParameterError(f'unknown effect {name!r}; known: {", ".join(EFFECT_NAMES)}')
        extra = set(params) - set(EFFECT_PARAMETERS[name])
        if extra:
            raise ParameterError(f'effect {name} has no parameter {sorted(extra)[0]!r}; '
                                 f'it takes {", ".join(EFFECT_PARAMETERS[name])}')
        values = {}
        for key in EFFECT_PARAMETERS[name]:
            value = float(params.get(key, 0.0))
            low, high = PARAMETER_RANGES[key]
            if not (math.isfinite(value) and low <= value <= high):
                raise ParameterError(f'{name}.{key} = {value} is outside [{low}, {high}]')
            values[key] = value
        checked[name] = values
    return {name: checked[name] for name in EFFECT_NAMES if name in checked}


class NormalSource(Protocol):
    """Where an effect draws its normals: a numpy Generator, or one giving antithetic pairs."""

    def standard_normal(self, size: int | tuple[int, ...]) -> np.ndarray:
        """Draw standard normals of shape `size`."""


def warped_time(effects: Effects, t: np.ndarray, n_runs: int,
                rngs: Mapping[str, NormalSource]) -> np.ndarray:
    """
    Give the (n, T) gait clock: the times at which the unwarped model is evaluated.

    speed_decay warps first, then each run's gait_frequency_variation stretches the result:
    clock = (1 + e) (t - fraction t^2 / (2 T)).
    """
    clock = np.broadcast_to(t, (n_runs, len(t))).astype(float)
    duration = float(t[-1]) if len(t) else 0.0
    if 'speed_decay' in effects and duration > 0:
        fraction = effects['speed_decay']['fraction']
        clock = clock - fraction * clock ** 2 / (2.0 * duration)
    if 'gait_frequency_variation' in effects:
        std = effects['gait_frequency_variation']['relative_std']
        stretch = 1.0 + std * rngs['gait_frequency_variation'].standard_normal(n_runs)
        clock = clock * stretch[:, None]
    return clock


def mean_gait_rate(effects: Effects) -> float:
    """
    Return the gait clock's mean rate over a run, relative to the model's stride frequency.

    speed_decay's clock runs at 1 - fraction t / T, on average 1 - fraction / 2: the stride
    frequency seen in a run (a spectral peak) is the model's times this.
    """
    if 'speed_decay' not in effects:
        return 1.0
    return 1.0 - 0.5 * float(effects['speed_decay']['fraction'])


def apply_pose_effects(poses: np.ndarray, t: np.ndarray, effects: Effects,
                       rngs: Mapping[str, NormalSource]) -> np.ndarray:
    """Apply the non-warp effects to runs, in canonical order. poses: (n, T, 3), SI."""
    poses = poses.copy()
    n_runs = poses.shape[0]
    if 'persistent_turning' in effects:
        std = math.radians(effects['persistent_turning']['yaw_rate_std_deg_s'])
        yaw_rate = std * rngs['persistent_turning'].standard_normal(n_runs)
        poses = turn_persistently(poses, t, yaw_rate)
    if 'lateral_slip' in effects:
        velocity = effects['lateral_slip']['velocity_cm_s'] / 100.0
        poses = slip_sideways(poses, t, velocity)
    if 'initial_pose_error' in effects:
        params = effects['initial_pose_error']
        rng = rngs['initial_pose_error']
        dheading = math.radians(params['heading_std_deg']) * rng.standard_normal(n_runs)
        shift = params['position_std_cm'] / 100.0 * rng.standard_normal((n_runs, 2))
        poses = rotate_about_start(poses, dheading)
        poses[..., :2] += shift[:, None, :]
    if 'measurement_noise' in effects:
        std = effects['measurement_noise']['position_std_cm'] / 100.0
        poses[..., :2] += std * rngs['measurement_noise'].standard_normal(poses[..., :2].shape)
    return poses


def rotate_about_start(poses: np.ndarray, dheading: np.ndarray) -> np.ndarray:
    """Rotate each run by its own angle about its first position."""
    start = poses[:, :1, :2]
    rel = poses[..., :2] - start
    cos_d, sin_d = np.cos(dheading)[:, None], np.sin(dheading)[:, None]
    out = poses.copy()
    out[..., 0] = start[..., 0] + cos_d * rel[..., 0] - sin_d * rel[..., 1]
    out[..., 1] = start[..., 1] + sin_d * rel[..., 0] + cos_d * rel[..., 1]
    out[..., 2] = poses[..., 2] + dheading[:, None]
    return out


def turn_persistently(poses: np.ndarray, t: np.ndarray, yaw_rate: np.ndarray) -> np.ndarray:
    """
    Turn each run at its rate w: theta + w t, p(0) + integral of R(w s) p_dot(s) ds.

    The integral is a sum over sample steps, each step rotated by w at its midpoint time.
    """
    steps = np.diff(poses[..., :2], axis=1)
    mid_angle = yaw_rate[:, None] * 0.5 * (t[1:] + t[:-1])[None, :]
    cos_a, sin_a = np.cos(mid_angle), np.sin(mid_angle)
    turned = np.stack([cos_a * steps[..., 0] - sin_a * steps[..., 1],
                       sin_a * steps[..., 0] + cos_a * steps[..., 1]], axis=-1)
    out = poses.copy()
    out[:, 1:, :2] = poses[:, :1, :2] + np.cumsum(turned, axis=1)
    out[..., 2] = poses[..., 2] + yaw_rate[:, None] * t[None, :]
    return out


def slip_sideways(poses: np.ndarray, t: np.ndarray, velocity: float) -> np.ndarray:
    """
    Add a sideways drift: p + integral of v r(theta) ds, r = (sin theta, -cos theta).

    The integral follows the trapezoid rule on the sample times.
    """
    heading = poses[..., 2]
    right = np.stack([np.sin(heading), -np.cos(heading)], axis=-1)
    dt = np.diff(t)[None, :, None]
    drift = np.cumsum(0.5 * (right[:, 1:] + right[:, :-1]) * dt, axis=1) * velocity
    out = poses.copy()
    out[:, 1:, :2] += drift
    return out
