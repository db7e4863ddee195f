"""
Detection limits: the smallest size of each cause that the diagnosis names with 80 % power.

A cause is named when two things hold (diagnose.py): its size's lower confidence bound on the
calibration half clears its floor, and its model beats the one without it on the held-out
half. The two halves are independent, so the probability of naming a cause of size s is the
product of the two probabilities:

- **size bound** (decide.py): the bound is normal around the size with the data's own
  standard error (bootstrap over the measured runs) plus, for the level the cause adds, the
  error simulated runs with the cause show (`decide.data_se_if_true`);
  P1(s) = Phi((s_u - floor_u - z1 se) / se), u the scale the bound is taken on.
- **held-out test**: runs simulated from the model with the cause at size s (as many as the
  held-out half, 1000 for precision) are scored under the model with and without it; the mean
  per-run gain over its spread, times sqrt(held-out runs), is the expected t statistic T(s),
  and P2(s) = Phi(T(s) - z2). T is computed at two sizes and interpolated in log-log;
  where the test decides the limit, T is computed again at the limit found and the limit
  solved anew through the points so far (at most REFINEMENTS times): T of a variance effect
  bends in log-log (it grows like s^4 at small sizes and slower above), so a chord between
  two sizes underestimates it in between, which made the limits of persistent_turning lean
  conservative (studies/limits.yaml).

A **path family** (yaw_rate_ramp, change_point) is screened on a quick estimate before the
joint fit with the geometry sizes it (diagnose.screen), with an error about twice the fit's:
P1 is the screen's bound (at z - SCREEN_ALLOWANCE, on the quick estimate's error) times the
refit's (`bound_power` with a screen); the quick error at the full z alone, as before, made
the ramp's size bound seem to decide its limit where the test did. The race scores its
extended model at the size refit on the calibration half, so P2 is averaged over that
size's error (`size_averaged_t`); and where a geometry fitted without the term mimics its
mean (yaw_rate_ramp's mean turn, `Cause.geometry_mimics`), the model without it is refit to
the runs with it (`geometry_absorbed`), as the race's baseline is. change_point's limit is
stated for a change at half the runs (causes.change_point_limit_s), its refit made there,
and its
screen simulated (`screen_power`: its step's error depends on how clearly runs show the
change's time, which a null data set says nothing of).

A term that slows or speeds the gait clock (speed_decay, change_point) is weighed the same
way: the runs stride as the robot with the term would, and the model without it, refit to
them, takes their mean rate in its stride frequency (its geometry mimics the term's mean).
Entered instead at the strides per run of the model without it (`same_strides`), a clock the
robot does not have, a change at half the runs showed half as much again in the test (t
5.99 against 4.02 at its limit on Table II's robot; `benchmarks/bench_path_limits.py --term
change_point`).

A term with a **look-alike** the race may add in its place (`Cause.look_alike`: a speed
decay over the run takes up much of a change at its middle) is named only if it gains more
than that look-alike on the held-out runs: the race adds, of the terms that qualify, the one
of the largest gain, and the term refit beside its look-alike seldom clears its floor
after. The look-alike is fitted to the runs simulated with the term and P(the term's per-run
gain over it is positive in mean) joins the simulated screen's share in P1
(`look_alike_power`).

A heading term (heading_random_walk, periodic_heading) is weighed at the spread scale the
race would fit with it, not only at the true one: with the term in it, a model's spread is
read off the stride length's variance (modelfit.spread_statistic), a noisier statistic matched
with few simulated runs, and T is steep in that scale. P2 is averaged over the scale's error
(`spread_averaged_t`); at the true scale alone, these limits were named in 2 of 4 data sets
each at 1x in studies/open_world.yaml.

One thing the runs with the cause must show before the race weighs it is simulated as well:
**two groups** (run_mixture). A mixture enters the race only where two groups of runs fit the
heading rates better than one normal of free spread, by MIXTURE_EVIDENCE_NATS on the
calibration half; the probability P3(s) of that evidence is taken from subsets of the
simulated runs as large as the calibration half. (Without it the mixture's limit was its
spread's, and no mixture at that limit was named: 0 of 8.)

The limit solves P1(s) P2(s) P3(s) = POWER (P3 = 1 but for run_mixture), at the levels of the
first step (every candidate in the race: the strictest). Whether limits computed this way hold
is measured by studies/limits.yaml and studies/open_world.yaml (docs/measured.md).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from octoroach_model.arrays import FloatArray
from octoroach_model.diagnosis.causes import BY_NAME, Cause, EstimateKind
from octoroach_model.diagnosis.decide import (
    out_of_reach, POWER, SCREEN_ALLOWANCE, se_u_if_true)
from octoroach_model.diagnosis.features import INDEX
from octoroach_model.diagnosis.modelfit import (
    at_size, CHANGE_POINT_BOOTSTRAP, fit_geometry, fit_spread, FitSettings, FittedModel,
    geometry_starts, largest_size, MIXTURE_EVIDENCE_NATS, path_terms, RunData, same_strides,
    Simulator, SizeEstimate, speed_ratio, spread_error, spread_statistic, striding_at,
    two_groups, two_groups_evidence)
from octoroach_model.diagnosis.scoring import feature_log_score
from octoroach_model.fitting.gait import cycle_distances
from octoroach_model.model.effects import mean_gait_rate

PSEUDO_RUNS = 1000
REFINEMENTS = 2            # at most this many extra sizes at which T is computed
FURTHER_UP = 2             # sizes 9 and 27 times the first, where none reached POWER below
TEST_DECIDES = 0.999       # below this test power at the limit, the test decides the limit
CLOSE = 0.02               # a limit within 2 % (in size) of a computed size needs no more
T_CAP = 1e6                # an expected t beyond this is certain detection (a spread of 0)
PSEUDO_PURPOSE = 51
MODEL_PURPOSE = 52
EVIDENCE_SUBSETS = 40      # calibration halves drawn from the simulated runs for P3
SCREEN_SUBSETS = 20        # ... for a simulated screen (`screen_power`)

METHOD = ('smallest size named with 80 % power: P(size bound clears the floor) x P(held-out '
          'test significant) (x P(two groups seen), for run_mixture), the first from the '
          "measured runs' own standard error, the others from runs simulated with the cause "
          '(docs/diagnosis.md, "Detection limits")')


@dataclass(frozen=True)
class Limit:
    """A cause's detection limit and the powers it balances (at the limit)."""

    cause: str
    size: float | None
    size_bound_power: float                  # P1, `screen_power` in it too
    test_power: float
    two_groups_power: float | None = None    # run_mixture only: P3 (module docstring)
    # a simulated screen's part of P1 (Cause), with P(added before its look-alike)
    screen_power: float | None = None

    @property
    def simulated_power(self) -> float:
        """Return the product of the parts of the limit that runs simulated with it give."""
        parts = (self.test_power, self.two_groups_power, self.screen_power)
        return math.prod(1.0 if part is None else part for part in parts)


