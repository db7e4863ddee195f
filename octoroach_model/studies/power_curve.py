"""
The power curve of `plan --method simulate`: power(n) = expit(a + b ln n) from diagnosed rows.

The curve is fitted by maximum likelihood with every diagnosed data set a trial, and
parameterised by the answer itself, c = ln of the run count at the target power; the 95 %
interval of c is where the profile log likelihood stays within chi-squared(1) of its best.
A replicate's data sets share their seed (common random numbers: for most causes its smaller
data sets are the first runs of its larger ones), so its outcomes are not independent: a
likelihood that takes them as such is right about the curve but too sure of it. The
likelihood-ratio statistic is therefore scaled by k = (naive variance of c) / (variance of c
robust to replicates, the sandwich with the replicates' summed scores, small-sample factor
G / (G - 1) for G replicates), k in [1 / (counts per replicate), 1]: nested outcomes count
about as one trial per replicate, independent ones as every trial.

Why not what plan did before, a percentile bootstrap over replicates: on a known curve with
six replicates per count it held the true run count in 60 % of simulated plans, missing
almost always below the truth (a low answer comes with a steep fitted curve and so a narrow
interval). Why not a threshold model (each replicate named from some run count on): it is
biased low where outcomes at different counts are not nested.
`benchmarks/bench_plan_coverage.py` measures all three.
"""
from __future__ import annotations

from collections.abc import Sequence
import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from octoroach_model.errors import ParameterError
from octoroach_model.studies.rows import StudyRow

MAX_SLOPE = 20.0            # per unit of ln(runs): power 10 % -> 90 % over at least x1.25 runs
MIN_SLOPE = 0.02            # power 10 % -> 90 % over at most x1e95 runs: flat
RIDGE = 1e-3                # keeps the fit finite when every data set agrees
MARGIN = math.log(64.0)     # the answer is sought from the fewest runs / 64 to the most x 64
CROSSINGS = 1601            # grid of ln(runs at the target) the profile is taken on
GOLDEN_STEPS = 48          # the slope to 20 x 0.618^48 = 2e-9 at every crossing
LIKELIHOOD_RATIO_95 = float(stats.chi2.ppf(0.95, 1))
INTERVAL_METHOD = ('profile likelihood of the run count at the target, its ratio scaled for '
                   'outcomes that hang together by replicate (sandwich)')


class PowerFit(NamedTuple):
    """
    The fit power(n) = expit(a + b ln n) and the n where it reaches the target.

    `interval_95` is the replicate-robust profile-likelihood 95 % interval of that n (0 or
    inf where it reaches past the counts by more than a factor 64: the data do not bound it
    there).
    """

    intercept: float
    slope: float
    runs_at_target: float
    interval_95: tuple[float, float]
    counts: tuple[int, ...]


def fit_power_curve(rows: Sequence[StudyRow], cause: str, target: float) -> PowerFit:
    """Fit named / not named against ln(runs) over `rows` (status ok only), module docstring."""
    usable = [row for row in rows if row.ok]
    if not usable:
        raise ParameterError('no data set of the plan could be diagnosed; see the rows')
    x = np.log([row.runs for row in usable])
    named = np.array([1.0 if row.terms[cause].named else 0.0 for row in usable])
    replicate = np.unique([row.replicate for row in usable], return_inverse=True)[1]
    levels, level = np.unique(x, return_inverse=True)
    trials = np.bincount(level).astype(float)
    successes = np.bincount(level, weights=named)
    crossings = np.linspace(levels[0] - MARGIN, levels[-1] + MARGIN, CROSSINGS)
    centre = float(x.mean())
    profile, slopes = _profile(levels, trials, successes, crossings, centre, target)
    best = int(np.argmax(profile))
    if 0 < best < CROSSINGS - 1:    # the answer to a fraction of a run: finely around it
        step = crossings[1] - crossings[0]
        fine = np.linspace(crossings[best] - step, crossings[best] + step, 201)
        fine_profile, fine_slopes = _profile(levels, trials, successes, fine, centre, target)
        where = int(np.argmax(fine_profile))
        crossing, slope = float(fine[where]), float(fine_slopes[where])
        peak = float(fine_profile[where])
    else:
        crossing, slope, peak = float(crossings[best]), float(slopes[best]), float(profile[best])
    scale = replicate_scale(x, named, replicate, crossing, slope, target, len(levels))
    inside = np.flatnonzero(scale * 2.0 * (peak - profile) <= LIKELIHOOD_RATIO_95)
    low = 0.0 if inside[0] == 0 else math.exp(crossings[inside[0]])
    high = math.inf if inside[-1] == CROSSINGS - 1 else math.exp(crossings[inside[-1]])
    answer = math.inf if best == CROSSINGS - 1 else math.exp(crossing)
    counts = tuple(sorted({int(row.runs) for row in usable}))
    return PowerFit(_logit(target) - slope * crossing, slope, answer,
                    (min(low, answer), max(high, answer)), counts)


