"""Set-level statistics of runs, the discrepancies of data against a model, and scores.

A statistic summarises a whole set of runs (a spread, a mean); its uncertainty comes from a
bootstrap over runs. Scores are per held-out run, so two models can be compared run by run.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy import stats

from octoroach_model.diagnosis.features import INDEX, RESOLUTION
from octoroach_model.paths import Paths


def _std(column: str, scale: float = 1.0) -> Callable:
    return lambda f, p: float(np.std(f[:, INDEX[column]], ddof=1) * scale)


def _mean(column: str, scale: float = 1.0) -> Callable:
    return lambda f, p: float(np.mean(f[:, INDEX[column]]) * scale)


def start_position_spread_cm(f, p) -> float:
    return float(np.sqrt(0.5 * (f[:, 1].var(ddof=1) + f[:, 2].var(ddof=1))) * 100)


def jitter_rms_cm(f, p) -> float:
    return float(np.sqrt(np.exp(f[:, INDEX['log_jitter']]).mean()) * 100)


def lateral_spread(paths: Paths, fraction: float, reference_heading: float) -> float:
    """Std (m) of the displacement across the reference heading at a fraction of the run."""
    index = int(round(fraction * (len(paths.t) - 1)))
    step = paths.poses[:, index, :2] - paths.poses[:, 0, :2]
    right = np.array([math.sin(reference_heading), -math.cos(reference_heading)])
    return float(np.std(step @ right, ddof=1))


def spread_growth_exponent(f, p) -> float:
    """Slope of log(lateral spread) against log(t) from a quarter of the run to its end:
    about 1 for a fixed heading error, 1.5 for a random-walk heading, 2 for steady turning."""
    paths, heading, _ = p
    early = lateral_spread(paths, 0.25, heading)
    late = lateral_spread(paths, 1.0, heading)
    return float(math.log(max(late, 1e-12) / max(early, 1e-12)) / math.log(4.0))


def heading_increment_autocorrelation(f, p) -> float:
    """Mean lag-1 autocorrelation of per-half-cycle heading changes within runs: near zero (or
    negative) for fresh angles at each stance, positive for a persistent bias."""
    paths, _, frequency = p
    heading = paths.poses[..., 2]
    dt = float(paths.t[1] - paths.t[0])
    window = max(1, int(round(1.0 / (frequency * dt))))
    increments = heading[:, window::window] - heading[:, :-window:window][
        :, :heading[:, window::window].shape[1]]
    if increments.shape[1] < 3:
        return 0.0
    centred = increments - increments.mean(axis=1, keepdims=True)
    numerator = (centred[:, 1:] * centred[:, :-1]).sum(axis=1)
    denominator = (centred ** 2).sum(axis=1)
    return float(np.mean(numerator / np.maximum(denominator, 1e-18)))


# name -> (function of (features, (paths, reference heading, stride frequency)), unit)
STATISTICS: dict[str, tuple[Callable, str]] = {
    'start heading spread': (_std('start_heading', 180 / math.pi), 'deg'),
    'start position spread': (start_position_spread_cm, 'cm'),
    'position jitter (rms second difference)': (jitter_rms_cm, 'cm'),
    'heading to travel angle': (_mean('slip_angle', 180 / math.pi), 'deg'),
    'mean stride frequency': (_mean('stride_frequency'), 'Hz'),
    'stride frequency spread across runs': (_std('stride_frequency'), 'Hz'),
    'log speed ratio, 2nd half / 1st half': (_mean('progress_ratio'), ''),
    'heading rate spread across runs': (_std('heading_rate', 180 / math.pi), 'deg/s'),
    'per-cycle heading change spread within runs':
        (lambda f, p: float(np.sqrt(f[:, INDEX['increment_var']].mean()) * 180 / math.pi),
         'deg'),
    'lateral spread at the end': (_std('end_lateral', 100), 'cm'),
    'progress spread at the end': (_std('end_progress', 100), 'cm'),
    'lateral spread growth exponent': (spread_growth_exponent, ''),
    'lag-1 autocorrelation of heading changes': (heading_increment_autocorrelation, ''),
}


def statistics_with_errors(features: np.ndarray, paths: Paths, reference_heading: float,
                           stride_frequency: float, rng: np.random.Generator,
                           n_boot: int = 100) -> dict[str, tuple[float, float]]:
    """{name: (value, bootstrap standard error)} for every statistic in STATISTICS."""
    context = (paths, reference_heading, stride_frequency)
    values = {name: fn(features, context) for name, (fn, _) in STATISTICS.items()}
    boot = {name: [] for name in STATISTICS}
    n = features.shape[0]
    for _ in range(n_boot):
        pick = rng.integers(0, n, n)
        sub = (paths.subset(pick), reference_heading, stride_frequency)
        for name, (fn, _) in STATISTICS.items():
            boot[name].append(fn(features[pick], sub))
    return {name: (values[name], float(np.std(boot[name], ddof=1))) for name in STATISTICS}


def gaussian_log_score(model_features: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Log density of each observed feature vector under a Gaussian fitted to the model's
    simulated features (a synthetic likelihood; the log score is proper for it)."""
    mean = model_features.mean(axis=0)
    cov = np.cov(model_features, rowvar=False) + np.diag(RESOLUTION ** 2)
    scale = np.sqrt(np.diag(cov))
    standardised_cov = cov / np.outer(scale, scale)
    z = (observed - mean) / scale
    logpdf = stats.multivariate_normal(np.zeros(len(mean)), standardised_cov,
                                       allow_singular=True).logpdf(z)
    return np.atleast_1d(logpdf) - np.log(scale).sum()


def energy_scores(model_points: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Energy score of each observed vector against the model sample (lower is better)."""
    to_obs = np.linalg.norm(model_points[None, :, :] - observed[:, None, :], axis=-1).mean(1)
    half = len(model_points) // 2
    spread = np.linalg.norm(model_points[:half] - model_points[half:2 * half], axis=-1).mean()
    return to_obs - 0.5 * spread


def paired_improvement(candidate: np.ndarray, baseline: np.ndarray) -> tuple[float, float]:
    """Mean per-run gain (candidate - baseline) and its one-sided t-test p-value."""
    difference = candidate - baseline
    gain = float(difference.mean())
    if len(difference) < 3 or np.ptp(difference) <= 1e-12 * (1 + abs(gain)):
        return gain, 0.0 if gain > 1e-9 else 1.0
    result = stats.ttest_1samp(difference, 0.0, alternative='greater')
    return gain, float(result.pvalue)