class TestPoint(NamedTuple):
    """What runs simulated with a cause of one size show: the test's expected t, and P3."""

    t: float
    # P(the runs show it as what it is): P3 for a mixture, P(screen passed) for a simulated
    # screen (`screen_power`), times P(added before its look-alike) (`look_alike_power`),
    # else 1
    identified: float = 1.0


def bound_power(estimate: SizeEstimate, size: float, floor: float, z: float,
                screen: SizeEstimate | None = None) -> float:
    """
    P(the lower bound of the size clears the floor) when the true size is `size`.

    With `screen`, the quick estimate a path family is screened on before its refit sizes
    it (diagnose.screen): the probability that it passes the screen's bound (at z -
    SCREEN_ALLOWANCE) times that of the refit's bound. Both rise with the same data, so the
    product is below the chance of both (conservative); taken at the full z on the quick
    estimate alone, as before, the size bound seemed to decide yaw_rate_ramp's limit (P 0.80)
    where its refit's bound, half as wide, cleared by far and the held-out test decided.
    """
    if screen is not None:
        return bound_power(estimate, size, floor, z) * bound_power(
            screen, size, floor, max(z - SCREEN_ALLOWANCE, 0.0))
    cause = BY_NAME[estimate.cause]
    if cause.kind == EstimateKind.MOMENTS:
        if not (estimate.slope > 0 and math.isfinite(estimate.se_u)):
            return 0.0
        u = size ** 2
        se = se_u_if_true(estimate, u, floor)
        if se <= 0:
            return 1.0 if u > floor ** 2 else 0.0
        return float(stats.norm.cdf((u - floor ** 2 - z * se) / se))
    se = estimate.se
    if se == 0:
        return 1.0 if size > floor else 0.0
    if not (math.isfinite(se) and se > 0):
        return 0.0          # no error to bound the size with: never clears (out_of_reach)
    return float(stats.norm.cdf((size - floor - z * se) / se))


