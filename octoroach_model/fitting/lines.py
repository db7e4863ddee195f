"""
Sizes read off lines through simulated points, and the bootstrap errors they carry.

A size that a statistic S grows with (u = size^2 for a spread, the size itself for a drift)
is read off the line (or piecewise line) through S of simulated runs at a few sizes; the
errors of S on data and on simulated runs come from resampling runs.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from octoroach_model.arrays import FloatArray

Statistic = Callable[[FloatArray], float]


def read_line(points: dict[float, float], target: float) -> float:
    """
    Return u where the piecewise-linear line through (u, S) points reaches `target`.

    Extrapolated beyond the ends; points made monotone by a running maximum.
    """
    us = np.array(sorted(points))
    values = np.maximum.accumulate(np.array([points[u] for u in us]))
    if len(us) == 1 or values[-1] <= values[0]:
        return float(us[0])
    index = int(np.clip(np.searchsorted(values, target) - 1, 0, len(us) - 2))
    while index < len(us) - 2 and values[index + 1] <= values[index]:
        index += 1
    u0, u1, s0, s1 = us[index], us[index + 1], values[index], values[index + 1]
    if s1 <= s0:
        return float(u0)
    return float(u0 + (target - s0) * (u1 - u0) / (s1 - s0))


def paired_relative_se(statistic: Statistic, without: FloatArray, with_cause: FloatArray,
                       rng: np.random.Generator, n_boot: int) -> float:
    """
    Return the relative error of S(with) - S(without) on the same simulated runs.

    Runs are resampled in pairs: run i of both sets shares its random numbers.

    Parameters
    ----------
    statistic : function of an (n, F) array
        S.
    without, with_cause : arrays, shape (n, F)
        Features of the same simulated runs without and with the cause.
    rng : numpy Generator
        Draws the resamples.
    n_boot : int
        Resamples.

    """
    n = min(without.shape[0], with_cause.shape[0])
    difference = statistic(with_cause[:n]) - statistic(without[:n])
    if not difference > 0:
        return 0.0
    values = []
    for _ in range(n_boot):
        picks = rng.integers(0, n, n)
        values.append(statistic(with_cause[picks]) - statistic(without[picks]))
    return float(np.std(values, ddof=1)) / difference


def bootstrap_se(statistic: Statistic, features: FloatArray, rng: np.random.Generator,
                 n_boot: int) -> float:
    """
    Return the standard error of `statistic` over the runs (rows) of `features`.

    Parameters
    ----------
    statistic : function of an (n, F) array
        The statistic.
    features : array, shape (n, F)
        Run features, SI units.
    rng : numpy Generator
        Draws the resamples.
    n_boot : int
        Resamples.

    """
    n = features.shape[0]
    values = [statistic(features[rng.integers(0, n, n)]) for _ in range(n_boot)]
    return float(np.std(values, ddof=1))
