"""Per-run features: the few numbers per run in which the contract's causes show.

Each feature answers one question about a run; together they are what the diagnosis compares
between measured and simulated runs:

| feature | what it measures | reveals |
| --- | --- | --- |
| start_heading | heading at t = 0, rad | initial_pose_error |
| start_x, start_y | position at t = 0, m | initial_pose_error, noise |
| log_jitter | log mean squared second difference of x, y (noise adds 6 s^2) | noise |
| slip_angle | mean angle heading -> direction of travel over cycles, rad | lateral_slip |
| stride_frequency | spectral peak of the heading's sway (once per cycle), Hz | gait frequency |
| progress_ratio | log(distance in 2nd half / distance in 1st half) | speed_decay |
| heading_rate | least-squares slope of heading over time, rad/s | persistent_turning |
| increment_var | within-run variance of the heading change per cycle, rad^2 | sigma1, sigma2 |
| end_lateral, end_progress | final displacement across / along the heading, m | spread |
| sway_amplitude | amplitude of the heading's sway at the stride frequency, rad | geometry |
| lateral_sway_1, _2 | amplitude of the sideways sway at f and 2f, m | geometry, slip |
"""
from __future__ import annotations

import numpy as np

from octoroach_model.paths import Paths
from octoroach_model.validation.gait import heading_sway

FEATURES = ('start_heading', 'start_x', 'start_y', 'log_jitter', 'slip_angle', 'stride_frequency',
            'progress_ratio', 'heading_rate', 'increment_var', 'end_lateral', 'end_progress',
            'sway_amplitude', 'lateral_sway_1', 'lateral_sway_2')
INDEX = {name: i for i, name in enumerate(FEATURES)}

# Smallest standard deviation a feature is taken to have (its resolution): keeps the Gaussian
# score finite where a model has no spread at all (e.g. the paper's model at t = 0).
RESOLUTION = np.array([1e-3, 1e-4, 1e-4, 0.05, 1e-3, 5e-3, 2e-3, 1e-3, 1e-6, 1e-4, 1e-4, 1e-3,
                       1e-5, 1e-5])


def run_features(paths: Paths, stride_frequency: float, reference_heading: float) -> np.ndarray:
    """(n, len(FEATURES)) features of each run; see the module table."""
    t, poses = paths.t, paths.poses
    dt = float(t[1] - t[0])
    xy, heading = poses[..., :2], poses[..., 2]
    n = poses.shape[0]
    out = np.empty((n, len(FEATURES)))
    out[:, 0] = heading[:, 0]
    out[:, 1:3] = xy[:, 0]
    second = np.diff(xy, n=2, axis=1)
    out[:, 3] = np.log((second ** 2).mean(axis=(1, 2)) + 1e-14)
    cycle = max(2, int(round(1.0 / (stride_frequency * dt))))
    out[:, 4] = _slip_angle(xy, heading, cycle)
    out[:, 5], out[:, 11] = heading_sway(heading, dt, stride_frequency)
    out[:, 12], out[:, 13] = _lateral_sway(xy, heading, t, out[:, 5])
    half = len(t) // 2
    first = np.linalg.norm(xy[:, half] - xy[:, 0], axis=-1)
    second_half = np.linalg.norm(xy[:, -1] - xy[:, half], axis=-1)
    out[:, 6] = np.log(np.maximum(second_half, 1e-9) / np.maximum(first, 1e-9))
    centred_t = t - t.mean()
    out[:, 7] = (heading - heading.mean(axis=1, keepdims=True)) @ centred_t \
        / (centred_t @ centred_t)
    later = heading[:, cycle::cycle]
    increments = later - heading[:, :-cycle:cycle][:, :later.shape[1]]
    out[:, 8] = increments.var(axis=1, ddof=1) if increments.shape[1] > 1 else 0.0
    end = xy[:, -1] - xy[:, 0]
    forward = np.array([np.cos(reference_heading), np.sin(reference_heading)])
    right = np.array([forward[1], -forward[0]])
    out[:, 9] = end @ right
    out[:, 10] = end @ forward
    return out


def _slip_angle(xy: np.ndarray, heading: np.ndarray, cycle: int) -> np.ndarray:
    """Mean over cycle-long windows of (direction of travel - mean heading in the window)."""
    step = xy[:, cycle:] - xy[:, :-cycle]
    travel = np.arctan2(step[..., 1], step[..., 0])
    kernel = np.ones(cycle + 1) / (cycle + 1)
    mean_heading = np.apply_along_axis(lambda h: np.convolve(h, kernel, mode='valid'), 1, heading)
    offset = travel - mean_heading
    return np.angle(np.exp(1j * offset)).mean(axis=1)


def _lateral_sway(xy: np.ndarray, heading: np.ndarray, t: np.ndarray,
                  frequency: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes of the sideways sway of G (across the run's mean heading, linear trend
    removed) at the stride frequency and twice it: the shape of a stance."""
    mean_heading = heading.mean(axis=1, keepdims=True)
    across = xy[..., 0] * np.sin(mean_heading) - xy[..., 1] * np.cos(mean_heading)
    centred_t = t - t.mean()
    slope = across @ centred_t / (centred_t @ centred_t)
    residual = across - across.mean(axis=1, keepdims=True) - slope[:, None] * centred_t
    window = np.hanning(len(t))
    amplitudes = []
    for harmonic in (1, 2):
        phase = np.exp(-2j * np.pi * harmonic * frequency[:, None] * t[None, :])
        amplitudes.append(2 * np.abs((residual * window * phase).sum(axis=1)) / window.sum())
    return amplitudes[0], amplitudes[1]
