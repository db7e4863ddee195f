"""How well a model predicts held-out runs: proper scores per run, and their comparison.

- **Feature score** (the decision's score): the continuous ranked probability score (CRPS) of
  each of a run's features against the model's simulated runs, every feature divided by its
  spread in the calibration half (so no feature's unit decides), summed over the features.
  It is proper, it stays finite where a model has no spread at all (a model that starts every
  run at one point), and a gain in one feature is not diluted by the others' noise, as it is
  in a multivariate energy score. Unit: the data's spread.
- **Position energy score** (cm): the same on the run's positions at 20/40/60/80/100 % of
  its duration, for a reader who thinks in centimetres.
- **Log score** (nats): the Gaussian synthetic likelihood of the features, over the features
  in which both models predict a spread of at least a tenth of the data's (a model with no
  spread in a feature has no finite log score there; those features are scored by the energy
  score only, so no floor decides the number).
- **Ideal**: the same scores of the held-out runs against the calibration runs themselves
  (data predicting data). `relative` gains are the share of the baseline's excess over this
  ideal that a model removes.

Every comparison is paired run by run: the per-run gain's mean, and a one-sided t-test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from octoroach_model.diagnosis.features import RESOLUTION

ENERGY_FRACTIONS = (0.2, 0.4, 0.6, 0.8, 1.0)
PAIR_RUNS = 400           # model runs used for the energy score's spread term
LOG_SCORE_MIN_SPREAD = 0.1
NUMERICAL_NOISE = 1e-6    # per-run score differences below this are rounding, not evidence


@dataclass(frozen=True)
class Scores:
    """Per held-out run scores of one model (lower is better for energy, higher for log)."""

    features: np.ndarray            # feature score (summed CRPS), data spreads
    energy_cm: np.ndarray           # position energy score, cm
    model_spread: np.ndarray        # (F,) the model's standardised feature spreads


def feature_scales(calibration_features: np.ndarray) -> np.ndarray:
    """Each feature's spread over the calibration runs (never below its resolution)."""
    return np.maximum(np.std(calibration_features, axis=0, ddof=1), RESOLUTION)


def crps_sum(sample: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Sum over columns of the CRPS of each observed row against the sample (lower is
    better): E|X - y| - E|X - X'| / 2 per column, from the sorted sample in O(n log n)."""
    n = sample.shape[0]
    total = np.zeros(observed.shape[0])
    weights = (2 * np.arange(1, n + 1) - n - 1) / n ** 2
    for column in range(sample.shape[1]):
        ordered = np.sort(sample[:, column])
        sums = np.concatenate([[0.0], np.cumsum(ordered)])
        y = observed[:, column]
        below = np.searchsorted(ordered, y, side='right')
        to_observed = (y * below - sums[below] + (sums[-1] - sums[below])
                       - y * (n - below)) / n
        total += to_observed - weights @ ordered
    return total


def energy_score(sample: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Energy score of each observed row against the sample rows (lower is better)."""
    distances = np.sqrt(((sample[None, :, :] - observed[:, None, :]) ** 2).sum(axis=-1))
    to_observed = distances.mean(axis=1)
    pairs = sample[:PAIR_RUNS]
    half = len(pairs) // 2
    spread = np.sqrt(((pairs[:half] - pairs[half:2 * half]) ** 2).sum(axis=-1)).mean()
    return to_observed - 0.5 * spread


def position_points_cm(positions: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(n, 2 x len(ENERGY_FRACTIONS)) positions (cm) at fractions of each run's duration,
    relative to the run's start."""
    rows = np.arange(positions.shape[0])
    last = np.maximum(lengths - 1, 0)
    picks = [np.rint(fraction * last).astype(int) for fraction in ENERGY_FRACTIONS]
    points = [positions[rows, pick] - positions[:, 0] for pick in picks]
    return np.concatenate(points, axis=1) * 100.0


def score_model(model_features: np.ndarray, model_points_cm: np.ndarray,
                observed_features: np.ndarray, observed_points_cm: np.ndarray,
                scales: np.ndarray) -> Scores:
    """Scores of the observed (held-out) runs under a model's simulated runs."""
    model_standard = model_features / scales
    observed_standard = observed_features / scales
    return Scores(crps_sum(model_standard, observed_standard),
                  energy_score(model_points_cm, observed_points_cm),
                  np.std(model_standard, axis=0, ddof=1))


def log_scores(first: np.ndarray, second: np.ndarray, observed: np.ndarray,
               scales: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Gaussian log scores (nats, higher is better) of the observed runs under two models'
    simulated features, over the features where both have at least LOG_SCORE_MIN_SPREAD of
    the data's spread; returns both score arrays and the features used."""
    first, second, observed = first / scales, second / scales, observed / scales
    usable = [index for index in range(first.shape[1])
              if min(np.std(first[:, index]), np.std(second[:, index])) >= LOG_SCORE_MIN_SPREAD]
    if not usable:
        zero = np.zeros(observed.shape[0])
        return zero, zero.copy(), []
    return (_gaussian_log_score(first[:, usable], observed[:, usable]),
            _gaussian_log_score(second[:, usable], observed[:, usable]), usable)


def _gaussian_log_score(sample: np.ndarray, observed: np.ndarray) -> np.ndarray:
    mean = sample.mean(axis=0)
    covariance = np.atleast_2d(np.cov(sample, rowvar=False))
    covariance = covariance + np.eye(len(mean)) * 1e-6 * np.trace(covariance) / len(mean)
    return np.atleast_1d(stats.multivariate_normal(mean, covariance,
                                                   allow_singular=True).logpdf(observed))


@dataclass(frozen=True)
class PairedGain:
    """Per-run gain of one model over another on held-out runs, and its one-sided test."""

    mean: float
    standard_error: float
    p_value: float

    @classmethod
    def of(cls, improvement: np.ndarray) -> PairedGain:
        """`improvement` per run (positive: the second model predicts the run better)."""
        improvement = np.asarray(improvement, dtype=float)
        mean = float(improvement.mean())
        if len(improvement) < 3:
            return cls(mean, math.inf, 1.0)
        if float(np.max(np.abs(improvement))) < NUMERICAL_NOISE:
            return cls(0.0, 0.0, 1.0)           # the same model up to rounding: no evidence
        standard_error = float(improvement.std(ddof=1) / math.sqrt(len(improvement)))
        if standard_error <= 1e-12 * (1 + abs(mean)):
            return cls(mean, 0.0, 0.0 if mean > 1e-9 else 1.0)
        p_value = float(stats.t.sf(mean / standard_error, df=len(improvement) - 1))
        return cls(mean, standard_error, p_value)
