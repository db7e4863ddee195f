"""
The causes as the diagnosis sees them.

What each one moves, how its size is estimated, and the smallest size it may claim.

Two kinds of estimate (docs/diagnosis.md):

- **moments** (initial_pose_error, measurement_noise, gait_frequency_variation,
  persistent_turning): a statistic of the runs whose *variance-like* value grows linearly in
  the squared size, S(u) = S(0) + kappa u with u = size^2. S(0) and kappa come from runs of the
  current model simulated without and with the cause (common random numbers); the size is
  read off the line at the data's value of S.
- **path** (lateral_slip, speed_decay): the cause bends the average path, which the geometry
  alone could mimic, so its size is fitted jointly with the geometry (eq. 9 extended). The
  fit starts from the size its `signature` statistic (mean slip angle, mean speed ratio)
  reads off a line through the model without and with the cause: a geometry that has bent
  to mimic the cause would otherwise hold the fit in the wrong valley.

The **floor** of a cause is the smallest size that matters, which the diagnosis claims only when it
is sure the size exceeds it (decide.py), whatever the p-value:

| cause | floor | why |
| --- | --- | --- |
| initial_pose_error | 0.5 deg | below the orientation accuracy of a motion-capture body |
| measurement_noise | 0.01 cm | the motion capture's position resolution (0.1 mm) |
| gait_frequency_variation | 0.005 | a stride frequency 0.5 % off moves a run by 0.5 % |
| speed_decay | 0.01 | the stride frequency 1 % lower at the end of the run |
| lateral_slip | 1 % of the forward speed | a drift angle of 0.6 deg |
| persistent_turning | 1 deg per run | a turn of 1 deg over the run's duration |

The path-length and duration floors scale with the robot (`RunScale`): what matters for a fast
robot on long runs is smaller in absolute terms than for a slow one.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from octoroach_model.diagnosis.features import INDEX, MEDIAN_CHI2_1
from octoroach_model.model import EFFECT_NAMES, EFFECT_PARAMETERS

POSITION_RESOLUTION_M = 1e-4     # what motion capture resolves; no size below it is claimed


@dataclass(frozen=True)
class RunScale:
    """What the floors depend on: how long a run lasts and how far it goes."""

    duration_s: float
    path_length_m: float


@dataclass(frozen=True)
class Cause:
    """
    One cause of the table of causes, as a diagnosis candidate.

    `statistic` (moments causes) maps a feature matrix to the variance-like statistic S;
    `reference` is the size simulated to measure the slope kappa (the contract's unit);
    `floor` maps a RunScale to the smallest size claimed.
    """

    name: str
    unit: str
    kind: str                                   # 'moments' or 'path'
    statistic_name: str
    statistic: Callable[[np.ndarray], float] | None
    reference: float
    floor: Callable[[RunScale], float]
    signed: bool = False
    bounds: tuple[float, float] = (0.0, 1.0)    # sizes a fit may take (path causes)
    signature: Callable[[np.ndarray], float] | None = None   # path causes: where to start

    @property
    def parameter(self) -> str:
        """Return the main parameter: the first of the cause in the table of causes."""
        return EFFECT_PARAMETERS[self.name][0]

    def effects(self, size: float) -> dict[str, dict[str, float]]:
        """{cause: {main parameter: size}} (other parameters 0)."""
        return {self.name: {self.parameter: float(size)}}


def _variance_of(column: str) -> Callable[[np.ndarray], float]:
    index = INDEX[column]
    return lambda features: float(np.var(features[:, index], ddof=1))


def _mean_of(column: str) -> Callable[[np.ndarray], float]:
    index = INDEX[column]
    return lambda features: float(np.mean(features[:, index]))


def _noise_variance(features: np.ndarray) -> float:
    """Position noise variance (m^2) read from the median 4th differences (module features)."""
    return float(np.mean(np.exp(features[:, INDEX['log_noise']])) / (70.0 * MEDIAN_CHI2_1))


def _slip_floor(scale: RunScale) -> float:
    speed_cm_s = 100 * scale.path_length_m / max(scale.duration_s, 1e-3)
    return max(0.01 * speed_cm_s, POSITION_RESOLUTION_M * 100 / max(scale.duration_s, 1e-3))


CAUSES: tuple[Cause, ...] = (
    Cause('initial_pose_error', 'deg', 'moments', 'start heading variance',
          _variance_of('start_heading'), 4.0, lambda scale: 0.5),
    Cause('measurement_noise', 'cm', 'moments', 'position noise variance (median 4th '
          'difference)', _noise_variance, 0.05, lambda scale: POSITION_RESOLUTION_M * 100),
    Cause('gait_frequency_variation', '', 'moments', 'stride frequency variance across runs',
          _variance_of('stride_frequency'), 0.05, lambda scale: 0.005),
    Cause('speed_decay', '', 'path', 'average path (joint fit with the geometry)', None, 0.2,
          lambda scale: 0.01, signed=True, bounds=(-0.9, 0.9),
          signature=_mean_of('progress_ratio')),
    Cause('lateral_slip', 'cm/s', 'path', 'average path (joint fit with the geometry)', None,
          2.0, _slip_floor, signed=True, bounds=(-50.0, 50.0),
          signature=_mean_of('slip_angle')),
    Cause('persistent_turning', 'deg/s', 'moments', 'heading rate variance across runs',
          _variance_of('heading_rate'), 5.0, lambda scale: 1.0 / max(scale.duration_s, 1e-3)),
)
BY_NAME = {cause.name: cause for cause in CAUSES}
assert tuple(sorted(BY_NAME)) == tuple(sorted(EFFECT_NAMES))
