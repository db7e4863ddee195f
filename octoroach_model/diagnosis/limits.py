"""
Detection limits: the smallest size of each cause that the diagnosis names with 80 % power.

A cause is named when two things hold (diagnose.py): its size's lower confidence bound on the
calibration half clears its floor, and its model beats the one without it on the held-out
half. The two halves are independent, so the probability of naming a cause of size s is the
product of the two probabilities:

- **size bound** (decide.py): the bound is normal around the size with the data's own
  standard error (bootstrap over the measured runs, grown with the size as a variance's error
  grows with its level); P1(s) = Phi((s_u - floor_u - z1 se) / se), u the scale the bound is
  taken on.
- **held-out test**: runs simulated from the model with the cause at size s (as many as the
  held-out half, 1000 for precision) are scored under the model with and without it; the mean
  per-run gain over its spread, times sqrt(held-out runs), is the expected t statistic T(s),
  and P2(s) = Phi(T(s) - z2). T is computed at two sizes and interpolated in log-log.

The limit solves P1(s) P2(s) = POWER, at the levels of the first step (all six causes in the
race: the strictest). Whether limits computed this way hold is measured by
studies/limits.yaml (README: "What the diagnosis can find").
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy import stats

from octoroach_model.diagnosis.causes import BY_NAME, Cause
from octoroach_model.diagnosis.decide import POWER, relative_error
from octoroach_model.diagnosis.features import run_features
from octoroach_model.diagnosis.modelfit import FittedModel, Simulator, SizeEstimate
from octoroach_model.diagnosis.scoring import feature_log_score

PSEUDO_RUNS = 1000
PSEUDO_PURPOSE = 51
MODEL_PURPOSE = 52

METHOD = ('smallest size named with 80 % power: P(size bound clears the floor) x P(held-out '
          "test significant), the first from the measured runs' own standard error, the "
          'second from runs simulated with the cause (docs/diagnosis.md, "Detection limits")')


@dataclass(frozen=True)
class Limit:
    """A cause's detection limit and the two powers it balances (at the limit)."""

    cause: str
    size: float | None
    size_bound_power: float
    test_power: float


def bound_power(estimate: SizeEstimate, size: float, floor: float, z: float) -> float:
    """P(the lower bound of the size clears the floor) when the true size is `size`."""
    cause = BY_NAME[estimate.cause]
    if cause.kind == 'moments':
        if not (estimate.slope > 0 and math.isfinite(estimate.se_u)):
            return 0.0
        relative = relative_error(estimate, floor)
        u = size ** 2
        level = max(estimate.intercept + estimate.slope * u, 0.0)
        se = math.hypot(relative * level, estimate.intercept_se) / estimate.slope
        if se <= 0:
            return 1.0 if u > floor ** 2 else 0.0
        return float(stats.norm.cdf((u - floor ** 2 - z * se) / se))
    se = estimate.se
    if not (math.isfinite(se) and se > 0):
        return 1.0 if size > floor else 0.0
    return float(stats.norm.cdf((size - floor - z * se) / se))


def _features(simulator: Simulator, model: FittedModel, runs: int, purpose: int,
              scales: np.ndarray) -> np.ndarray:
    paths = simulator.paths(model, runs, purpose)
    data = simulator.data
    return run_features(paths, data.stride_frequency, data.reference_heading) / scales


def expected_t(simulator: Simulator, without: FittedModel, without_features: np.ndarray,
               cause: Cause, size: float, scales: np.ndarray, held_out: int,
               score_runs: int) -> float:
    """
    Return the expected t statistic of the held-out test for a cause of `size`.

    See the module docstring;
    `without_features` are the scored runs of the model without the cause.
    """
    values = {cause.parameter: size}
    if cause.name == 'initial_pose_error':
        values['position_std_cm'] = float((without.effects.get(cause.name) or {}).get(
            'position_std_cm', 0.0))
    extended = without.with_effect(cause.name, values)
    pseudo = _features(simulator, extended, PSEUDO_RUNS, PSEUDO_PURPOSE, scales)
    gain = (feature_log_score(_features(simulator, extended, score_runs, MODEL_PURPOSE,
                                        scales), pseudo)
            - feature_log_score(without_features, pseudo))
    spread = float(np.std(gain, ddof=1))
    if spread <= 0:
        return math.inf if gain.mean() > 0 else 0.0
    return float(gain.mean() / spread * math.sqrt(held_out))


def detection_limit(simulator: Simulator, without: FittedModel, estimate: SizeEstimate,
                    floor: float, z_bound: float, z_test: float, scales: np.ndarray,
                    held_out: int, score_runs: int, start: float | None) -> Limit:
    """
    Return the size at which the cause is named with POWER (module docstring).

    `start` is the size
    bound's own 80 % limit (decide.py), where the search begins.
    """
    cause = BY_NAME[estimate.cause]
    first = max(start or 0.0, 2 * floor, 1e-9)
    sizes = [first, 3 * first]
    base = _features(simulator, without, score_runs, MODEL_PURPOSE, scales)
    t_values = [max(expected_t(simulator, without, base, cause, size, scales, held_out,
                               score_runs), 1e-9) for size in sizes]
    slope = (math.log(t_values[1]) - math.log(t_values[0])) / math.log(sizes[1] / sizes[0])
    slope = max(slope, 0.1)

    def t_at(size: float) -> float:
        return t_values[0] * (size / sizes[0]) ** slope

    def power(size: float) -> float:
        return bound_power(estimate, size, floor, z_bound) * float(
            stats.norm.cdf(t_at(size) - z_test))

    low, high = max(floor, 1e-9), first
    for _ in range(60):
        if power(high) >= POWER:
            break
        high *= 1.5
    else:
        return Limit(cause.name, None, 0.0, 0.0)
    for _ in range(60):
        middle = math.sqrt(low * high) if low > 0 else 0.5 * high
        low, high = (middle, high) if power(middle) < POWER else (low, middle)
    return Limit(cause.name, high, bound_power(estimate, high, floor, z_bound),
                 float(stats.norm.cdf(t_at(high) - z_test)))
