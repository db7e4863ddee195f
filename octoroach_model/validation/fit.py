"""
The nominal fit (eq. 9): the deterministic model closest to the average measured path.

docs/validation.md ("The nominal fit") describes it for users.

Least squares over zeta = [l, phi1..phi4] (the paper's) plus the stride frequency. The model
starts at the measured mean start pose (Table I's means: x, y and the circular mean heading):
fitting it instead would trade a start offset for a better middle, and the confidence region
is narrowest at the start. The stride frequency starts from the spectral peak of the average
forward speed as well as from the initial value, so the fit does not lock onto a wrong number
of strides. Liftoff angles follow from the touchdown angles by eqs. (7)-(8).

Two extensions, off by default (the paper's fit):
- `heading_weight_m` adds the average heading to the residuals (radians times this length):
  without it the geometry can bend to turn the path where the data drift sideways without
  turning, e.g. under lateral slip;
- `effects` are applied to the model path; the parameters named in `free` are fitted
  together with the geometry (the geometry alone can mimic a sideways drift with a crab-like
  gait; the shape of the average path over a stance tells the two apart).

The fit runs in two stages: first with the stride frequency held at its guess, then with it
free. Freed from the start, the frequency can slide to one stride more or less over a long
run before the angles settle.

The paper fits the deterministic path (every angle at its nominal value) to the average
path. For a nonlinear model with random angles the two differ: the average of the model's
runs is not the run of the average angles, and at Table III's spreads the deterministic fit
misplaces the touchdown angles by up to 1.3 deg (benchmarks/bench_nominal_fit.py).
`fit_nominal(mean=...)` fits the mean of simulated runs instead at given spreads (common
random numbers, so the mean is a smooth function of the geometry): the fit is then unbiased
for the stochastic model.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

import numpy as np
from scipy import optimize

from octoroach_model.errors import DataError
from octoroach_model.model import check_effects, model_poses, ModelParameters, RandomStreams
from octoroach_model.model.kinematics import integrate_stances
from octoroach_model.paths import Paths
from octoroach_model.validation.gait import (
    aligned_runs, stride_frequency_estimate, sway_features)

LOWER = [0.003, 0.05, 0.05, 0.05, 0.05, 0.2]
UPPER = [0.08, 1.45, 1.45, 1.45, 1.45, 20.0]
X_SCALE = [0.005, 0.1, 0.1, 0.1, 0.1, 0.1]


@dataclass(frozen=True)
class FreeEffect:
    """An effect parameter fitted together with the geometry, within [lower, upper]."""

    cause: str
    parameter: str
    lower: float
    upper: float
    start: float = 0.0


@dataclass(frozen=True)
class NominalFit:
    """
    Fitted deterministic model and how well it matches the average path.

    `jacobian` is d(residual)/d(vector) at the solution, vector = [l, phi1..phi4, f, free
    effects...] and residuals in cm (the average path, then the weighted heading): with
    `average_runs`, a resampling of the runs moves the solution by about
    -pinv(jacobian) @ d(residual), which gives intervals without refitting.
    """

    parameters: ModelParameters
    start_pose: tuple[float, float, float]
    rms_error_m: float
    average_path: np.ndarray     # (T, 2) the measured average it was fitted to
    effects: dict = field(default_factory=dict)   # effects in the model, incl. fitted ones
    cost: float = 0.0            # least-squares cost at the solution (compares restarts)
    jacobian: np.ndarray | None = None
    free: tuple[FreeEffect, ...] = ()
    heading_weight_m: float = 0.0

    def report(self) -> dict:
        return {**self.parameters.table(),
                'start_pose': {'x_cm': self.start_pose[0] * 100, 'y_cm': self.start_pose[1] * 100,
                               'heading_deg': math.degrees(self.start_pose[2])},
                'rms_error_cm': self.rms_error_m * 100}


@dataclass(frozen=True)
class MeanPathSettings:
    """
    Fit the mean of `runs` simulated runs at `sigmas` (rad), drawn from `seed`.

    With `sway`, the runs' mean sway (heading sway amplitude, sideways sway at f and 2f: what
    one run does within a stride, which an average over runs blurs) is matched to the data's
    as well, each mismatch weighted as a path offset of that size held over the whole run
    (heading through `heading_weight_m`, `sway_weights`).
    """

    sigmas: tuple[float, float]
    runs: int = 200
    seed: int = 0
    sway: SwayTarget | None = None
    scales: ResidualScales | None = None


@dataclass(frozen=True)
class SwayTarget:
    """
    The data's mean sway: heading sway amplitude [rad], sideways sway at f and 2f [m].

    Measured on the runs as recorded (`t`, each run `lengths[i]` samples long): the model's
    runs are simulated on the same grid and cut to the same lengths before they are compared.
    """

    values: tuple[float, float, float]
    t: np.ndarray
    lengths: np.ndarray

    def of_runs(self, runs: np.ndarray, guess_hz: float) -> np.ndarray:
        """Return the (runs, 3) sway of simulated runs on `t`, cut like the data's runs."""
        picks = self.lengths[np.arange(runs.shape[0]) % len(self.lengths)]
        cut = np.arange(len(self.t))[None, :] >= picks[:, None]
        runs = np.where(cut[..., None], np.nan, runs)
        return sway_features(self.t, runs[..., :2], runs[..., 2], guess_hz)


