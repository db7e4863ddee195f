"""
The covariance of a mean-path fit's vector, without refitting; how sure the runs are of it.

Two sources of error, each resampled and carried to the vector by one Gauss-Newton step from
the fit (`-pinv(jacobian) @ d(residual)`): the measured runs (a bootstrap over runs) and the
simulated runs whose mean the model is (a bootstrap of their antithetic pairs). Only the first
shrinks with more measured runs (diagnosis/power.py), so the two are returned apart.
The same resamples of the runs say whether they prefer one of two fits (two valleys of the
objective) over the other: `cost_gap_se` is the spread of the cost gap between them.
"""
from __future__ import annotations

import numpy as np

from octoroach_model.arrays import FloatArray, IntArray
from octoroach_model.fitting.nominal import MeanPathSettings, NominalFit, simulated_runs
from octoroach_model.fitting.target import AverageTarget, residual_vector, ResidualScales


def path_covariance(fit: NominalFit, target: AverageTarget, data_gait: FloatArray,
                    mean: MeanPathSettings, seed: int, n_boot: int = 60
                    ) -> tuple[FloatArray, FloatArray]:
    """
    Return the covariance of the fit's vector from the measured and from the simulated runs.

    `target` is what the fit matched, `data_gait` (n, 5) each measured run's gait target values
    (their means the target), `mean` the fit's simulated runs (with the gait matched), `seed` that
    of the resamples.

    Returns
    -------
    measured, simulated : arrays, shape (p, p)
        Covariances of the fit's p parameters (the fit's vector's units).

    """
    assert fit.jacobian is not None, 'a fit by least squares has its Jacobian'
    pseudo_inverse = np.linalg.pinv(fit.jacobian)
    gait = mean.gait
    assert gait is not None, 'the covariance is of a fit with the gait matched'
    full = simulated_runs(fit.parameters, fit.start_pose, gait.t, fit.effects, mean)
    model_gait = gait.of_runs(full, fit.parameters.stride_frequency)
    runs = full[:, :len(target.t)]

    def vector(xy: FloatArray, turn: FloatArray, gait: FloatArray) -> FloatArray:
        return residual_vector(xy, turn, gait, fit.heading_weight_m, mean.scales)

    rng = np.random.default_rng([seed, 17])
    changes = target_changes(target, data_gait, fit.heading_weight_m, mean.scales, rng, n_boot)
    data_steps = [pseudo_inverse @ change for change in changes]
    half = mean.runs // 2
    pairs = 0.5 * (runs[:half] + runs[half:2 * half])          # antithetic pair means
    pair_gait = 0.5 * (model_gait[:half] + model_gait[half:2 * half])
    centre = vector(pairs[..., :2].mean(axis=0), pairs[..., 2].mean(axis=0),
                    pair_gait.mean(axis=0))
    weights = resample_weights(rng, half, n_boot)
    paths, gaits = resampled_means(weights, pairs), resampled_means(weights, pair_gait)
    model_steps = [pseudo_inverse @ (vector(path[..., :2], path[..., 2], gait) - centre)
                   for path, gait in zip(paths, gaits)]
    measured = np.atleast_2d(np.cov(np.array(data_steps), rowvar=False))
    simulated = np.atleast_2d(np.cov(np.array(model_steps), rowvar=False))
    return measured, simulated


def target_changes(target: AverageTarget, data_gait: FloatArray, heading_weight_m: float,
                   scales: ResidualScales | None, rng: np.random.Generator, n_boot: int
                   ) -> FloatArray:
    """
    Return how the fit's target moves when the measured runs are resampled: (n_boot, m).

    Each row is the change of the target's residual vector (`residual_vector` of the data's
    average path, heading and gait) under one bootstrap resample of the runs; a fit's
    residuals move by minus it.
    """
    def vector(xy: FloatArray, turn: FloatArray, gait: FloatArray) -> FloatArray:
        return residual_vector(xy, turn, gait, heading_weight_m, scales)

    base = vector(target.average, target.turn, np.nanmean(data_gait, axis=0))
    weights = resample_weights(rng, len(data_gait), n_boot)
    averages, turns, gaits = (resampled_means(weights, values) for values in
                              (target.runs_xy, target.runs_turn, data_gait))
    return np.array([vector(average, turn, gait) - base
                     for average, turn, gait in zip(averages, turns, gaits)]
                    ).reshape(n_boot, len(base))


def resample_picks(rng: np.random.Generator, n: int, n_boot: int) -> IntArray:
    """
    Return the items of `n_boot` bootstrap resamples of `n` items: (n_boot, n) indices.

    Drawn one resample after the other, each as `rng.integers(0, n, n)`: one (n_boot, n)
    draw gives other items for odd n (numpy draws bounded integers in buffered 32-bit
    halves per call), and a seed must give the items it always gave.
    """
    return np.array([rng.integers(0, n, n) for _ in range(n_boot)],
                    dtype=np.intp).reshape(n_boot, n)


def resample_weights(rng: np.random.Generator, n: int, n_boot: int) -> FloatArray:
    """Return how often each of `n` items is drawn in each resample (`resample_picks`)."""
    picks = resample_picks(rng, n, n_boot)
    # every resample's counts in one bincount: resample b's items numbered from b n
    counts = np.bincount((picks + n * np.arange(n_boot)[:, None]).ravel(),
                         minlength=n_boot * n)
    return counts.reshape(n_boot, n).astype(float)


def resampled_means(weights: FloatArray, values: FloatArray) -> FloatArray:
    """
    Return the mean of `values` (n, ...) over its first axis in each resample: (n_boot, ...).

    NaN entries (a run that has ended) are left out of their mean, as `np.nanmean` does;
    all resamples in one product, not a copy of the values each.
    """
    flat = values.reshape(len(values), -1)
    present = np.isfinite(flat)
    with np.errstate(invalid='ignore', divide='ignore'):
        means = (weights @ np.where(present, flat, 0.0)) / (weights @ present)
    return means.reshape(len(weights), *values.shape[1:])


def cost_gap_se(residuals: FloatArray, rival_residuals: FloatArray,
                changes: FloatArray) -> float:
    """
    Return the standard error of the cost gap between two fits over resamples of the runs.

    Each fit's cost is half its sum of squared residuals; when the target moves by `change`
    the gap between the two moves by exactly -(rival - fit) . change (the squares of the
    change cancel), so its spread over the bootstrap changes (`target_changes`) is the gap's
    standard error, with the two models held where they are (refitting each moves its cost
    by the same amount to first order).
    """
    moves = changes @ (np.asarray(rival_residuals) - np.asarray(residuals))
    return float(np.std(moves, ddof=1)) if len(moves) > 1 else 0.0
