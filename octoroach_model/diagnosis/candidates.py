"""The candidate extensions and how each one's parameter is estimated from data.

Every candidate names one cause of the contract's table, a statistic of a run set that the
cause moves, and a grid of its main parameter. The parameter is estimated by simulated
moments: the extended model is simulated over the grid on common random numbers, and the
measured statistic is read off the (monotone) curve. Causes that move the average path are
instead fitted jointly with the geometry (eq. 9 extended).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from octoroach_model.diagnosis.features import INDEX


def _std_of(column: str) -> Callable[[np.ndarray], float]:
    return lambda features: float(np.std(features[:, INDEX[column]], ddof=1))


def _mean_of(column: str) -> Callable[[np.ndarray], float]:
    return lambda features: float(np.mean(features[:, INDEX[column]]))


def start_position_spread_m(features: np.ndarray) -> float:
    return float(np.sqrt(0.5 * (features[:, INDEX['start_x']].var(ddof=1)
                                + features[:, INDEX['start_y']].var(ddof=1))))


@dataclass(frozen=True)
class Candidate:
    """One cause as a diagnosis candidate."""

    cause: str
    parameter: str                       # the main parameter, contract units
    grid: tuple[float, ...]              # calibration values of the main parameter
    statistic: Callable[[np.ndarray], float]
    statistic_name: str
    signed: bool = False                 # the parameter can be negative
    refit_nominal: bool = False          # the effect moves the average path: refit eq. 9 with it

    def effects(self, value: float, extra: dict[str, float] | None = None) -> dict:
        return {self.cause: {self.parameter: value, **(extra or {})}}


CANDIDATES: tuple[Candidate, ...] = (
    Candidate('initial_pose_error', 'heading_std_deg', (0, 1, 2, 4, 7, 11, 16, 25),
              _std_of('start_heading'), 'start heading spread'),
    Candidate('measurement_noise', 'position_std_cm', (0, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6),
              _mean_of('log_jitter'), 'position jitter'),
    Candidate('gait_frequency_variation', 'relative_std',
              (0, 0.01, 0.02, 0.04, 0.07, 0.11, 0.16, 0.25),
              _std_of('stride_frequency'), 'stride frequency spread across runs'),
    Candidate('speed_decay', 'fraction', (-0.5, -0.2, 0, 0.2, 0.5),
              _mean_of('progress_ratio'), 'log speed ratio, 2nd half / 1st half', signed=True,
              refit_nominal=True),
    Candidate('lateral_slip', 'velocity_cm_s', (-5, -2, 0, 2, 5),
              _mean_of('slip_angle'), 'heading to travel angle', signed=True,
              refit_nominal=True),
    Candidate('persistent_turning', 'yaw_rate_std_deg_s', (0, 0.5, 1, 2, 4, 7, 11, 18),
              _std_of('heading_rate'), 'heading rate spread across runs'),
)
BY_CAUSE = {candidate.cause: candidate for candidate in CANDIDATES}

def read_off_curve(grid: np.ndarray, curve: np.ndarray, value: float, signed: bool) -> float:
    """The parameter whose statistic equals `value`, by linear interpolation on the curve.

    The curve is made monotone first (running maximum, or minimum if it falls): the simulated
    statistic carries Monte Carlo noise, the true one is monotone in the parameter.
    """
    increasing = curve[-1] >= curve[0]
    ordered = curve if increasing else -curve
    target = value if increasing else -value
    monotone = np.maximum.accumulate(ordered)
    if target <= monotone[0]:
        return float(grid[0]) if signed else 0.0
    if target >= monotone[-1]:
        return float(grid[-1])
    # strictly increasing support for np.interp: drop flat repeats
    keep = np.concatenate([[True], np.diff(monotone) > 0])
    return float(np.interp(target, monotone[keep], np.asarray(grid)[keep]))


def direct_extra_parameters(cause: str, train_features: np.ndarray,
                            baseline_features: np.ndarray) -> dict[str, float]:
    """Secondary parameters estimated directly (excess variance over the baseline)."""
    if cause != 'initial_pose_error':
        return {}
    excess = start_position_spread_m(train_features) ** 2 \
        - start_position_spread_m(baseline_features) ** 2
    return {'position_std_cm': float(math.sqrt(max(excess, 0.0)) * 100)}