@dataclass(frozen=True)
class ResidualScales:
    """
    Standard errors that make the fit's residuals dimensionless.

    They are those of the average path at each time (G, 2) [m], of the average heading change
    (G,) [rad] and of the mean sway (3,).

    From the data's own run-to-run spread: where the runs scatter widely (late in a run, or
    under a random turning rate), the average is uncertain and a gap there weighs little, so
    the geometry does not bend to follow the chance curvature of an average path.
    """

    path: np.ndarray
    turn: np.ndarray
    sway: np.ndarray


def residual_vector(path_gap: np.ndarray, turn_gap: np.ndarray | None,
                    sway_gap: np.ndarray | None, heading_weight_m: float,
                    scales: ResidualScales | None) -> np.ndarray:
    """
    Return the fit's residuals from model-minus-data gaps.

    In standard errors with `scales`, else in cm (heading through `heading_weight_m`, sway
    through `sway_weights`).
    """
    if scales is not None:
        parts = [(path_gap / scales.path).ravel()]
        if turn_gap is not None:
            parts.append(turn_gap / scales.turn)
        if sway_gap is not None:
            parts.append(sway_gap / scales.sway)
        return np.concatenate(parts)
    parts = [path_gap.ravel()]
    if turn_gap is not None:
        parts.append(turn_gap * heading_weight_m)
    if sway_gap is not None:
        parts.append(sway_gap * sway_weights(heading_weight_m, len(path_gap)))
    return np.concatenate(parts) * 100.0


SWAY_WEIGHT = 5.0


def sway_weights(heading_weight_m: float, samples: int) -> np.ndarray:
    """
    Weigh the sway residuals against the path's.

    A mismatch counts SWAY_WEIGHT times as much as a path offset of its size held over the
    `samples` of the average path (heading through `heading_weight_m`). At weight 1 the path
    outweighs the sway and the fitted angles leave the heading sway several standard errors
    off on robots away from Table II; at 5 it is matched within its error (and the angles
    come closer to the truth).
    """
    return np.array([max(heading_weight_m, 0.0), 1.0, 1.0]) * SWAY_WEIGHT * math.sqrt(samples)


def simulated_runs(parameters: ModelParameters, start_pose, t: np.ndarray,
                   effects: dict | None, settings: MeanPathSettings) -> np.ndarray:
    """
    Simulate the (runs, T, 3) runs of a mean path.

    Common random numbers, drawn in antithetic pairs so that their mean has no random tilt of
    its own.
    """
    return model_poses(parameters, RandomStreams(settings.seed, antithetic=True),
                       settings.runs, t, settings.sigmas[0], settings.sigmas[1], 'stance',
                       effects or {}, None, start_pose)


def deterministic_path(parameters: ModelParameters, start_pose, t: np.ndarray,
                       effects: dict | None = None) -> np.ndarray:
    """(T, 3) pose of the model with every angle at its nominal value."""
    if effects:
        return model_poses(parameters, RandomStreams(0), 1, t, 0.0, 0.0, 'stance', effects,
                           None, start_pose)[0]
    n_stances = max(1, int(math.ceil(2 * parameters.stride_frequency * t[-1] - 1e-9)))
    angles = np.broadcast_to(parameters.nominal_angles, (1, n_stances, 6))
    phase = 2 * parameters.stride_frequency * t
    return integrate_stances(angles, phase, start_pose, parameters.leg_length,
                             parameters.hip_distance)[0]


