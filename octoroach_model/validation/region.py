"""
The confidence region a multisample defines and the decision g (eq. 13).

Choice (docs/validation.md, "The confidence region"): per time sample and per coordinate,
the Student-t prediction interval for one new run, mean +- t_{(1+gamma)/2, k-1} * s *
sqrt(1 + 1/k). A model run violates (g = 1) when any coordinate at any sample leaves its
interval. The floor on the half-width (the instrument's resolution) is applied by
`validate.Validation`.
"""
from __future__ import annotations

import numpy as np
from scipy import stats

from octoroach_model.arrays import FloatArray


def t_multiplier(k: int, gamma: float) -> float:
    """Half-width of the prediction interval in units of the sample standard deviation."""
    return float(stats.t.ppf(0.5 * (1.0 + gamma), df=k - 1) * np.sqrt(1.0 + 1.0 / k))


def prediction_region(samples: FloatArray, gamma: float) -> tuple[FloatArray, FloatArray]:
    """
    Centre and half-width of the region.

    Parameters
    ----------
    samples : array, shape (..., k, T, C)
        Measured runs of each multisample (C coordinates, m).
    gamma : float
        Coverage of the region, in (0, 1).

    Returns
    -------
    centre, half_width : arrays, shape (..., T, C)
        In the units of `samples`.

    """
    k = samples.shape[-3]
    centre = samples.mean(axis=-3)
    spread = samples.std(axis=-3, ddof=1)
    return centre, t_multiplier(k, gamma) * spread


def violations(model_runs: FloatArray, centre: FloatArray, half_width: FloatArray) -> FloatArray:
    """
    Decide g for each model run: 1 if it leaves its region anywhere.

    Parameters
    ----------
    model_runs : array, shape (..., T, C)
        Model runs, in the units of the region.
    centre, half_width : arrays, broadcastable to (..., T, C)
        `prediction_region`.

    Returns
    -------
    array, shape (...,)
        1.0 where a run leaves its region, else 0.0.

    """
    outside = np.abs(model_runs - centre) > half_width
    return outside.any(axis=(-2, -1)).astype(float)
