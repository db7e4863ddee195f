"""
The causes and the extension families as the diagnosis sees them.

What each one moves, how its size is estimated, and the smallest size it may claim. The table
of causes (CAUSES) and the library of extension families (FAMILIES, docs/extensions.md) are
declared alike and race in the same forward selection; a family is one entry here plus its
term in model/extensions.py.

Four kinds of estimate (docs/diagnosis.md):

- **moments** (initial_pose_error, measurement_noise, gait_frequency_variation,
  persistent_turning): a statistic of the runs whose *variance-like* value grows linearly in
  the squared size, S(u) = S(0) + kappa u with u = size^2. S(0) and kappa come from runs of the
  current model simulated without and with the cause (common random numbers); the size is
  read off the line at the data's value of S.
- **path** (lateral_slip, speed_decay): the cause bends the average path, which the geometry
  alone could mimic, so its size is fitted jointly with the geometry (eq. 9 extended). The
  fit starts from the size its `signature` statistic (mean slip angle, mean speed ratio)
  reads off a line through the model without and with the cause: a geometry that has bent
  to mimic the cause would otherwise hold the fit in the wrong valley. change_point is one
  too, with two parameters free (its start comes from the runs' speed profile).
- **trend** (run_order_drift): the least-squares slope of a feature against the run's place
  in the recording, T(c) = T(0) + kappa c, read off at the data's slope (linear in the size,
  signed): a drift over the session is a trend in run order, not a spread. A touchdown
  angle's drift (a leg that wears) is read off a curve (`secant_steps`), and off two
  features at once (`also_reads`): the forward distance's and the heading rate's slopes bend
  where the angle passes its pair partner's and the liftoff angle changes legs, and which of
  the two shows the wear depends on the leg (on open_world's robots phi1 and phi2 move the
  distance and hardly the turn, phi4 the turn, phi3 both).
- **mixture** (run_mixture): the fraction and yaw rate of the turning runs by maximum
  likelihood on the runs' heading rates (two normals a yaw rate apart, the spread of each the
  model's), the geometry refit around them; its size is the spread it adds,
  |yaw rate| sqrt(fraction (1 - fraction)), which is zero when no run or every run turns.

The **floor** of a cause is the smallest size that matters, which the diagnosis claims only when it
is sure the size exceeds it (decide.py), whatever the p-value:

| cause | floor | why |
| --- | --- | --- |
| initial_pose_error | 0.5 deg | below the orientation accuracy of a motion-capture body |
| measurement_noise | 0.01 cm | the motion capture's position resolution (0.1 mm) |
| gait_frequency_variation | 0.005 | a stride frequency 0.5 % off moves a run by 0.5 % |
| speed_decay | 0.01 | the stride frequency 1 % lower at the end of the run |
| lateral_slip | 1 % of the forward speed | a drift angle of 0.6 deg |
| persistent_turning | 1 deg per run | a turn of 1 deg over the run's duration |
| run_order_drift, stride_frequency | 0.01 | the stride frequency 1 % lower at the last run |
| run_order_drift, yaw_rate | 1 deg per run | the last run turns 1 deg more over its duration |
| run_order_drift, lateral_velocity | 1 % of the forward speed | as lateral_slip |
| run_order_drift, touchdown_angle_k | 1 deg | Table II's 5 s run turns 1.5 deg, goes 0.5 cm |
| heading_random_walk | 1 deg / sqrt(stances per run) | a wander of 1 deg over the run |
| periodic_heading | 0.5 deg | below the orientation accuracy of a motion-capture body |
| change_point | 0.01 | the speed 1 % different after the change |
| run_mixture | 1 deg per run | the spread of turning it adds, as persistent_turning |

The path-length and duration floors scale with the robot (`RunScale`): what matters for a fast
robot on long runs is smaller in absolute terms than for a slow one.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.diagnosis.features import (
    INDEX, noise_variance_m2, POSITION_RESOLUTION_M)
from octoroach_model.model import EFFECT_NAMES, EFFECT_PARAMETERS
from octoroach_model.model.extensions import drift_term, TERM_BY_NAME, TERM_NAMES, WORN_ANGLES

# the share of turning runs at which run_mixture's detection limit is stated (a yaw rate),
# and which a study or a limit uses where none is given or fitted
MIXTURE_FRACTION = 0.3
# the periods per run at which periodic_heading's detection limit is stated (a heading's
# noise depends on its frequency: a limit at the frequency a null data set happens to peak at
# says nothing of an oscillation elsewhere), and where a study puts one when none is given
PERIODIC_LIMIT_PERIODS = 3.0


# where in a run change_point's detection limit is stated, and where a study or a limit puts
# a change when none is given or fitted (a null data set's step peaks where chance puts it)
CHANGE_POINT_LIMIT_SHARE = 0.5


def change_point_limit_s(duration_s: float) -> float:
    """
    Return the time at which change_point's detection limit is stated: half the runs (s).

    The held-out test's power depends on the time: on Table II's robot a change of 3 % had an
    expected t of 15.5 at 3.4 s of 5 s runs, 14.2 at 1.25 s and 6.1 at 2.5 s (the quarters'
    progress features see a change within a half; a probe, script not kept), and a null data
    set's step peaks where chance puts it (0.5, 2.0 and 3.4 s on three of Table II's null
    data sets), so a limit at the time fitted said nothing of a change elsewhere.
    """
    return CHANGE_POINT_LIMIT_SHARE * duration_s


def periodic_limit_hz(duration_s: float, stride_hz: float) -> float:
    """
    Return where periodic_heading's limit is stated: PERIODIC_LIMIT_PERIODS per run.

    Below the stride's own sway: at most half the stride frequency (runs under six strides).
    """
    return min(PERIODIC_LIMIT_PERIODS / max(duration_s, 1e-9), 0.5 * stride_hz)


class EstimateKind(StrEnum):
    """How a candidate's size is estimated (the four kinds of the module docstring)."""

    MOMENTS = 'moments'
    PATH = 'path'
    TREND = 'trend'
    MIXTURE = 'mixture'


