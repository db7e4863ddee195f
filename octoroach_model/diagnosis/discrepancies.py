"""
Set-level statistics of runs and the discrepancies of data against a model.

A statistic summarises a whole set of runs (a spread, a mean) and is a function of the
per-run features alone, so its bootstrap over runs only resamples rows. A discrepancy compares
the data's value with the model's (simulated runs as many as the data, with the data's run
lengths) in standard errors: z = (data - model) / sqrt(se_data^2 + se_model^2), where
se_data is the data's bootstrap error but at least the model's spread at the data's run count.

Two rules keep numerical noise out (docs/diagnosis.md):
- a difference below the statistic's resolution is no difference (z = 0): e.g. the start
  heading spread of a model and of data that both start every run at one point;
- a discrepancy is *material* only when the difference reaches a tenth of the run-to-run
  spread of the feature behind it (mean statistics), or a tenth of the statistic's value
  (spread statistics), or 0.1 (exponents and correlations), and, where a statistic has one,
  its `relative_floor` of the data's value. With thousands of runs a difference can be
  significant and still too small to matter.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
import math

import numpy as np
from scipy import stats

from octoroach_model.arrays import FloatArray
from octoroach_model.diagnosis.causes import (
    CANDIDATES, Cause, FeatureStatistic, Reading, STRIDE_FREQUENCY_FLOOR)
from octoroach_model.diagnosis.features import INDEX, noise_variance_m2

DEG = 180.0 / math.pi


class Materiality(StrEnum):
    """How large a difference in a statistic is material (see `Statistic`)."""

    MEAN = 'mean'
    SPREAD = 'spread'
    ABSOLUTE = 'absolute'


MEAN, SPREAD, ABSOLUTE = Materiality.MEAN, Materiality.SPREAD, Materiality.ABSOLUTE


@dataclass(frozen=True)
class Statistic:
    """
    A set-level statistic.

    Its function of the feature matrix, unit, resolution, and how large
    a difference is material ('mean': a tenth of the feature's spread across runs, 'spread': a
    tenth of its value, 'absolute': `material` itself; and at least `relative_floor` times the
    data's value, where the runs' spread says nothing of what matters: runs that all stride
    alike spread by their spectra's noise alone). `feature`: the feature behind it, where it
    has one (a mean statistic's materiality reads that feature's spread).
    """

    name: str
    unit: str
    function: Callable[[FloatArray], float]
    resolution: float
    kind: Materiality
    material: float = 0.1
    feature: str = ''
    relative_floor: float = 0.0
    reading: Reading | None = None     # how it reads `feature`, where a term reads it alike

    def read_by(self) -> tuple[Cause, ...]:
        """
        Return the candidates sized or started from this statistic's feature, read alike.

        Those that read it first (their statistic or signature), then those that read it
        beside another (`Cause.also_reads`: a worn leg's terms read the heading rate's trend
        beside the forward distance's).
        """
        if self.reading is None:
            return ()
        first = tuple(cause for cause in CANDIDATES
                      if self.reads(cause.statistic, cause.signature))
        return first + tuple(cause for cause in CANDIDATES
                             if cause not in first and self.reads(*cause.also_reads))

    def reads(self, *statistics: FeatureStatistic | None) -> bool:
        """Return whether any of a term's `statistics` reads this one's feature as it does."""
        return any(read is not None and read.feature == self.feature
                   and read.reading == self.reading for read in statistics)


def _std(column: str, scale: float = 1.0) -> Callable[[FloatArray], float]:
    index = INDEX[column]
    return lambda f: float(np.std(f[:, index], ddof=1) * scale)


def _mean(column: str, scale: float = 1.0) -> Callable[[FloatArray], float]:
    index = INDEX[column]
    return lambda f: float(np.mean(f[:, index]) * scale)


def _start_position_spread_cm(f: FloatArray) -> float:
    return float(np.sqrt(0.5 * (f[:, INDEX['start_x']].var(ddof=1)
                                + f[:, INDEX['start_y']].var(ddof=1))) * 100)


def _noise_cm(f: FloatArray) -> float:
    return float(np.sqrt(max(float(np.mean(noise_variance_m2(f[:, INDEX['log_noise']]))), 0.0))
                 * 100)


def _trend(column: str, scale: float = 1.0) -> Callable[[FloatArray], float]:
    """Return the change of a feature from the first run to the last (least squares)."""
    index, place = INDEX[column], INDEX['position']

    def change(f: FloatArray) -> float:
        x = f[:, place] - f[:, place].mean()
        denominator = float(x @ x)
        return float(x @ f[:, index]) / denominator * scale if denominator > 0 else 0.0
    return change


def _rms(column: str, scale: float = 1.0) -> Callable[[FloatArray], float]:
    """Return the root of the mean of exp(feature): an amplitude from its log square."""
    index = INDEX[column]
    return lambda f: float(np.sqrt(np.mean(np.exp(f[:, index]))) * scale)


def _root_mean(column: str, scale: float = 1.0) -> Callable[[FloatArray], float]:
    index = INDEX[column]
    return lambda f: float(np.sqrt(max(float(np.mean(f[:, index])), 0.0)) * scale)


def _kurtosis(column: str) -> Callable[[FloatArray], float]:
    """Excess kurtosis across runs: two groups of runs make it negative, heavy tails positive."""
    index = INDEX[column]

    def kurtosis(f: FloatArray) -> float:
        values = f[:, index] - f[:, index].mean()
        variance = float(np.mean(values ** 2))
        return float(np.mean(values ** 4)) / variance ** 2 - 3.0 if variance > 0 else 0.0
    return kurtosis


def _growth_exponent(f: FloatArray) -> float:
    """
    Return the slope of log(lateral spread) against log(time).

    Fitted from a quarter of the run to its end: about 1
    for a fixed heading error, 1.5 for a random-walk heading, 2 for steady turning.
    """
    late = float(np.std(f[:, INDEX['end_lateral']], ddof=1))
    early = float(np.std(f[:, INDEX['quarter_lateral']], ddof=1))
    return float(math.log(max(late, 1e-12) / max(early, 1e-12)) / math.log(4.0))


# the name of the statistic a turn growing within each run moves (read by name elsewhere)
HEADING_RATE_CHANGE = 'heading rate change, 2nd half - 1st half'
STATISTICS: tuple[Statistic, ...] = (
    Statistic('start heading spread', 'deg', _std('start_heading', DEG), 0.01, SPREAD,
              feature='start_heading', reading=Reading.VARIANCE),
    Statistic('start position spread', 'cm', _start_position_spread_cm, 0.001, SPREAD),
    Statistic('position noise (median 4th difference)', 'cm', _noise_cm, 0.001, SPREAD),
    Statistic('heading to travel angle', 'deg', _mean('slip_angle', DEG), 0.01, MEAN,
              feature='slip_angle', reading=Reading.MEAN),
    # material from the size floor of gait_frequency_variation on (0.5 %)
    Statistic('mean stride frequency', 'Hz', _mean('stride_frequency'), 1e-4, MEAN,
              feature='stride_frequency', relative_floor=STRIDE_FREQUENCY_FLOOR),
    Statistic('stride frequency spread across runs', 'Hz', _std('stride_frequency'), 1e-4,
              SPREAD),
    Statistic('log speed ratio, 2nd half / 1st half', '', _mean('progress_ratio'), 1e-4, MEAN,
              feature='progress_ratio', reading=Reading.MEAN),
    Statistic('heading rate spread across runs', 'deg/s', _std('heading_rate', DEG), 0.01,
              SPREAD),
    Statistic('per-cycle heading change spread within runs', 'deg',
              lambda f: float(np.sqrt(f[:, INDEX['increment_var']].mean()) * DEG), 0.01,
              SPREAD, feature='increment_var', reading=Reading.MEAN),
    Statistic('lag-1 autocorrelation of heading changes', '', _mean('increment_autocorr'),
              1e-3, ABSOLUTE),
    Statistic('mean progress at the end', 'cm', _mean('end_progress', 100), 0.01, MEAN,
              feature='end_progress'),
    Statistic('mean lateral position at the end', 'cm', _mean('end_lateral', 100), 0.01,
              MEAN, feature='end_lateral'),
    Statistic('lateral spread at the end', 'cm', _std('end_lateral', 100), 0.01, SPREAD),
    Statistic('progress spread at the end', 'cm', _std('end_progress', 100), 0.01, SPREAD),
    Statistic('lateral spread growth exponent', '', _growth_exponent, 1e-3, ABSOLUTE),
    Statistic('heading sway amplitude', 'deg', _mean('sway_amplitude', DEG), 0.01, MEAN,
              feature='sway_amplitude'),
    Statistic('sideways sway at the stride frequency', 'cm', _mean('lateral_sway_1', 100),
              1e-4, MEAN, feature='lateral_sway_1'),
    Statistic('sideways sway at twice the stride frequency', 'cm', _mean('lateral_sway_2', 100),
              1e-4, MEAN, feature='lateral_sway_2'),
    # what the extension families move (docs/extensions.md)
    Statistic('stride frequency change from the first run to the last', 'Hz',
              _trend('stride_frequency'), 1e-4, MEAN, feature='stride_frequency',
              reading=Reading.TREND),
    Statistic('heading rate change from the first run to the last', 'deg/s',
              _trend('heading_rate', DEG), 0.01, MEAN, feature='heading_rate',
              reading=Reading.TREND),
    Statistic('heading to travel angle change from the first run to the last', 'deg',
              _trend('slip_angle', DEG), 0.01, MEAN, feature='slip_angle',
              reading=Reading.TREND),
    # a worn leg's: phi1 and phi2 move the distance, hardly the turn (docs/extensions.md)
    Statistic('forward distance change from the first run to the last', 'cm',
              _trend('end_progress', 100), 0.01, MEAN, feature='end_progress',
              reading=Reading.TREND),
    Statistic('log speed ratio, 2nd quarter / 1st quarter', '', _mean('progress_early'), 1e-4,
              MEAN, feature='progress_early'),
    Statistic('log speed ratio, 4th quarter / 3rd quarter', '', _mean('progress_late'), 1e-4,
              MEAN, feature='progress_late'),
    Statistic('stride length change from cycle to cycle', 'cm',
              _root_mean('stride_length_var', 100), 1e-4, SPREAD, feature='stride_length_var'),
    Statistic('heading wobble at the wobble frequency', 'deg', _rms('heading_wobble', DEG),
              0.01, SPREAD),
    Statistic('heading rate excess kurtosis across runs', '', _kurtosis('heading_rate'), 1e-3,
              ABSOLUTE, material=0.5),
    # a turn that grows within each run (features.py, note (5)), yaw_rate_ramp's size or less
    Statistic(HEADING_RATE_CHANGE, 'deg/s',
              _mean('heading_rate_change', DEG), 0.01, MEAN, feature='heading_rate_change',
              reading=Reading.MEAN),
)


@dataclass(frozen=True)
class Discrepancy:
    """One statistic of the data against a model (units in `unit`)."""

    statistic: str
    unit: str
    data: float
    model: float
    data_se: float
    model_se: float
    z: float
    material: bool

    @property
    def difference(self) -> float:
        return self.data - self.model


def values_with_errors(features: FloatArray, rng: np.random.Generator, n_boot: int
                       ) -> tuple[FloatArray, FloatArray]:
    """Every statistic's value and bootstrap standard error over runs."""
    return statistic_values(features), _bootstrap_se(features, rng, n_boot, features.shape[0])


def _bootstrap_se(features: FloatArray, rng: np.random.Generator, n_boot: int, runs: int
                  ) -> FloatArray:
    """Every statistic's spread over `n_boot` sets of `runs` runs drawn from `features`."""
    n = features.shape[0]
    boot = np.array([[s.function(features[pick]) for s in STATISTICS]
                     for pick in (rng.integers(0, n, runs) for _ in range(n_boot))])
    return np.asarray(np.std(boot, axis=0, ddof=1), dtype=float)


def statistic_values(features: FloatArray) -> FloatArray:
    """Every statistic of STATISTICS, in order."""
    return np.array([s.function(features) for s in STATISTICS])


def discrepancies(data_features: FloatArray, model_features: FloatArray,
                  rng: np.random.Generator, n_boot: int,
                  fit_se: FloatArray | None = None) -> list[Discrepancy]:
    """
    Every statistic of data against model, largest |z| first.

    `fit_se` (per statistic) is the error the model's statistics carry because its
    parameters were fitted to these same runs: without it, a model fitted on many runs would
    be judged against a precision its own fit does not have.
    """
    data, data_se = values_with_errors(data_features, rng, n_boot)
    model, model_se = values_with_errors(model_features, rng, n_boot)
    # Under the check's null the data have the model's sampling spread: a few runs that
    # happen to be light-tailed or tight bootstrap to a tiny error (the kurtosis of 60 normal
    # heading rates against 2000: z's mean square 1.15-3.0, test_diagnosis.py), so the
    # data's error is at least the model's own spread of the statistic at the data's run
    # count. Its draws come from a spawned stream: every other draw stays as it was, so on
    # the same seed this can only lower |z|.
    data_se = np.fmax(data_se, _bootstrap_se(model_features, rng.spawn(1)[0], n_boot,
                                             data_features.shape[0]))
    if fit_se is not None:
        model_se = np.hypot(model_se, fit_se)
    rows = []
    for index, statistic in enumerate(STATISTICS):
        difference = data[index] - model[index]
        error = math.hypot(data_se[index], model_se[index])
        if abs(difference) < statistic.resolution or not math.isfinite(difference):
            z = 0.0
        else:
            z = difference / error if error > 0 else math.copysign(math.inf, difference)
        rows.append(Discrepancy(statistic.name, statistic.unit, float(data[index]),
                                float(model[index]), float(data_se[index]),
                                float(model_se[index]), float(z),
                                _material(statistic, difference, data[index], data_features)))
    rows.sort(key=lambda row: -abs(row.z))
    return rows


def _material(statistic: Statistic, difference: float, value: float,
              features: FloatArray) -> bool:
    if abs(difference) < statistic.relative_floor * abs(value):
        return False
    if statistic.kind == MEAN:
        spread = float(np.std(features[:, INDEX[statistic.feature]], ddof=1))
        scale = spread * _unit_factor(statistic)
        return abs(difference) >= statistic.material * scale
    if statistic.kind == SPREAD:
        return abs(difference) >= statistic.material * max(abs(value), statistic.resolution)
    return abs(difference) >= statistic.material


def _unit_factor(statistic: Statistic) -> float:
    """From the feature's SI unit to the statistic's reporting unit."""
    return {'deg': DEG, 'cm': 100.0}.get(statistic.unit, 1.0)


def critical_z(level: float, count: int) -> float:
    """
    Return |z| beyond which a statistic is off (Bonferroni, two-sided).

    At family level `level` over `count` statistics.
    """
    return float(stats.norm.isf(level / (2 * max(count, 1))))