def _features(simulator: Simulator, model: FittedModel, runs: int, purpose: int,
              scales: FloatArray) -> FloatArray:
    return simulator.features(model, runs, purpose) / scales


def limit_base(simulator: Simulator, without: FittedModel, scales: FloatArray,
               score_runs: int) -> FloatArray:
    """Return the scored runs of the model without the cause: features in data spreads."""
    return _features(simulator, without, score_runs, MODEL_PURPOSE, scales)


def expected_t(simulator: Simulator, without: FittedModel, without_features: FloatArray,
               cause: Cause, size: float, scales: FloatArray, held_out: int,
               score_runs: int, fitted_values: Mapping[str, float] | None = None,
               fit: FitSettings | None = None, z_test: float | None = None,
               size_se: float | None = None,
               screen_floor_z: tuple[float, float] | None = None) -> TestPoint:
    """
    Return the expected t statistic of the held-out test for a cause of `size`, and P3.

    See the module docstring; `without_features` are the scored runs of the model without
    the cause; `fitted_values` the cause's other parameters as fitted (modelfit.at_size).
    With `z_test`, a term that moves the spread's statistic (a heading term) gets the test's
    power averaged over the error of the spread scale fitted with it (`spread_averaged_t`),
    and with `size_se` too, a path family over the error of its size (`size_averaged_t`).
    With `screen_floor_z` (floor, z), a term whose screen is simulated (`Cause.
    screen_simulated`) gets P(screen passed) in P3's place (`screen_power`).
    """
    pair = simulated_pair(simulator, without, without_features, cause, size, scales,
                          score_runs, fitted_values, fit)
    gains = pair.gains(simulator, scales, score_runs)
    identified = 1.0
    if cause.kind == EstimateKind.MIXTURE:
        identified = two_groups_power(pair.without_features * scales, pair.runs, held_out)
    elif cause.screen_simulated and screen_floor_z is not None:
        identified = screen_power(simulator, pair, held_out, *screen_floor_z)
    if cause.look_alike and pair.pseudo is not None:
        identified *= look_alike_power(simulator, pair, cause, gains, scales, held_out,
                                       score_runs, fit or FitSettings())
    t = t_statistic(gains, held_out)
    if z_test is not None and size_se is not None:
        return TestPoint(size_averaged_t(simulator, pair, cause, size, size_se, t, scales,
                                         held_out, score_runs, z_test, fitted_values),
                         identified)
    if z_test is None or not pair.absorbed:
        return TestPoint(t, identified)
    return TestPoint(spread_averaged_t(simulator, pair, t, scales, held_out, score_runs,
                                       fit or FitSettings(), z_test), identified)


def look_alike_power(simulator: Simulator, pair: SimulatedPair, cause: Cause,
                     gains: FloatArray, scales: FloatArray, held_out: int, score_runs: int,
                     fit: FitSettings) -> float:
    """
    Return P(the race adds `cause` before its look-alike) on runs like `pair`'s.

    Of the terms that qualify at a step the race adds the one of the largest mean held-out
    gain (diagnose._step_result). A look-alike (`Cause.look_alike`) fitted to runs with the
    cause gains on them too; where it gains more it enters first, and the cause refit beside
    it no longer clears its floor: in studies/clock_terms.yaml at commit cc3324a,
    change_point at its limit went unnamed in 3 of 8 data sets, speed_decay named in its
    place in 2 of them, where the limit had predicted its size bound to clear in 0.97. The
    look-alike's model is the one without the cause with the look-alike added from where
    the race starts it (`geometry_starts`' first start) and its geometry refit to the runs;
    the probability is that of the cause's per-run gain over it (`gains` less the
    look-alike's, on the same scored runs) being positive in mean on `held_out` runs.
    """
    difference = gains - pair.gains(simulator, scales, score_runs,
                                    look_alike_model(simulator, pair, cause, fit))
    return float(stats.norm.cdf(t_statistic(difference, held_out)))