def stride_frequency_guess(average_path: np.ndarray, t: np.ndarray, fallback: float) -> float:
    """Half the dominant frequency of the average speed (one speed peak per stance)."""
    if len(t) < 16:
        return fallback
    dt = float(t[1] - t[0])
    speed = np.hypot(*np.gradient(average_path, dt, axis=0).T)
    spectrum = np.abs(np.fft.rfft((speed - speed.mean()) * np.hanning(len(speed))))
    freqs = np.fft.rfftfreq(len(speed), dt)
    usable = freqs > 0.4
    if not usable.any() or spectrum[usable].max() <= 0:
        return fallback
    return float(freqs[usable][np.argmax(spectrum[usable])] / 2.0)


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

    t: np.ndarray
    runs_xy: np.ndarray
    runs_turn: np.ndarray
    start_heading: np.ndarray

    @property
    def average(self) -> np.ndarray:
        return _nanmean_rows(self.runs_xy)

    @property
    def turn(self) -> np.ndarray:
        return _nanmean_rows(self.runs_turn)

    def scales(self, sway_per_run: np.ndarray | None = None,
               floor_m: float = 1e-5) -> ResidualScales:
        """
        Return the standard errors of this target's averages (and of `sway_per_run`'s mean).

        Never below `floor_m` (positions; the same in rad for the heading).
        """
        def standard_error(values: np.ndarray) -> np.ndarray:
            count = np.maximum(np.isfinite(values).sum(axis=0), 2)
            with np.errstate(invalid='ignore'):
                spread = np.nanstd(values, axis=0, ddof=1)
            return np.maximum(np.nan_to_num(spread / np.sqrt(count)), floor_m)

        sway = (standard_error(sway_per_run) if sway_per_run is not None
                else np.full(3, floor_m))
        return ResidualScales(standard_error(self.runs_xy), standard_error(self.runs_turn),
                              np.maximum(sway, 1e-12))

    def resampled(self, index: np.ndarray) -> AverageTarget:
        """Return the target of the runs picked by `index` (a bootstrap resample)."""
        return AverageTarget(self.t, self.runs_xy[index], self.runs_turn[index],
                             self.start_heading[index])


def _nanmean_rows(values: np.ndarray) -> np.ndarray:
    with np.errstate(invalid='ignore', divide='ignore'):
        count = np.isfinite(values).sum(axis=0)
        return np.nansum(values, axis=0) / np.maximum(count, 1)


