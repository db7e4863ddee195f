"""
When a size counts as found, its interval, and the smallest size this data could find.

A cause's size is *found* when the one-sided lower confidence bound of its main parameter,
at level 1 - decision_alpha / m (m candidates still in the race, Bonferroni), lies above the
cause's floor (causes.py): we are that sure that the size matters. Moments causes are read
as u = size^2 on a line, so the bound is taken on u (normal there) and square-rooted; path
causes are bounded on |size|.

The detection limit is the smallest size at which that bound clears the floor with 80 %
power on runs like the data at hand: the standard error is the data's own (bootstrap over
the measured runs, so a misfit that makes the data noisier than the model widens it), grown
with the size as a variance statistic's error grows with its level (never below the relative
error simulated runs with the cause show), plus the simulation's (intercept and slope:
`modelfit.moments_se_u`). The slope's relative error is the one at the cause's reference
size: the slope of an estimate near zero is taken near zero, where its relative error is
large (a cross term of the cause with the runs' own spread, 39 % on a null data set) but
counts only in proportion to u; held over the sizes a limit is sought at, it kept the bound
from ever clearing the floor (no limit for persistent_turning on 2 of 8 null data sets).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from scipy import stats

from octoroach_model.diagnosis.causes import BY_NAME
from octoroach_model.diagnosis.modelfit import moments_se_u, SizeEstimate

POWER = 0.8
INTERVAL_LEVEL = 0.95
# a moments statistic below this share of the level its cause adds at the floor is a zero
NUMERICAL_ZERO = 1e-9


@dataclass(frozen=True)
class SizeVerdict:
    """What a size estimate supports: interval, lower bound, floor and detection limit."""

    cause: str
    estimate: float
    standard_error: float
    interval: tuple[float, float]      # INTERVAL_LEVEL, two-sided
    lower_bound: float                 # one-sided, at the decision's level (of |size|)
    floor: float
    clears_floor: bool
    limit: float | None                # smallest size found with POWER (None: unbounded)


def judge(estimate: SizeEstimate, floor: float, z_decision: float) -> SizeVerdict:
    """Judge one size estimate (module docstring)."""
    cause = BY_NAME[estimate.cause]
    z_interval = float(stats.norm.isf((1 - INTERVAL_LEVEL) / 2))
    if cause.kind == 'moments':
        u, se_u = estimate.u, estimate.se_u
        interval = (_root(u - z_interval * se_u), _root(u + z_interval * se_u))
        lower = _root(u - z_decision * se_u)
        limit = _moments_limit(estimate, floor, z_decision)
    else:
        size, se = estimate.size, estimate.se
        interval = (size - z_interval * se, size + z_interval * se)
        lower = max(abs(size) - z_decision * se, 0.0)
        limit = floor + (z_decision + stats.norm.isf(1 - POWER)) * se \
            if math.isfinite(se) else None
    return SizeVerdict(estimate.cause, estimate.size, estimate.se, interval, lower, floor,
                       bool(lower > floor), limit)


def _root(u: float) -> float:
    return math.sqrt(u) if u > 0 else 0.0


def relative_error(estimate: SizeEstimate, floor: float) -> float:
    """
    Return a moments statistic's relative error, by which its error grows with its level.

    It is the data's own (bootstrap error over level), never below what simulated runs with
    the cause show. A statistic that is numerically zero (a start heading spread of exactly 0,
    as runs simulated without one have: 1e-32 rad^2) has no relative error of its own, only
    the ratio of two rounding errors, so the simulated runs' figure is used alone.
    """
    level_now = max(estimate.data_statistic, estimate.intercept)
    if level_now <= NUMERICAL_ZERO * estimate.slope * floor ** 2:
        return estimate.relative_se
    return max(estimate.data_se / level_now, estimate.relative_se)


def se_u_if_true(estimate: SizeEstimate, u: float, relative: float) -> float:
    """
    Return the standard error u's estimate would have if the true size^2 were `u`.

    The data's error grows with the statistic's level (`relative`, from `relative_error`);
    the slope's error is the one at the reference size (module docstring). The size bound's
    limit here and its power in limits.py both use it.
    """
    level = max(estimate.intercept + estimate.slope * u, 0.0)
    return moments_se_u(estimate, u, relative * level, estimate.reference_slope_relative_se)


def _moments_limit(estimate: SizeEstimate, floor: float, z_decision: float) -> float | None:
    """Smallest size s with P(u_hat - z se_u(s) > floor^2) = POWER, u_hat ~ N(s^2, se_u(s))."""
    if not (estimate.slope > 0 and math.isfinite(estimate.se_u)):
        return None
    z_power = float(stats.norm.isf(1 - POWER))
    relative = relative_error(estimate, floor)

    def margin(u: float) -> float:
        return u - floor ** 2 - (z_decision + z_power) * se_u_if_true(estimate, u, relative)

    low, high = floor ** 2, max(floor ** 2, estimate.u, estimate.se_u, 1e-300)
    for _ in range(200):
        if margin(high) > 0:
            break
        high *= 2
    else:
        return None
    for _ in range(100):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if margin(middle) <= 0 else (low, middle)
    return math.sqrt(high)


def decision_z(alpha: float, candidates: int) -> float:
    """One-sided normal quantile at level alpha / candidates."""
    return float(stats.norm.isf(alpha / max(candidates, 1)))