def look_alike_model(simulator: Simulator, pair: SimulatedPair, cause: Cause,
                     fit: FitSettings) -> FittedModel:
    """
    Return the model without `cause` with its look-alike fitted to `pair`'s runs.

    From the race's first start (`geometry_starts`: the look-alike sized off its signature,
    the strides per run kept), the geometry refit with it.
    """
    assert pair.pseudo is not None, 'the look-alike is fitted to the simulated runs'
    rival = BY_NAME[cause.look_alike]
    on_runs = Simulator(pair.pseudo, simulator.seed)
    absent = pair.without.with_effect(rival.name, at_size(rival, 0.0, None, pair.pseudo))
    start = geometry_starts(on_runs, absent, [rival.name], fit)[0]
    return fit_geometry(pair.pseudo, start, path_terms(start.causes), fit)[0]


def t_statistic(gain: FloatArray, held_out: int) -> float:
    """Return the held-out test's t for per-run gains like `gain` on `held_out` runs."""
    spread = float(np.std(gain, ddof=1))
    if spread <= 0:
        return math.inf if gain.mean() > 0 else 0.0
    return float(gain.mean() / spread * math.sqrt(held_out))


# A standard normal's three-point Gauss-Hermite rule (probabilists'): nodes and weights.
SPREAD_NODES = (0.0, -math.sqrt(3.0), math.sqrt(3.0))
SPREAD_WEIGHTS = (2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0)


def spread_averaged_t(simulator: Simulator, pair: SimulatedPair, t_at_fit: float,
                      scales: FloatArray, held_out: int, score_runs: int, fit: FitSettings,
                      z_test: float) -> float:
    """
    Return the t whose power is the test's averaged over the fitted spread scale's error.

    With a heading term in it, a model's spread scale is read off the variance of the
    stride length (modelfit.spread_statistic), which is noisier than the heading's and
    carries the simulation error of the runs it is matched with; and the test's t is steep
    in that scale: on open_world's replicate 3, heading_random_walk at its limit, t was 4.01
    at the true scale, 2.83 and 1.62 at one and two standard errors (2.1 % each) below it
    and 4.90 at one above (`benchmarks/bench_heading_limits.py --spread-part`). The
    race's extended model is fitted on a calibration half, so its scale is off by a draw
    of that error; the power is averaged over it (three-point Gauss-Hermite, the error from
    `modelfit.spread_error` on runs as many as a half) and returned as the t with that power
    at `z_test`. `t_at_fit` is t at the true scale (the rule's centre).
    """
    extended = pair.extended
    se = spread_error(simulator, extended, fit, pair.runs, held_out)
    ts = [t_at_fit]
    for node in SPREAD_NODES[1:]:
        moved = replace(extended, sigma_scale=max(extended.sigma_scale + node * se, 0.0))
        ts.append(t_statistic(pair.gains(simulator, scales, score_runs, moved), held_out))
    return _averaged(ts, z_test)


def size_averaged_t(simulator: Simulator, pair: SimulatedPair, cause: Cause, size: float,
                    size_se: float, t_at_fit: float, scales: FloatArray, held_out: int,
                    score_runs: int, z_test: float,
                    fitted_values: Mapping[str, float] | None = None) -> float:
    """
    Return the t whose power is the test's averaged over the error of the size fitted.

    The race scores a path family's extended model at the size its refit found on the
    calibration half, not at the truth, and the held-out gain falls off it unevenly: on
    Table II's robot, yaw_rate_ramp at 2.82 deg/s, t 3.70 at the true size, 3.71 at 1.7 of
    the refit's standard errors (0.37) below it and 2.52 above (power 0.70 at the truth, 0.62
    averaged; `benchmarks/bench_path_limits.py --size 2.82`). Averaged as
    `spread_averaged_t` (three-point Gauss-Hermite), `size_se` the refit's error
    (`diagnose.path_family_estimates`).
    """
    ts = [t_at_fit]
    duration = float(simulator.data.paths.t[-1])
    for node in SPREAD_NODES[1:]:
        # a clock term moved keeps the strides per run, as the refit that matches the runs'
        # gait would (`same_strides`); moved alone, its runs gain or lose strides, which the
        # test would score too (a first version did, and change_point's limits rose)
        moved = same_strides(pair.extended.with_effect(cause.name, at_size(
            cause, max(size + node * size_se, 0.0), fitted_values, simulator.data)),
            pair.extended, duration)
        ts.append(t_statistic(pair.gains(simulator, scales, score_runs, moved), held_out))
    return _averaged(ts, z_test)