def average_target(measured: Paths, start_pose, guess_hz: float,
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


def fit_nominal(measured: Paths, initial: ModelParameters | None = None, *,
                heading_weight_m: float = 0.0, effects: dict | None = None,
                free: tuple[FreeEffect, ...] = (), multistart: bool = True,
                align_gait: bool = False, mean: MeanPathSettings | None = None,
                start_pose: tuple[float, float, float] | None = None,
                target: AverageTarget | None = None, refine: bool = False,
                tolerance: float = 1e-8) -> NominalFit:
    """
    Solve eq. (9) on the average of `measured`; see the module docstring for the options.

    `multistart` also starts from the spectral guess of the stride frequency; a refit from a
    good `initial` can skip it. `align_gait` fits the average taken on a common gait clock
    (`gait.aligned_runs`), which stride-to-stride frequency spread does not smear.
    `mean` fits the mean of simulated runs instead of the deterministic path (module
    docstring); with `align_gait` the model's own stride-frequency spread is left out of it,
    as the alignment removes the data's. `free` effects are fitted with the geometry, the
    other `effects` held. `target` (from `average_target`) skips recomputing the average.
    `refine` starts from a good `initial` in one stage, every parameter free; `tolerance` is
    the relative change of cost and parameters at which least squares stops.
    """
    if measured.n_paths < 1 or len(measured.t) < 3:
        raise DataError('the nominal fit needs at least one run of three samples')
    if not measured.well_formed:
        raise DataError('the measured runs are not finite inside a run (only the tail of a '
                        'run that ends early may be missing)')
    if initial is None:
        initial = ModelParameters.nominal()
        estimate = stride_frequency_estimate(measured.poses[..., 2], measured.t)
        if math.isfinite(estimate):
            initial = replace(initial, stride_frequency=estimate)
    initial = initial.with_paper_liftoff()
    start_pose = start_pose or mean_start_pose(measured)
    target = target or average_target(measured, start_pose, initial.stride_frequency,
                                      align_gait)
    t, average = target.t, target.average
    if len(t) < 3:
        raise DataError('the runs share fewer than three samples of the gait: too short for '
                        'the nominal fit')
    average_heading = target.turn if heading_weight_m > 0 else None
    fixed_effects = {name: dict(values) for name, values in (effects or {}).items()}
    for item in free:
        fixed_effects.setdefault(item.cause, {})[item.parameter] = float(item.start)

    def build(vector):
        parameters = replace(initial, leg_length=vector[0], touchdown_angles=tuple(vector[1:5]),
                             stride_frequency=vector[5]).with_paper_liftoff()
        model_effects = {name: dict(values) for name, values in fixed_effects.items()}
        for item, value in zip(free, vector[6:]):
            model_effects[item.cause][item.parameter] = float(value)
        return parameters, check_effects(model_effects)

    sway = mean.sway if mean is not None else None
    grid = sway.t if sway is not None else t     # t is a prefix of the recorded grid

    def runs_of(parameters, model_effects):
        if mean is None:
            return deterministic_path(parameters, start_pose, t, model_effects)[None]
        if align_gait:
            model_effects = {name: values for name, values in model_effects.items()
                             if name != 'gait_frequency_variation'}
        return simulated_runs(parameters, start_pose, grid, model_effects, mean)

    def path_of(parameters, model_effects):
        return runs_of(parameters, model_effects)[:, :len(t)].mean(axis=0)

    scales = mean.scales if mean is not None else None
    if scales is not None:
        average_heading = target.turn

    def residuals(vector):
        parameters, model_effects = build(vector)
        runs = runs_of(parameters, model_effects)
        path = runs[:, :len(t)].mean(axis=0)
        turn_gap = (path[:, 2] - start_pose[2] - average_heading
                    if average_heading is not None else None)
        sway_gap = (np.nanmean(sway.of_runs(runs, parameters.stride_frequency), axis=0)
                    - np.asarray(sway.values) if sway is not None else None)
        return residual_vector(path[:, :2] - average, turn_gap, sway_gap, heading_weight_m,
                               scales)

    lower = LOWER + [item.lower for item in free]
    upper = UPPER + [item.upper for item in free]
    x_scale = X_SCALE + [max(0.1, 0.05 * (item.upper - item.lower)) for item in free]
    guesses = {initial.stride_frequency}
    if multistart:
        guesses.add(stride_frequency_guess(average, t, initial.stride_frequency))
    solutions = []
    for frequency in sorted(guesses):
        values = [initial.leg_length, *initial.touchdown_angles,
                  float(np.clip(frequency, LOWER[5] * 1.5, UPPER[5] * 0.95))]
        values += [item.start for item in free]
        start = np.clip(values, lower, upper)
        if refine:
            solution = optimize.least_squares(residuals, start, bounds=(lower, upper),
                                              x_scale=x_scale, ftol=tolerance, xtol=tolerance)
        else:
            solution = _two_stage_least_squares(residuals, start, lower, upper, x_scale,
                                                tolerance)
        solutions.append(solution)
    best = min(solutions, key=lambda candidate: candidate.cost)  # the first of equal costs
    parameters, model_effects = build(best.x)
    path = path_of(parameters, model_effects)
    rms = float(np.sqrt(np.mean(np.sum((path[:, :2] - average) ** 2, axis=1))))
    return NominalFit(parameters, start_pose, rms, average, model_effects, float(best.cost),
                      np.asarray(best.jac), tuple(free), heading_weight_m)


def _two_stage_least_squares(residuals, start, lower, upper, x_scale, tolerance=1e-8):
    """Least squares with the stride frequency (index 5) held first, then released."""
    frequency = start[5]
    free = [i for i in range(len(start)) if i != 5]

    def held(vector):
        full = np.insert(vector, 5, frequency)
        return residuals(full)

    first = optimize.least_squares(held, start[free], bounds=(
        [lower[i] for i in free], [upper[i] for i in free]), x_scale=[x_scale[i] for i in free],
        ftol=tolerance, xtol=tolerance)
    return optimize.least_squares(residuals, np.insert(first.x, 5, frequency),
                                  bounds=(lower, upper), x_scale=x_scale, ftol=tolerance,
                                  xtol=tolerance)