def replicate_scale(x: np.ndarray, named: np.ndarray, replicate: np.ndarray, crossing: float,
                    slope: float, target: float, counts: int) -> float:
    """
    Return k, the likelihood ratio's scale for outcomes that hang together by replicate.

    k = naive / robust variance of the crossing at the fit (module docstring), within
    [1 / counts, 1]; 1 / counts where the fit's information is degenerate.
    """
    from scipy.special import expit

    chance = expit(_logit(target) + slope * (x - crossing))
    gradient = np.stack([np.full_like(x, -slope), x - crossing], axis=1)   # d eta / d(c, b)
    information = (gradient.T * (chance * (1.0 - chance))) @ gradient
    scores = np.zeros((int(replicate.max()) + 1, 2))
    np.add.at(scores, replicate, (named - chance)[:, None] * gradient)
    groups = len(scores)
    meat = scores.T @ scores * (groups / (groups - 1) if groups > 1 else 1.0)
    try:
        inverse = np.linalg.inv(information)
    except np.linalg.LinAlgError:
        return 1.0 / counts
    naive, robust = inverse[0, 0], (inverse @ meat @ inverse)[0, 0]
    if not (np.isfinite(naive) and np.isfinite(robust)) or naive <= 0 or robust <= 0:
        return 1.0 / counts
    return float(min(1.0, max(1.0 / counts, naive / robust)))


def _profile(levels: np.ndarray, trials: np.ndarray, successes: np.ndarray,
             crossings: np.ndarray, centre: float, target: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the penalised log likelihood's profile over `crossings` and the slope at each.

    power(n) = expit(logit(target) + b (ln n - c)), the trials counted per run count. At a
    fixed c the log likelihood is concave in b (a logistic likelihood, concave in intercept
    and slope, along a line), so a golden-section search over b, all c at once, finds its
    best.
    """
    from scipy.special import log_expit

    logit = _logit(target)
    distance = levels[None, :] - crossings[:, None]
    tilt = crossings - centre

    def likelihood(b: np.ndarray) -> np.ndarray:
        eta = logit + b[:, None] * distance
        return ((successes * log_expit(eta) + (trials - successes) * log_expit(-eta)).sum(axis=1)
                - RIDGE * ((logit - b * tilt) ** 2 + b ** 2))

    low = np.full(len(crossings), MIN_SLOPE)
    high = np.full(len(crossings), MAX_SLOPE)
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    left, right = high - ratio * (high - low), low + ratio * (high - low)
    left_value, right_value = likelihood(left), likelihood(right)
    for _ in range(GOLDEN_STEPS):
        rising = left_value < right_value          # the best lies right of `left`
        low = np.where(rising, left, low)
        high = np.where(rising, high, right)
        new_left = np.where(rising, right, high - ratio * (high - low))
        new_right = np.where(rising, low + ratio * (high - low), left)
        moved_value = likelihood(np.where(rising, new_right, new_left))
        left_value, right_value = (np.where(rising, right_value, moved_value),
                                   np.where(rising, moved_value, left_value))
        left, right = new_left, new_right
    slopes = (low + high) / 2.0
    return likelihood(slopes), slopes


def _logit(power: float) -> float:
    return math.log(power / (1.0 - power))