def _averaged(ts: list[float], z_test: float) -> float:
    """Return the t whose power at `z_test` is the Gauss-Hermite average of `ts`' powers."""
    power = sum(weight * float(stats.norm.cdf(min(t, T_CAP) - z_test))
                for weight, t in zip(SPREAD_WEIGHTS, ts))
    power = min(max(power, 1e-12), 1.0 - 1e-12)
    return z_test + float(stats.norm.ppf(power))


def held_out_gains(simulator: Simulator, without: FittedModel, without_features: FloatArray,
                   cause: Cause, size: float, scales: FloatArray, score_runs: int,
                   fitted_values: Mapping[str, float] | None = None, fit: FitSettings | None = None
                   ) -> FloatArray:
    """Return the per-run gains of runs simulated with the cause at `size` (expected_t)."""
    return simulated_gains(simulator, without, without_features, cause, size, scales,
                           score_runs, fitted_values, fit)[0]


@dataclass(frozen=True)
class SimulatedPair:
    """
    What the held-out test weighs at one size: the two models, and runs with the cause.

    `without_features` are the scored runs of `without` (in data spreads); `runs` the
    pseudo-data runs' features (SI); `absorbed` says that `without`'s spread scale was refit
    to them (`spread_absorbed`).
    """

    extended: FittedModel
    without: FittedModel
    without_features: FloatArray
    runs: FloatArray
    absorbed: bool
    pseudo: RunData | None = None     # the runs themselves, where the geometry was refit

    def gains(self, simulator: Simulator, scales: FloatArray, score_runs: int,
              extended: FittedModel | None = None) -> FloatArray:
        """Return the per-run gains of `extended` (default: the pair's) over `without`."""
        model = self.extended if extended is None else extended
        pseudo = self.runs / scales
        gain: FloatArray = (
            feature_log_score(_features(simulator, model, score_runs, MODEL_PURPOSE, scales),
                              pseudo, model.order_dependent)
            - feature_log_score(self.without_features, pseudo, self.without.order_dependent))
        return gain


def simulated_pair(simulator: Simulator, without: FittedModel, without_features: FloatArray,
                   cause: Cause, size: float, scales: FloatArray, score_runs: int,
                   fitted_values: Mapping[str, float] | None = None,
                   fit: FitSettings | None = None) -> SimulatedPair:
    """
    Return the pair the held-out test weighs, and runs simulated with the cause at `size`.

    The model without the cause is as the diagnosis would fit it to those runs: where a
    geometry mimics the term (`Cause.geometry_mimics`), the runs are those of the robot
    without it plus the term (its clock as before, for a term that slows or speeds it) and
    the model without it has its geometry refit to them (`geometry_absorbed`), as the race's
    baseline is fitted to the runs; a heading term's has its spread refit
    (`spread_absorbed`); `fit` sizes these refits. A clock term whose geometry is not refit
    (none now) would enter with the strides per run of the model without it (`same_strides`),
    the one part of such a refit that matters most.
    """
    values = at_size(cause, size, fitted_values, simulator.data)
    if cause.name == 'initial_pose_error':
        values['position_std_cm'] = float((without.effects.get(cause.name) or {}).get(
            'position_std_cm', 0.0))
    extended = without.with_effect(cause.name, values)
    if not cause.geometry_mimics:
        extended = same_strides(extended, without, float(simulator.data.paths.t[-1]))
    # as many pseudo-data runs as the models are scored with, at most PSEUDO_RUNS
    paths, positions = simulator.runs(extended, min(PSEUDO_RUNS, score_runs), PSEUDO_PURPOSE)
    if cause.geometry_mimics:
        pseudo = simulator.data.with_runs(paths, positions)
        runs = pseudo.features
        without = geometry_absorbed(pseudo, without, extended, fit or FitSettings())
        without_features = limit_base(simulator, without, scales, score_runs)
    else:
        runs = simulator.data.features_of(paths, positions)
    absorbing = spread_absorbed(simulator, without, extended, runs, fit or FitSettings())
    if absorbing is not None:
        without, without_features = absorbing, limit_base(simulator, absorbing, scales,
                                                          score_runs)
    return SimulatedPair(extended, without, without_features, runs, absorbing is not None,
                         pseudo if cause.geometry_mimics else None)