@dataclass(frozen=True)
class RunScale:
    """What the floors depend on: how long a run lasts, how far it goes, how many stances."""

    duration_s: float
    path_length_m: float
    stances: float = 20.0


class Reading(StrEnum):
    """How a `FeatureStatistic` reads its feature's column over runs."""

    MEAN = 'mean'
    VARIANCE = 'variance'
    MEAN_EXP = 'mean of exp'                 # a log-power feature read as a power
    NOISE_VARIANCE = 'noise variance'        # log_noise read as a variance, m^2
    TREND = 'trend'                          # slope against the run's place in the recording


@dataclass(frozen=True)
class FeatureStatistic:
    """
    A number a term is sized or started from: one feature's column over runs, read one way.

    A `Cause`'s `statistic` and `signature`. It names its feature so that a test can check
    that every feature a term is sized from is also scored (features.OUTCOMES): a term whose
    size the runs show in a feature the held-out test does not read can clear its floor by
    far and still go unnamed (features.py, note (5)).
    """

    feature: str
    reading: Reading

    def __call__(self, features: FloatArray) -> float:
        values = features[:, INDEX[self.feature]]
        if self.reading == Reading.MEAN:
            return float(np.mean(values))
        if self.reading == Reading.VARIANCE:
            return float(np.var(values, ddof=1))
        if self.reading == Reading.MEAN_EXP:
            return float(np.mean(np.exp(values)))
        if self.reading == Reading.NOISE_VARIANCE:
            return float(np.mean(noise_variance_m2(values)))
        place = features[:, INDEX['position']]
        x = place - place.mean()
        denominator = float(x @ x)
        return float(x @ values) / denominator if denominator > 0 else 0.0


