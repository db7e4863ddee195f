"""
When a size counts as found, its interval, and the smallest size this data could find.

A cause's size is *found* when the one-sided lower confidence bound of its main parameter,
at level 1 - decision_alpha / m (m candidates still in the race, Bonferroni), lies above the
cause's floor (causes.py): we are that sure that the size matters. Moments causes are read
as u = size^2 on a line, so the bound is taken on u (normal there) and square-rooted; path
causes (and the trend and mixture kinds) are bounded on |size - null| (null: the value that
means no effect, 1 for change_point's speed factor, else 0); their limits are distances from
it.

The detection limit is the smallest size at which that bound clears the floor with 80 %
power on runs like the data at hand: the standard error is the data's own (bootstrap over
the measured runs, so a misfit that makes the data noisier than the model widens it), plus,
for the level the cause adds, the relative error simulated runs with the cause show (for a
variance the two errors add: exact for normal runs, conservative for heavier tails), plus
the simulation's (intercept and slope: `modelfit.moments_se_u`). The slope's relative error
is the one at the cause's reference size: the slope of an estimate near zero is taken near
zero, where its relative error is large (a cross term of the cause with the runs' own
spread, 39 % on a null data set) but counts only in proportion to u; held over the sizes a
limit is sought at, it kept the bound from ever clearing the floor (no limit for
persistent_turning on 2 of 8 null data sets).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from scipy import stats

from octoroach_model.diagnosis.causes import BY_NAME, EstimateKind
from octoroach_model.diagnosis.modelfit import moments_se_u, SizeEstimate

POWER = 0.8
INTERVAL_LEVEL = 0.95
# a moments statistic below this share of the level its cause adds at the floor is a zero
NUMERICAL_ZERO = 1e-9
# A held-out t within this many of its scoring errors (t_scoring_se) of the critical value
# could have fallen on the other side with other simulated runs: a close call, scored again
# on more runs and decided on those (diagnose._settled), said in summary.md and counted by
# the studies (close_calls).
CLOSE_CALL_SE = 2.0
# A term screened before its refit (diagnose.screened_first) is refit and scored only where
# its quick estimate's bound, at the decision's z less this many standard errors, could
# reach its floor (diagnose.screen); its limit counts that step too (limits.bound_power).
SCREEN_ALLOWANCE = 2.0


def out_of_reach(estimate: SizeEstimate, floor: float, z: float) -> bool:
    """Whether the size's lower bound at `z` standard errors stays below `floor`."""
    cause = BY_NAME[estimate.cause]
    if cause.kind == EstimateKind.MOMENTS:
        return bool(not math.isfinite(estimate.se_u)
                    or estimate.u - z * estimate.se_u <= floor ** 2)
    return bool(not math.isfinite(estimate.se)
                or abs(estimate.size - cause.null) - z * estimate.se <= floor)


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
    if cause.kind == EstimateKind.MOMENTS:
        u, se_u = estimate.u, estimate.se_u
        interval = (_root(u - z_interval * se_u), _root(u + z_interval * se_u))
        lower = _root(u - z_decision * se_u)
        limit = _moments_limit(estimate, floor, z_decision)
    else:
        size, se = estimate.size, estimate.se
        interval = (size - z_interval * se, size + z_interval * se)
        lower = max(abs(size - cause.null) - z_decision * se, 0.0)
        limit = floor + (z_decision + stats.norm.isf(1 - POWER)) * se \
            if math.isfinite(se) else None
    return SizeVerdict(estimate.cause, estimate.size, estimate.se, interval, lower, floor,
                       bool(lower > floor), limit)


def _root(u: float) -> float:
    return math.sqrt(u) if u > 0 else 0.0


def data_se_if_true(estimate: SizeEstimate, u: float, floor: float) -> float:
    """
    Return the standard error the data's statistic would have if the true size^2 were `u`.

    The data's own error at its level now stays (a misfit that makes the data noisier than
    the model widens it); the level the cause adds beyond the data's own carries the relative
    error simulated runs with the cause show (on a null the data's relative error is that of a
    statistic with none of the cause in it: carried to the whole level, it doubled
    measurement_noise's limit above its floor); never below that relative error of the whole
    level. Below the data's level the error shrinks in proportion. A statistic that is
    numerically zero (a start heading spread of exactly 0, as runs simulated without one
    have: 1e-32 rad^2) has only rounding error, so the simulated runs' relative error is used
    alone.
    """
    level = max(estimate.intercept + estimate.slope * u, 0.0)
    simulated = estimate.relative_se * level
    level_now = max(estimate.data_statistic, estimate.intercept)
    if level_now <= NUMERICAL_ZERO * estimate.slope * floor ** 2:
        return simulated
    u_now = (level_now - estimate.intercept) / estimate.slope
    own = estimate.data_se * min(level / level_now, 1.0)
    added = estimate.relative_se * estimate.slope * max(u - u_now, 0.0)
    return max(own + added, simulated)


def se_u_if_true(estimate: SizeEstimate, u: float, floor: float) -> float:
    """
    Return the standard error u's estimate would have if the true size^2 were `u`.

    The data's part is `data_se_if_true`; the slope's error is the one at the reference size
    (module docstring). The size bound's limit here and its power in limits.py both use it.
    """
    return moments_se_u(estimate, u, data_se_if_true(estimate, u, floor),
                        estimate.reference_slope_relative_se)


def _moments_limit(estimate: SizeEstimate, floor: float, z_decision: float) -> float | None:
    """Smallest size s with P(u_hat - z se_u(s) > floor^2) = POWER, u_hat ~ N(s^2, se_u(s))."""
    if not (estimate.slope > 0 and math.isfinite(estimate.se_u)):
        return None
    z_power = float(stats.norm.isf(1 - POWER))

    def margin(u: float) -> float:
        return u - floor ** 2 - (z_decision + z_power) * se_u_if_true(estimate, u, floor)

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


def close_call(t: float, critical: float, scoring_se: float) -> bool:
    """Whether `t` ended within CLOSE_CALL_SE of its `scoring_se` of the `critical` t."""
    return abs(t - critical) <= CLOSE_CALL_SE * scoring_se


def decision_z(alpha: float, candidates: int) -> float:
    """One-sided normal quantile at level alpha / candidates."""
    return float(stats.norm.isf(alpha / max(candidates, 1)))