def geometry_absorbed(runs: RunData, without: FittedModel, robot: FittedModel,
                      fit: FitSettings) -> FittedModel:
    """
    Return `without` with its geometry refit to `runs`, runs with a term a geometry mimics.

    The race weighs a term against the model fitted to the runs without it, and a geometry
    bends to take up the mean of some path terms (`Cause.geometry_mimics`): yaw_rate_ramp's
    runs turn on average at half its final rate, which touchdown angles a degree apart make
    too. Scored against the model as fitted to runs without the term, the gain was that of
    the mean turn as well: on Table II's robot (500 null runs) the ramp at its former limit,
    2.82 deg/s, had an expected t of 6.16 against the model as fitted and 3.70 against the
    model refit to runs with it, and four data sets with it there gave t = 2.35, 4.54, 1.64
    and 1.17 for 3.22 where the limit had said 0.999 (`benchmarks/bench_path_limits.py
    --size 2.82 --data-sets 4`). A clock term's mean rate is taken up by the stride frequency
    (module docstring). Other terms keep the model as fitted (`simulated_pair`).

    The refit starts striding at the mean rate of `robot` (the model the runs were simulated
    from), legs scaled to keep the speed (`striding_at`), as the race's baseline starts at the
    runs' own stride frequency: from the old clock, runs of the paper's model with a fifth off
    the clock for half of each run were once fitted at the old clock with legs bent, at 18
    times the cost of the fit from their mean rate (CI, OCTOROACH_TEST_SEED=288569).
    """
    duration = float(runs.paths.t[-1])
    rate = mean_gait_rate(robot.effects, duration) / mean_gait_rate(without.effects, duration)
    start = without if rate == 1.0 else striding_at(
        without, without.parameters.stride_frequency * rate)
    return fit_geometry(runs, start, path_terms(without.causes), fit)[0]


def simulated_gains(simulator: Simulator, without: FittedModel, without_features: FloatArray,
                    cause: Cause, size: float, scales: FloatArray, score_runs: int,
                    fitted_values: Mapping[str, float] | None = None,
                    fit: FitSettings | None = None
                    ) -> tuple[FloatArray, FloatArray]:
    """Return (per-run gains, the pseudo-data runs' features in SI units) at `size`."""
    pair = simulated_pair(simulator, without, without_features, cause, size, scales,
                          score_runs, fitted_values, fit)
    return pair.gains(simulator, scales, score_runs), pair.runs


def spread_absorbed(simulator: Simulator, without: FittedModel, extended: FittedModel,
                    runs: FloatArray, fit: FitSettings) -> FittedModel | None:
    """
    Return `without` with its spread scale refit to `runs`, where a term moves that scale.

    Fitted to data with a heading term, the model without it reads its spread scale off the
    within-run variance of the heading change, which the term raises (modelfit.
    spread_statistic): the spread widens and takes up part of the term, and the held-out
    test weighs the term against that wider model. Scored against the model as fitted
    without the term, the gain was overstated: in open_world, heading_random_walk and
    periodic_heading at their limits were named in 1 of 4 data sets each. None where the
    term leaves the spread's statistic alone (the model without it is as fitted).
    """
    if spread_statistic(extended) == spread_statistic(without):
        return None
    return replace(without, sigma_scale=fit_spread(simulator, without, fit, runs))


def two_groups_power(without_runs: FloatArray, runs: FloatArray, half: int) -> float:
    """
    Return P3: how often calibration halves of `runs` show two groups of heading rates.

    The evidence the race asks of run_mixture (MIXTURE_EVIDENCE_NATS, on heading rates
    centred and spread as the model without it has them), on EVIDENCE_SUBSETS subsets of
    `half` runs drawn without replacement from the simulated runs.
    """
    column = INDEX['heading_rate']
    base = without_runs[:, column]
    centre, spread = float(np.mean(base)), max(float(np.std(base, ddof=1)), 1e-6)
    rates = runs[:, column]
    size = min(half, len(rates))
    rng = np.random.default_rng(len(rates))
    shown = 0
    for _ in range(EVIDENCE_SUBSETS):
        subset = rates[rng.permutation(len(rates))[:size]]
        shift, separation, fraction = two_groups(subset, centre, spread)
        evidence = two_groups_evidence(subset - centre, shift, separation, fraction, spread)
        shown += evidence >= MIXTURE_EVIDENCE_NATS
    return shown / EVIDENCE_SUBSETS


