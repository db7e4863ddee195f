"""
How well a model predicts held-out runs: proper scores per run, and their comparison.

- **Feature log score** (nats per run, higher is better; the one that decides): the log
  density of each of a run's features under a normal distribution with the mean and spread
  of the model's simulated runs, every feature in units of its spread in the calibration
  half, summed over the features. A model is never credited with less than a quarter of the
  data's spread in any feature (FLOOR): a model that predicts no spread at all (the paper's
  model starts every run at one point) then costs at most about 8 nats per run in that
  feature instead of an unbounded amount, so no floor dominates a reported gain. Summing
  per feature keeps a gain in one feature from being diluted by the others' noise, and the
  log score is the most powerful of the proper scores for a change of spread.
- **Position energy score** (cm per run, lower is better): the energy score of the run's
  positions at 20/40/60/80/100 % of its duration against the model's, for a reader who thinks
  in centimetres.
- **Ideal**: the same scores of the held-out runs against the calibration runs themselves
  (data predicting data). A relative gain is the share of the gap between a model and this
  ideal that another model closes.

A model whose terms depend on the run's place in the recording (run_order_drift) predicts each
held-out run at its place: the mean of each feature is the least-squares line of the model's
simulated runs against their places, the spread that line's residual spread (the place is a
covariate, `features.COVARIATES`, and never itself scored). Every other model predicts all
runs alike, as before.

Every comparison is paired run by run: the per-run gain's mean, and a one-sided t-test.
The held-out runs are not the t's only source of error: each model's mean and spread come
from its simulated runs, and other simulated runs give another t. `t_scoring_se` says how
much, by resampling the scored runs of both models together (a run of each drew the same
random numbers), the held-out runs fixed: the part of the t that is the simulation's.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy import stats

from octoroach_model.arrays import FloatArray, IntArray
from octoroach_model.diagnosis.features import INDEX, OUTCOMES, RESOLUTION

ENERGY_FRACTIONS = (0.2, 0.4, 0.6, 0.8, 1.0)
PAIR_RUNS = 400           # model runs used for the energy score's spread term
FLOOR = 0.25              # smallest spread (in data spreads) a model is credited with
CAP = 8.0                 # a feature further off than this (in predictive spreads) counts as CAP
NUMERICAL_NOISE = 1e-6    # per-run score differences below this are rounding, not evidence
SCORING_RESAMPLES = 50    # resamples of the scored runs behind `t_scoring_se`


@dataclass(frozen=True)
class Scores:
    """Per held-out run scores of one model."""

    log: FloatArray                 # feature log score, nats (higher is better)
    energy_cm: FloatArray           # position energy score, cm (lower is better)
    sample: FloatArray | None = None    # the model's scored runs' features, in data spreads
    by_position: bool = False           # predicted at each run's place (module docstring)
    points_cm: FloatArray | None = None     # the scored runs' `position_points_cm`

    @property
    def runs(self) -> int:
        """Return how many scored runs these scores came from (0: none kept)."""
        return 0 if self.sample is None else len(self.sample)


def feature_scales(calibration_features: FloatArray) -> FloatArray:
    """
    Each feature's spread over the calibration runs (never below its resolution).

    Parameters
    ----------
    calibration_features : array, shape (n, F)
        Run features in SI units (`features.run_features`).

    Returns
    -------
    array, shape (F,)
        Spreads, in the features' units.

    """
    scales: FloatArray = np.maximum(np.std(calibration_features, axis=0, ddof=1), RESOLUTION)
    return scales


def feature_log_densities(sample: FloatArray, observed: FloatArray, by_position: bool = False
                          ) -> FloatArray:
    """
    Return the normal log density of each observed row's outcome columns under the sample.

    Each column at the sample's column mean and spread (the spread never below FLOOR, the
    distance never beyond CAP spreads); columns in data spreads.
    `by_position`: the mean and spread are those of the sample's least-squares line against
    the position column, taken at each observed row's position (module docstring).

    Parameters
    ----------
    sample : array, shape (m, F)
        Simulated runs' features, in data spreads.
    observed : array, shape (n, F)
        Held-out runs' features, in data spreads.
    by_position : bool
        Condition on the position column (module docstring).

    Returns
    -------
    array, shape (n, outcome columns)
        Log density of each observed run's outcomes (features.OUTCOMES), nats.

    """
    outcomes, observed_outcomes = sample[:, OUTCOMES], observed[:, OUTCOMES]
    if by_position:
        place = sample[:, INDEX['position']]
        design = np.column_stack([np.ones_like(place), place - place.mean()])
        coefficients, *_ = np.linalg.lstsq(design, outcomes, rcond=None)
        residual = outcomes - design @ coefficients
        spread = np.maximum(np.sqrt((residual ** 2).sum(axis=0) / max(len(place) - 2, 1)),
                            FLOOR)
        observed_place = observed[:, INDEX['position']] - place.mean()
        mean = coefficients[0] + observed_place[:, None] * coefficients[1]
    else:
        mean = outcomes.mean(axis=0)
        spread = np.maximum(outcomes.std(axis=0, ddof=1), FLOOR)
    z = np.clip((observed_outcomes - mean) / spread, -CAP, CAP)
    densities: FloatArray = stats.norm.logpdf(z) - np.log(spread)
    return densities


def feature_log_score(sample: FloatArray, observed: FloatArray, by_position: bool = False
                      ) -> FloatArray:
    """
    Return the summed normal log density of each observed row under the sample.

    Summed over the outcome columns (`feature_log_densities`, where the parameters are
    described): the score the held-out test compares.
    """
    log_score: FloatArray = feature_log_densities(sample, observed, by_position).sum(axis=1)
    return log_score


def energy_score(sample: FloatArray, observed: FloatArray) -> FloatArray:
    """
    Energy score of each observed row against the sample rows (lower is better).

    Parameters
    ----------
    sample : array, shape (m, P)
        Simulated runs' points, cm.
    observed : array, shape (n, P)
        Held-out runs' points, cm.

    Returns
    -------
    array, shape (n,)
        Energy score of each observed run, cm.

    """
    distances = np.sqrt(((sample[None, :, :] - observed[:, None, :]) ** 2).sum(axis=-1))
    to_observed = distances.mean(axis=1)
    pairs = sample[:PAIR_RUNS]
    half = len(pairs) // 2
    spread = np.sqrt(((pairs[:half] - pairs[half:2 * half]) ** 2).sum(axis=-1)).mean()
    energy: FloatArray = to_observed - 0.5 * spread
    return energy


def position_points_cm(positions: FloatArray, lengths: IntArray) -> FloatArray:
    """
    Return positions (cm) at fractions of each run's duration, relative to the run's start.

    Parameters
    ----------
    positions : array, shape (n, T, 2)
        x, y, m (NaN after a run's end).
    lengths : array of int, shape (n,)
        Samples of each run.

    Returns
    -------
    array, shape (n, 2 len(ENERGY_FRACTIONS))
        Points, cm.

    """
    rows = np.arange(positions.shape[0])
    last = np.maximum(lengths - 1, 0)
    picks = [np.rint(fraction * last).astype(int) for fraction in ENERGY_FRACTIONS]
    points = [positions[rows, pick] - positions[:, 0] for pick in picks]
    return np.concatenate(points, axis=1) * 100.0


def score_model(model_features: FloatArray, model_points_cm: FloatArray,
                observed_features: FloatArray, observed_points_cm: FloatArray,
                scales: FloatArray, by_position: bool = False) -> Scores:
    """
    Scores of the observed (held-out) runs under a model's simulated runs.

    Parameters
    ----------
    model_features, observed_features : arrays, shapes (m, F) and (n, F)
        Run features, SI units.
    model_points_cm, observed_points_cm : arrays, shapes (m, P) and (n, P)
        `position_points_cm`, cm.
    scales : array, shape (F,)
        `feature_scales`.
    by_position : bool
        As in `feature_log_score`.

    """
    sample = model_features / scales
    return Scores(feature_log_score(sample, observed_features / scales, by_position),
                  energy_score(model_points_cm, observed_points_cm), sample, by_position,
                  model_points_cm)


def pooled_scores(first: Scores, more: Scores, observed: FloatArray,
                  observed_points_cm: FloatArray) -> Scores:
    """
    Return the scores under both batches of one model's scored runs at once.

    `first` and `more` are the same model scored on runs of their own random numbers;
    `observed` the held-out runs' features in data spreads. A close call is scored again this
    way (diagnose.py): the first batch's runs are kept, not simulated again.
    """
    assert first.sample is not None and more.sample is not None
    assert first.points_cm is not None and more.points_cm is not None
    sample = np.concatenate([first.sample, more.sample])
    points = np.concatenate([first.points_cm, more.points_cm])
    return Scores(feature_log_score(sample, observed, first.by_position),
                  energy_score(points, observed_points_cm), sample, first.by_position, points)


@dataclass(frozen=True)
class PairedGain:
    """Per-run gain of one model over another on held-out runs, and its one-sided test."""

    mean: float
    standard_error: float
    p_value: float

    @classmethod
    def of(cls, improvement: FloatArray) -> PairedGain:
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


def t_scoring_se(candidate: Scores, current: Scores, observed: FloatArray,
                 rng: np.random.Generator) -> float | None:
    """
    Return the error of the paired t of `candidate` over `current` from their scored runs.

    Both models' scored runs are resampled together, run i of each with run i of the other
    (they drew the same random numbers), SCORING_RESAMPLES times; the held-out runs
    (`observed`, features in data spreads) stay. None where either has no scored runs kept,
    or where fewer than half of the resamples give a t (a gain of no spread).
    """
    if candidate.sample is None or current.sample is None:
        return None
    runs = min(len(candidate.sample), len(current.sample))
    picks = rng.integers(0, runs, (SCORING_RESAMPLES, runs))
    gains = (_resampled_log_scores(candidate, picks, observed)
             - _resampled_log_scores(current, picks, observed))
    if gains.shape[1] < 3:
        return None
    # PairedGain.of's t for every resample at once, where it gives one
    mean = gains.mean(axis=1)
    error = gains.std(axis=1, ddof=1) / math.sqrt(gains.shape[1])
    has_t = ((np.abs(gains).max(axis=1) >= NUMERICAL_NOISE)
             & (error > 1e-12 * (1.0 + np.abs(mean))))
    if 2 * np.count_nonzero(has_t) < SCORING_RESAMPLES:
        return None
    return float(np.std(mean[has_t] / error[has_t], ddof=1))


def _resampled_log_scores(scores: Scores, picks: IntArray, observed: FloatArray) -> FloatArray:
    """
    Return the observed rows' log scores under each resample of the scored runs, (B, n).

    Each row of `picks` is one resample (indices into the scored runs). A model predicted at
    each run's place refits its lines per resample; the others' means and spreads come from
    the resamples' counts at once (bit for bit the same as the picked rows' up to rounding).
    """
    assert scores.sample is not None
    sample = scores.sample[:len(picks[0])]
    if scores.by_position:
        return np.array([feature_log_score(sample[pick], observed, True) for pick in picks])
    outcomes = sample[:, OUTCOMES]
    centre = outcomes.mean(axis=0)
    shifted = outcomes - centre
    runs = len(shifted)
    counts = np.stack([np.bincount(pick, minlength=runs) for pick in picks]).astype(float)
    mean = counts @ shifted / runs
    variance = (counts @ (shifted * shifted) - runs * mean * mean) / max(runs - 1, 1)
    spread = np.maximum(np.sqrt(np.maximum(variance, 0.0)), FLOOR)        # (B, F)
    z = np.clip((observed[None, :, OUTCOMES] - (mean + centre)[:, None, :])
                / spread[:, None, :], -CAP, CAP)
    # the normal log density, as stats.norm.logpdf writes it (without its per-call cost)
    log_scores: FloatArray = (-0.5 * z * z - _HALF_LOG_2PI
                              - np.log(spread)[:, None, :]).sum(axis=2)
    return log_scores


_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)
