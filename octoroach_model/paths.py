"""`Paths`: runs of the robot on one common time grid, the currency between all layers.

Model output, measured runs after splitting and resampling, and everything the validation and
the diagnosis consume are `Paths`. Poses are planar: x [m], y [m], heading [rad], with heading
pi/2 meaning motion along +y (the robot's forward axis maps to (cos heading, sin heading)).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

X, Y, HEADING = 0, 1, 2


@dataclass(frozen=True)
class Paths:
    """n runs sampled at the same times.

    Attributes
    ----------
    t : (T,) seconds from each run's first sample, increasing.
    poses : (n, T, 3) x [m], y [m], heading [rad] (unwrapped along time).
    info : free-form provenance (seed, parameters, source bags, notes on skipped data).
    """

    t: np.ndarray
    poses: np.ndarray
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.poses.ndim != 3 or self.poses.shape[2] != 3:
            raise ValueError(f'poses must be (n, T, 3), got {self.poses.shape}')
        if self.poses.shape[1] != self.t.shape[0]:
            raise ValueError(f'{self.t.shape[0]} times but {self.poses.shape[1]} samples per run')

    @property
    def n_paths(self) -> int:
        return self.poses.shape[0]

    @property
    def rate_hz(self) -> float:
        return float((len(self.t) - 1) / (self.t[-1] - self.t[0])) if len(self.t) > 1 else 0.0

    @property
    def positions(self) -> np.ndarray:
        """(n, T, 2) x, y in metres."""
        return self.poses[..., :2]

    def subset(self, index) -> Paths:
        """The runs selected by `index` (an index array, slice or boolean mask)."""
        return Paths(self.t, self.poses[index], dict(self.info))

    def truncated(self, duration_s: float) -> Paths:
        """The runs cut to their first `duration_s` seconds (inclusive)."""
        keep = self.t <= duration_s + 1e-9
        return Paths(self.t[keep], self.poses[:, keep], dict(self.info))