def screen_power(simulator: Simulator, pair: SimulatedPair, half: int, floor: float,
                 z_screen: float) -> float:
    """
    Return how often the race's screen lets change_point through on runs like `pair`'s.

    The screen's step (modelfit.change_point_step) seeks the change's time as well as its
    factor, and its bootstrap error depends on how clearly the runs show that time: on
    Table II's robot 0.0074 on a null data set (the time where chance peaked), 0.0022-0.0030
    with a change of 3 % at half the runs, larger again for smaller changes. So the step is
    taken as the race takes it, against the model without the term, on SCREEN_SUBSETS
    subsets of the simulated runs as large as a calibration half, and the share whose bound
    at `z_screen` reaches `floor` is returned (the null's error, taken instead, held the
    size bound's part of the limit low; a step held at the stated time knows the time the
    race does not).
    """
    assert pair.pseudo is not None, 'a simulated screen needs the simulated runs'
    ratio = speed_ratio(simulator, pair.without)
    with np.errstate(invalid='ignore'):
        rows = cycle_distances(pair.pseudo.paths.positions, ratio.cycle)
    size = min(half, len(rows))
    rng = np.random.default_rng([len(rows), 44])
    passed = 0
    for _ in range(SCREEN_SUBSETS):
        subset = rows[rng.permutation(len(rows))[:size]]
        _, factor, error = ratio.estimate(subset, CHANGE_POINT_BOOTSTRAP, rng)
        passed += not out_of_reach(SizeEstimate('change_point', factor, error), floor, z_screen)
    return passed / SCREEN_SUBSETS


def detection_limit(simulator: Simulator, without: FittedModel, estimate: SizeEstimate,
                    floor: float, z_bound: float, z_test: float, scales: FloatArray,
                    held_out: int, score_runs: int, start: float | None,
                    fitted_values: Mapping[str, float] | None = None,
                    base: FloatArray | None = None,
                    fit: FitSettings | None = None,
                    screen: SizeEstimate | None = None) -> Limit:
    """
    Return the size at which the cause is named with POWER (module docstring).

    `start` is the size bound's own 80 % limit (decide.py), where the search begins;
    `base`, the scored runs of `without` (`limit_base`), when already simulated; `screen`,
    a path family's quick estimate, screened on before `estimate` (its refit's) decides
    (`bound_power`).
    """
    cause = BY_NAME[estimate.cause]
    first = max(start or 0.0, 2 * floor, 1e-9)
    largest = largest_size(cause, fitted_values)
    if base is None:
        base = limit_base(simulator, without, scales, score_runs)

    # a path family (screened first) is scored at its size as refit (`size_averaged_t`)
    size_se = estimate.se if screen is not None and math.isfinite(estimate.se) else None
    # a simulated screen (`screen_power`) takes the place of the quick estimate's bound
    screen_floor_z = (floor, max(z_bound - SCREEN_ALLOWANCE, 0.0)) \
        if cause.screen_simulated else None

    def t_computed(size: float) -> TestPoint:
        point = expected_t(simulator, without, base, cause, size, scales, held_out,
                           score_runs, fitted_values, fit, z_test, size_se, screen_floor_z)
        return TestPoint(min(max(point.t, 1e-9), T_CAP), point.identified)

    return limit_from(t_computed, first, estimate, floor, z_bound, z_test, largest,
                      None if cause.screen_simulated else screen)


