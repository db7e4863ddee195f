"""
What a fit of the model matches: the measured average path, heading and gait, and its units.

The average of the runs (`AverageTarget`, on the recorded grid or a common gait clock), the
runs' mean start pose (Table I's means), their mean gait within a stride (`GaitTarget`: sway,
stride frequency, heading to travel angle), and the residuals of a model against them
(`residual_vector`), in cm (the path and heading alone) or in the data's own standard
errors (`ResidualScales`). Used by the nominal fit (nominal.py) and by the
diagnosis's fits alike.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from octoroach_model.arrays import FloatArray, IntArray
from octoroach_model.fitting.gait import aligned_runs, GAIT_FEATURES, gait_features
from octoroach_model.paths import Paths


@dataclass(frozen=True)
class GaitTarget:
    """
    The data's mean gait: its sway within a stride, its strides, its travel against its heading.

    Heading sway amplitude [rad], sideways sway at f and 2f [m], stride frequency [Hz] and
    heading to travel angle [rad], each the mean over the runs as the runs' features read
    it. The average path and sway alone leave two things loose on long runs: the stride
    frequency, where the path has minima a whole cycle of phase apart (40 strides at 5.7 Hz
    fitted at 5.37 Hz with a leg 9 % long, benchmarks/bench_geometry_coverage.py; a slow
    heading wobble let a robot of 2 Hz fit at 2.5 Hz, test_diagnosis.py), and the difference
    of the second and fourth touchdown angles, which sets the heading to travel angle.
    Measured on the runs as recorded (`t`, each run `lengths[i]` samples long, the angle over
    windows of `cycle` samples): the model's runs are simulated on the same grid and cut to
    the same lengths before they are compared.
    """

    values: tuple[float, ...]          # one per GAIT_FEATURES
    t: FloatArray
    lengths: IntArray
    cycle: int

    def of_runs(self, runs: FloatArray, guess_hz: float) -> FloatArray:
        """Return the (runs, GAIT_FEATURES) of simulated runs on `t`, cut like the data's."""
        picks = self.lengths[np.arange(runs.shape[0]) % len(self.lengths)]
        if picks.min() < len(self.t):          # some data runs end early: cut alike
            cut = np.arange(len(self.t))[None, :] >= picks[:, None]
            runs = np.where(cut[..., None], np.nan, runs)
        return gait_features(self.t, runs[..., :2], runs[..., 2], guess_hz, self.cycle)


@dataclass(frozen=True)
class ResidualScales:
    """
    Standard errors that make the fit's residuals dimensionless.

    They are those of the average path at each time (G, 2) [m], of the average heading change
    (G,) [rad] and of the gait target's means (`GaitTarget`, one per GAIT_FEATURES).

    From the data's own run-to-run spread: where the runs scatter widely (late in a run, or
    under a random turning rate), the average is uncertain and a gap there weighs little, so
    the geometry does not bend to follow the chance curvature of an average path.

    `gait_weight` multiplies the gait's residuals: the samples of the average path within one
    stride move together (its chance deviation grows stride by stride), so G path residuals
    are far fewer independent looks than G, while each gait residual is one. Weighed as a
    stride's samples of the path (`gait_weight_for`), the gait keeps its say on long runs
    finely sampled: at weight 1 a robot of 34 strides a run at 126 samples a stride fitted
    its angles to the chance wander of 30 runs' average path and left the sideways sway at
    the stride frequency 5-6 standard errors off the data's (test_diagnosis.py).
    """

    path: FloatArray
    turn: FloatArray
    gait: FloatArray
    gait_weight: float = 1.0


def residual_vector(path_gap: FloatArray, turn_gap: FloatArray | None,
                    gait_gap: FloatArray | None, heading_weight_m: float,
                    scales: ResidualScales | None) -> FloatArray:
    """
    Return the fit's residuals from model-minus-data gaps.

    In standard errors with `scales`, else in cm (heading through `heading_weight_m`); a gait
    gap has no unit in common with the path's and is matched in standard errors only.

    Parameters
    ----------
    path_gap : array, shape (G, 2)
        Model minus data average path, m.
    turn_gap : array, shape (G,), or None
        Heading change gap, rad.
    gait_gap : array, shape (5,), or None
        Gap to the gait target (rad, m, m, Hz, rad); needs `scales`.
    heading_weight_m : float
        m per rad of heading, without `scales`.
    scales : ResidualScales or None
        Standard errors of the gaps.

    Returns
    -------
    array, shape (2 G,), plus G with `turn_gap`, plus 5 with `gait_gap`
        The parts given, flattened in that order.

    """
    if scales is not None:
        parts = [(path_gap / scales.path).ravel()]
        if turn_gap is not None:
            parts.append(turn_gap / scales.turn)
        if gait_gap is not None:
            parts.append(gait_gap / scales.gait * scales.gait_weight)
        return np.concatenate(parts)
    if gait_gap is not None:
        raise ValueError('a gait target is matched in standard errors: give its ResidualScales')
    parts = [path_gap.ravel()]
    if turn_gap is not None:
        parts.append(turn_gap * heading_weight_m)
    return np.concatenate(parts) * 100.0