@dataclass(frozen=True)
class Cause:
    """
    One candidate of the diagnosis: a cause of the table, or a term of an extension family.

    `name` is the term in a model's effects (`run_order_drift:yaw_rate` for a family's term);
    `statistic` (moments and trend kinds) maps a feature matrix to the statistic S;
    `reference` is the size simulated to measure the slope kappa (the table's unit);
    `floor` maps a RunScale to the smallest size claimed; `family` is empty for a cause of the
    table; `null` is the main parameter's value that means no effect (change_point's speed
    factor 1); `order_dependent` terms are predicted run by run at the run's place;
    `geometry_mimics` marks a path term whose mean effect a geometry fitted without it takes
    up in good part (yaw_rate_ramp's mean turn; the mean rate of a term that slows or speeds
    the gait clock, which the stride frequency takes), so that its limit weighs it against
    the model refit without it (limits.geometry_absorbed); `limit_stated` says where a limit
    is stated when it depends on a parameter besides the size (a change's time);
    `screen_simulated` marks a path family whose screen the limit simulates (change_point:
    its step's error depends on how well the runs show the change's time, limits.
    screen_power), where the others take the screen's error off the null data set;
    `look_alike` names a term the race may add in this one's place on runs with it, which
    its limit weighs (change_point's speed_decay: a decay over the run takes up much of a
    change at its middle; limits.look_alike_power);
    `limit_caveat` says in words where studies found the term's detection limit not to hold
    as computed (the report carries it beside the limit); none does now (periodic_heading's,
    named in 7 of 12 data sets at 1x in studies/heading_terms.yaml's first run, was named in
    19 of 24 with studies/periodic_limits.yaml's twelve at commit 33f1294).
    """

    name: str
    unit: str
    kind: EstimateKind
    statistic_name: str
    statistic: FeatureStatistic | None
    reference: float
    floor: Callable[[RunScale], float]
    signed: bool = False
    bounds: tuple[float, float] = (0.0, 1.0)    # sizes a fit may take (path causes)
    signature: FeatureStatistic | None = None   # path causes: where to start
    family: str = ''
    main: str = ''                              # main parameter (default: the term's first)
    null: float = 0.0
    order_dependent: bool = False
    # a trend read off a curve, not a line: secant steps from the reference size towards
    # the data's statistic (modelfit.fit_trend; run_order_drift:touchdown_angle_3, whose
    # forward distance grows 0.54 cm a degree below phi4 and 0.22 above on Table II's robot)
    secant_steps: int = 0
    # more trends the size is read off with `statistic`, each weighed by its local slope
    # over its error on the data (modelfit._joint_secant; a worn leg shows in the distance,
    # the turn or both, depending on the leg and the robot)
    also_reads: tuple[FeatureStatistic, ...] = ()
    geometry_mimics: bool = False
    limit_stated: str = ''
    screen_simulated: bool = False
    look_alike: str = ''
    limit_caveat: str = ''

    @property
    def parameter(self) -> str:
        """Return the main parameter: the first of the cause in the table of causes."""
        if self.main:
            return self.main
        if self.name in EFFECT_PARAMETERS:
            return EFFECT_PARAMETERS[self.name][0]
        return TERM_BY_NAME[self.name].parameters[0]

    @property
    def is_extension(self) -> bool:
        """Return whether this is a term of an extension family (not a cause of the table)."""
        return bool(self.family)

    @property
    def is_path_family(self) -> bool:
        """Whether a family term sized with the geometry: screened on a quick estimate first."""
        return self.is_extension and self.kind == EstimateKind.PATH

    @property
    def size_bound_simulated(self) -> bool:
        """Whether part of its limit's P1 comes from simulated runs (screen, look-alike)."""
        return self.screen_simulated or bool(self.look_alike)

    @property
    def label(self) -> str:
        """Return the name a report gives it: the cause, or the extension family."""
        return self.family or self.name

    def effects(self, size: float) -> dict[str, dict[str, float]]:
        """{cause: {main parameter: size}} (other parameters 0)."""
        return {self.name: {self.parameter: float(size)}}


def _variance_of(feature: str) -> FeatureStatistic:
    return FeatureStatistic(feature, Reading.VARIANCE)


def _mean_of(feature: str) -> FeatureStatistic:
    return FeatureStatistic(feature, Reading.MEAN)


def _mean_exp_of(feature: str) -> FeatureStatistic:
    return FeatureStatistic(feature, Reading.MEAN_EXP)


def _trend_of(feature: str) -> FeatureStatistic:
    """Return the least-squares slope of a feature against the run's place in the recording."""
    return FeatureStatistic(feature, Reading.TREND)


# position noise variance (m^2) read from the median 4th differences (module features)
_NOISE_VARIANCE = FeatureStatistic('log_noise', Reading.NOISE_VARIANCE)


def _slip_floor(scale: RunScale) -> float:
    speed_cm_s = 100 * scale.path_length_m / max(scale.duration_s, 1e-3)
    return max(0.01 * speed_cm_s, POSITION_RESOLUTION_M * 100 / max(scale.duration_s, 1e-3))


# a stride frequency 0.5 % off moves a run by 0.5 % (also the adequacy check's floor of the
# mean stride frequency, discrepancies.py)
STRIDE_FREQUENCY_FLOOR = 0.005