def limit_from(t_computed: Callable[[float], TestPoint | float], first: float,
               estimate: SizeEstimate, floor: float, z_bound: float, z_test: float,
               largest: float = math.inf, screen: SizeEstimate | None = None) -> Limit:
    """
    Solve for the limit with T computed at `first`, 3 `first` and, if needed, the limit.

    Where no size reaches POWER through those two, T (and P3) is computed at 9 and 27 `first`
    before the limit is said to be none. No size above `largest` (a path cause's bound, a
    mixture's largest yaw rate: `modelfit.largest_size`) is computed or returned: a limit
    that would lie beyond it is none (`first` comes down to a third of it where needed).

    The limit found is where T is computed next while the simulated part (the test, and P3)
    decides it (module docstring). `t_computed` gives a TestPoint, or T alone; `screen` as
    in `bound_power`.
    """
    def computed(size: float) -> TestPoint:
        point = t_computed(size)
        return point if isinstance(point, TestPoint) else TestPoint(float(point))

    first = min(first, largest / 3)
    points = {size: computed(size) for size in (first, 3 * first)}
    limit = _solve(points, estimate, floor, z_bound, z_test, largest, screen)
    for _ in range(FURTHER_UP):
        # no size reaches POWER through these points: P3 is held at its last value beyond
        # them, so a mixture whose two groups the runs at 3 `first` do not yet show never
        # reached it, and the report said "unseen at any size" (a null of
        # studies/mixture_limits.yaml); simulate further up before saying so
        if limit is not None or max(points) >= largest or bound_power(
                estimate, 1e6 * max(points), floor, z_bound, screen) == 0:
            break       # found, at the edge, or a bound that never clears: nothing to simulate
        top = min(3 * max(points), largest)
        points[top] = computed(top)
        limit = _solve(points, estimate, floor, z_bound, z_test, largest, screen)
    for _ in range(REFINEMENTS):
        if limit is None or limit.size is None or limit.simulated_power >= TEST_DECIDES:
            break
        found = limit.size
        if min(abs(math.log(found / size)) for size in points) < CLOSE:
            break
        points[found] = computed(found)
        limit = _solve(points, estimate, floor, z_bound, z_test, largest, screen)
    if limit is None and largest not in points and math.isfinite(largest) and bound_power(
            estimate, largest, floor, z_bound, screen) > 0:
        # a refit moved the limit past the edge: none only if T computed there says so
        points[largest] = computed(largest)
        limit = _solve(points, estimate, floor, z_bound, z_test, largest, screen)
    return Limit(estimate.cause, None, 0.0, 0.0) if limit is None else limit


def t_interpolated(points: dict[float, float] | dict[float, TestPoint], size: float) -> float:
    """
    Return T at `size`, piecewise linear in log-log through the computed points.

    Beyond the points the end segments are extended, their slope never below 0.1.
    """
    sizes = sorted(points)
    log_s = np.log(sizes)
    log_t = np.log([_t_of(points[size]) for size in sizes])
    x = math.log(size)
    index = int(np.clip(np.searchsorted(log_s, x) - 1, 0, len(sizes) - 2))
    slope = max((log_t[index + 1] - log_t[index]) / (log_s[index + 1] - log_s[index]), 0.1)
    return float(math.exp(log_t[index] + slope * (x - log_s[index])))


def _t_of(point: float | TestPoint) -> float:
    return point.t if isinstance(point, TestPoint) else float(point)


def _identified_of(point: float | TestPoint) -> float:
    return point.identified if isinstance(point, TestPoint) else 1.0


def identified_interpolated(points: dict[float, float] | dict[float, TestPoint],
                            size: float) -> float:
    """
    Return P3 at `size`: linear in log size between the computed points, made monotone.

    Held at the nearest end beyond them (no guess where no runs were simulated).
    """
    sizes = sorted(points)
    values = np.maximum.accumulate([_identified_of(points[size]) for size in sizes])
    return float(np.interp(math.log(size), np.log(sizes), values))


def _solve(points: dict[float, float] | dict[float, TestPoint], estimate: SizeEstimate,
           floor: float, z_bound: float, z_test: float, largest: float = math.inf,
           screen: SizeEstimate | None = None) -> Limit | None:
    """
    Return the smallest size where P(bound) x P(test) x P3 reaches POWER, T interpolated.

    None where no size up to `largest` reaches it.
    """
    cause = BY_NAME[estimate.cause]
    mixture = cause.kind == EstimateKind.MIXTURE

    def test_power(size: float) -> float:
        return float(stats.norm.cdf(t_interpolated(points, size) - z_test))

    def identified(size: float) -> float:
        simulated = mixture or cause.size_bound_simulated
        return identified_interpolated(points, size) if simulated else 1.0

    def power(size: float) -> float:
        return bound_power(estimate, size, floor, z_bound, screen) * test_power(size) * (
            identified(size))

    low, high = max(floor, 1e-9), min(points)
    for _ in range(60):
        if power(high) >= POWER:
            break
        if high >= largest:
            return None
        high = min(1.5 * high, largest)
    else:
        return None
    for _ in range(60):
        middle = math.sqrt(low * high) if low > 0 else 0.5 * high
        low, high = (middle, high) if power(middle) < POWER else (low, middle)
    bound = bound_power(estimate, high, floor, z_bound, screen)
    screened = identified(high) if cause.size_bound_simulated else None
    return Limit(estimate.cause, high, bound * (1.0 if screened is None else screened),
                 test_power(high), identified(high) if mixture else None, screened)