def gait_weight_for(rate_hz: float, stride_frequency_hz: float) -> float:
    """
    Return the weight of a gait residual: as much as one stride's samples of the average path.

    The square root of the samples per stride, at least 1 (ResidualScales); 1 where the
    stride frequency is unknown.
    """
    if not (math.isfinite(rate_hz) and math.isfinite(stride_frequency_hz)
            and stride_frequency_hz > 0):
        return 1.0
    return math.sqrt(max(rate_hz / stride_frequency_hz, 1.0))


def mean_start_pose(measured: Paths) -> tuple[float, float, float]:
    """Mean first pose of the runs: x, y and the circular mean of the heading."""
    first = measured.poses[:, 0]
    heading = math.atan2(np.sin(first[:, 2]).mean(), np.cos(first[:, 2]).mean())
    return float(first[:, 0].mean()), float(first[:, 1].mean()), float(heading)


@dataclass(frozen=True)
class AverageTarget:
    """
    What the fit matches: times (G,), the average path (G, 2) and average heading change (G,).

    With the runs they average (`runs_xy` (n, G, 2), `runs_turn` (n, G); NaN where a run has
    ended), so that a resampling of the runs gives a resampled target.
    """

    t: FloatArray
    runs_xy: FloatArray
    runs_turn: FloatArray
    start_heading: FloatArray

    @property
    def average(self) -> FloatArray:
        return _nanmean_rows(self.runs_xy)

    @property
    def turn(self) -> FloatArray:
        return _nanmean_rows(self.runs_turn)

    def scales(self, gait_per_run: FloatArray | None = None,
               floor_m: float = 1e-5, gait_weight: float = 1.0) -> ResidualScales:
        """
        Return the standard errors of this target's averages (and of `gait_per_run`'s mean).

        Never below `floor_m` (positions; the same in rad for the heading); `gait_weight` as
        in `ResidualScales`.
        """
        def standard_error(values: FloatArray) -> FloatArray:
            count = np.maximum(np.isfinite(values).sum(axis=0), 2)
            with np.errstate(invalid='ignore'):
                spread = np.nanstd(values, axis=0, ddof=1)
            error: FloatArray = np.maximum(np.nan_to_num(spread / np.sqrt(count)), floor_m)
            return error

        gait = (standard_error(gait_per_run) if gait_per_run is not None
                else np.full(len(GAIT_FEATURES), floor_m))
        return ResidualScales(standard_error(self.runs_xy), standard_error(self.runs_turn),
                              np.maximum(gait, 1e-12), gait_weight)


def _nanmean_rows(values: FloatArray) -> FloatArray:
    with np.errstate(invalid='ignore', divide='ignore'):
        count = np.isfinite(values).sum(axis=0)
        mean: FloatArray = np.nansum(values, axis=0) / np.maximum(count, 1)
        return mean


def average_target(measured: Paths, start_pose: tuple[float, float, float], guess_hz: float,
                   align_gait: bool) -> AverageTarget:
    """
    Average the paths of `measured` over the times that at least a tenth of the runs reach.

    With `align_gait`, on a common gait clock.
    """
    if align_gait:
        t, xy, turn, _ = aligned_runs(measured, guess_hz)
    else:
        t, xy = measured.t, measured.positions
        # heading change since the mean start heading (runs are unwrapped)
        turn = np.angle(np.exp(1j * (measured.poses[..., 2] - start_pose[2])))
    reached = np.isfinite(xy[..., 0]).sum(axis=0) >= max(1, 0.1 * measured.n_paths)
    return AverageTarget(t[reached], xy[:, reached], turn[:, reached], measured.poses[:, 0, 2])