CAUSES: tuple[Cause, ...] = (
    Cause('initial_pose_error', 'deg', EstimateKind.MOMENTS, 'start heading variance',
          _variance_of('start_heading'), 4.0, lambda scale: 0.5),
    Cause('measurement_noise', 'cm', EstimateKind.MOMENTS, 'position noise variance (median 4th '
          'difference)', _NOISE_VARIANCE, 0.05, lambda scale: POSITION_RESOLUTION_M * 100),
    Cause('gait_frequency_variation', '', EstimateKind.MOMENTS,
          'stride frequency variance across runs', _variance_of('stride_frequency'), 0.05,
          lambda scale: STRIDE_FREQUENCY_FLOOR),
    Cause('speed_decay', '', EstimateKind.PATH, 'average path (joint fit with the geometry)',
          None, 0.2, lambda scale: 0.01, signed=True, bounds=(-0.9, 0.9),
          signature=_mean_of('progress_ratio'), geometry_mimics=True),
    Cause('lateral_slip', 'cm/s', EstimateKind.PATH,
          'average path (joint fit with the geometry)', None, 2.0, _slip_floor, signed=True,
          bounds=(-50.0, 50.0), signature=_mean_of('slip_angle')),
    Cause('persistent_turning', 'deg/s', EstimateKind.MOMENTS,
          'heading rate variance across runs', _variance_of('heading_rate'), 5.0,
          lambda scale: 1.0 / max(scale.duration_s, 1e-3)),
)


def _duration_floor(scale: RunScale) -> float:
    return 1.0 / max(scale.duration_s, 1e-3)


FAMILIES: tuple[Cause, ...] = (
    Cause(drift_term('stride_frequency'), '', EstimateKind.TREND,
          'stride frequency against run order', _trend_of('stride_frequency'), 0.1,
          lambda scale: 0.01, signed=True, family='run_order_drift', order_dependent=True),
    Cause(drift_term('yaw_rate'), 'deg/s', EstimateKind.TREND, 'heading rate against run order',
          _trend_of('heading_rate'), 5.0, _duration_floor, signed=True,
          family='run_order_drift', order_dependent=True),
    Cause(drift_term('lateral_velocity'), 'cm/s', EstimateKind.TREND,
          'heading to travel angle against run order', _trend_of('slip_angle'), 2.0,
          _slip_floor, signed=True, family='run_order_drift', order_dependent=True),
    *(Cause(drift_term(parameter), 'deg', EstimateKind.TREND,
            'forward distance and heading rate against run order', _trend_of('end_progress'),
            3.0, lambda scale: 1.0, signed=True, bounds=(-40.0, 40.0),
            family='run_order_drift', order_dependent=True, secant_steps=3,
            also_reads=(_trend_of('heading_rate'),))
      for parameter in WORN_ANGLES),
    Cause('heading_random_walk', 'deg', EstimateKind.MOMENTS,
          'per-cycle heading change variance beside the stride length variance',
          _mean_of('increment_var'), 1.0, lambda scale: 1.0 / np.sqrt(max(scale.stances, 1.0)),
          family='heading_random_walk'),
    Cause('periodic_heading', 'deg', EstimateKind.MOMENTS,
          'heading power at the wobble frequency', _mean_exp_of('heading_wobble'), 5.0,
          lambda scale: 0.5, family='periodic_heading',
          limit_stated=f'at {PERIODIC_LIMIT_PERIODS:g} periods per run, at most half the '
          'stride frequency'),
    Cause('change_point', '', EstimateKind.PATH, 'average path (joint fit with the geometry)',
          None, 0.7, lambda scale: 0.01, signed=True, bounds=(0.2, 3.0), family='change_point',
          main='speed_factor', null=1.0, geometry_mimics=True,
          limit_stated='for a change at half the runs', screen_simulated=True,
          look_alike='speed_decay'),
    Cause('run_mixture', 'deg/s', EstimateKind.MIXTURE,
          'heading rates across runs (two groups)', None, 8.0, _duration_floor, signed=True,
          family='run_mixture', main='yaw_rate_deg_s',
          limit_stated=f'with {MIXTURE_FRACTION:.0%} of the runs turning'),
    Cause('yaw_rate_ramp', 'deg/s', EstimateKind.PATH,
          'average path (joint fit with the geometry)', None, 5.0, _duration_floor,
          signed=True, bounds=(-30.0, 30.0), signature=_mean_of('heading_rate_change'),
          family='yaw_rate_ramp', geometry_mimics=True),
)
CANDIDATES: tuple[Cause, ...] = CAUSES + FAMILIES
BY_NAME = {cause.name: cause for cause in CANDIDATES}
assert tuple(sorted(cause.name for cause in CAUSES)) == tuple(sorted(EFFECT_NAMES))
assert tuple(sorted(cause.name for cause in FAMILIES)) == tuple(sorted(TERM_NAMES))
