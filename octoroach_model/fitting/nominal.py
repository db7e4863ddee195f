"""
The nominal fit (eq. 9): the deterministic model closest to the average measured path.

docs/validation.md ("The nominal fit") describes it for users.

Least squares over zeta = [l, phi1..phi4] (the paper's) plus the stride frequency. The model
starts at the measured mean start pose (Table I's means: x, y and the circular mean heading):
fitting it instead would trade a start offset for a better middle, and the confidence region
is narrowest at the start. The stride frequency starts from the spectral peak of the average
forward speed as well as from the initial value, so the fit does not lock onto a wrong number
of strides. Liftoff angles follow from the touchdown angles by eqs. (7)-(8).

Two extensions, off by default (the paper's fit), set in `NominalFitSettings`:
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
`NominalFitSettings(mean=...)` fits the mean of simulated runs instead at given spreads
(common random numbers, so the mean is a smooth function of the geometry): the fit is then
unbiased for the stochastic model.

The pieces: `NominalProblem` is the least-squares problem (the vector, its model, its
residuals, bounds and starts), `solve` runs least squares from one start, `fit_nominal` puts
them together.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
import math

import numpy as np
from scipy import optimize

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import DataError
from octoroach_model.fitting.gait import stride_frequency_estimate
from octoroach_model.fitting.target import (
    average_target, AverageTarget, GaitTarget, mean_start_pose, residual_vector,
    ResidualScales)
from octoroach_model.model import check_effects, model_poses, ModelParameters, RandomStreams
from octoroach_model.model.kinematics import integrate_stances
from octoroach_model.model.parameters import ParameterTable, StartPoseTable
from octoroach_model.paths import check_paths, Paths
from octoroach_model.settings import check_record

VECTOR_NAMES = ('leg_length', 'touchdown_angle_1', 'touchdown_angle_2', 'touchdown_angle_3',
                'touchdown_angle_4', 'stride_frequency')
LOWER = [0.003, 0.05, 0.05, 0.05, 0.05, 0.2]
UPPER = [0.08, 1.45, 1.45, 1.45, 1.45, 20.0]
X_SCALE = [0.005, 0.1, 0.1, 0.1, 0.1, 0.1]
FREQUENCY = 5            # index of the stride frequency in the fit's vector
Effects = dict[str, dict[str, float]]


@dataclass(frozen=True)
class FreeEffect:
    """An effect parameter fitted together with the geometry, within [lower, upper]."""

    cause: str
    parameter: str
    lower: float
    upper: float
    start: float = 0.0


class NominalTable(ParameterTable):
    """A nominal fit as reports print it (`NominalFit.report`)."""

    start_pose: StartPoseTable
    rms_error_cm: float


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
    average_path: FloatArray     # (T, 2) the measured average it was fitted to
    effects: Effects = field(default_factory=dict)   # effects in the model, incl. fitted ones
    cost: float = 0.0            # least-squares cost at the solution (compares restarts)
    jacobian: FloatArray | None = None
    free: tuple[FreeEffect, ...] = ()
    heading_weight_m: float = 0.0
    # the entries of the vector the solution ended on a bound of (VECTOR_NAMES, then the free
    # effects as cause.parameter): the fit found no interior optimum there
    at_bounds: tuple[str, ...] = ()

    def report(self) -> NominalTable:
        return {**self.parameters.table(),
                'start_pose': {'x_cm': self.start_pose[0] * 100, 'y_cm': self.start_pose[1] * 100,
                               'heading_deg': math.degrees(self.start_pose[2])},
                'rms_error_cm': self.rms_error_m * 100}


@dataclass(frozen=True)
class MeanPathSettings:
    """
    Fit the mean of `runs` simulated runs at `sigmas` (rad), drawn from `seed`.

    With `gait`, the runs' mean gait (heading sway amplitude, sideways sway at f and 2f: what
    one run does within a stride, which an average over runs blurs; the stride frequency and
    the heading to travel angle) is matched to the data's as well, in the data's standard
    errors (`scales`, which a gait target needs: its quantities share no unit with the path).
    """

    sigmas: tuple[float, float]
    runs: int = 200
    seed: int = 0
    gait: GaitTarget | None = None
    scales: ResidualScales | None = None

    def __post_init__(self) -> None:
        if self.gait is not None and self.scales is None:
            raise ValueError('a gait target is matched in standard errors: give scales too')


@dataclass(frozen=True)
class NominalFitSettings:
    """
    How the nominal fit runs; the defaults are the paper's fit (module docstring).

    `multistart` also starts from the spectral guess of the stride frequency; a refit from a
    good initial geometry can skip it. `align_gait` fits the average taken on a common gait
    clock (`gait.aligned_runs`), which stride-to-stride frequency spread does not smear.
    `mean` fits the mean of simulated runs instead of the deterministic path; with
    `align_gait` the model's own stride-frequency spread is left out of it, as the alignment
    removes the data's. `free` effects are fitted with the geometry, the other `effects`
    held. `refine` starts from a good initial geometry in one stage, every parameter free;
    `tolerance` is the relative change of cost and parameters at which least squares stops.
    """

    heading_weight_m: float = 0.0
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    free: tuple[FreeEffect, ...] = ()
    multistart: bool = True
    align_gait: bool = False
    mean: MeanPathSettings | None = None
    refine: bool = False
    tolerance: float = 1e-8


def simulated_runs(parameters: ModelParameters, start_pose: tuple[float, float, float],
                   t: FloatArray, effects: Mapping[str, Mapping[str, float]] | None,
                   settings: MeanPathSettings) -> FloatArray:
    """
    Simulate the (runs, T, 3) runs of a mean path.

    Common random numbers, drawn in antithetic pairs so that their mean has no random tilt of
    its own.

    Parameters
    ----------
    parameters : ModelParameters
        The geometry.
    start_pose : tuple of 3 floats
        x (m), y (m), heading (rad).
    t : array, shape (T,)
        s.
    effects : {cause: {parameter: value}} or None
        Effects in the model.
    settings : MeanPathSettings
        Runs, spreads and seed.

    Returns
    -------
    array, shape (settings.runs, T, 3)
        x (m), y (m), heading (rad).

    """
    runs: FloatArray = model_poses(parameters, RandomStreams(settings.seed, antithetic=True),
                                   settings.runs, t, settings.sigmas[0], settings.sigmas[1],
                                   'stance', effects or {}, None, start_pose)
    return runs


def deterministic_path(parameters: ModelParameters, start_pose: tuple[float, float, float],
                       t: FloatArray,
                       effects: Mapping[str, Mapping[str, float]] | None = None) -> FloatArray:
    """
    (T, 3) pose of the model with every angle at its nominal value.

    Parameters
    ----------
    parameters : ModelParameters
        The geometry.
    start_pose : tuple of 3 floats
        x (m), y (m), heading (rad).
    t : array, shape (T,)
        s.
    effects : {cause: {parameter: value}} or None
        Effects in the model.

    """
    if effects:
        path: FloatArray = model_poses(parameters, RandomStreams(0), 1, t, 0.0, 0.0, 'stance',
                                       effects, None, start_pose)[0]
        return path
    n_stances = max(1, int(math.ceil(2 * parameters.stride_frequency * t[-1] - 1e-9)))
    angles = np.broadcast_to(parameters.nominal_angles, (1, n_stances, 6))
    phase = 2 * parameters.stride_frequency * t
    nominal_path: FloatArray = integrate_stances(angles, phase, start_pose, parameters.leg_length,
                                                 parameters.hip_distance)[0]
    return nominal_path


def stride_frequency_guess(average_path: FloatArray, t: FloatArray, fallback: float) -> float:
    """
    Half the dominant frequency of the average speed (one speed peak per stance).

    Parameters
    ----------
    average_path : array, shape (G, 2)
        m.
    t : array, shape (G,)
        s.
    fallback : float
        Hz, where no peak is found.

    """
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


def check_measured(measured: Paths) -> None:
    """Refuse runs the nominal fit cannot use (DataError, with what is missing)."""
    check_paths(measured)
    if measured.n_paths < 1 or len(measured.t) < 3:
        raise DataError('the nominal fit needs at least one run of three samples')
    if not measured.well_formed:
        raise DataError('the measured runs are not finite inside a run (only the tail of a '
                        'run that ends early may be missing)')


def initial_geometry(measured: Paths, initial: ModelParameters | None) -> ModelParameters:
    """Return where the fit starts: `initial`, else Table II at the runs' stride frequency."""
    if initial is None:
        initial = ModelParameters.nominal()
        estimate = stride_frequency_estimate(measured.poses[..., 2], measured.t)
        if math.isfinite(estimate):
            initial = replace(initial, stride_frequency=estimate)
    return initial.with_paper_liftoff()


@dataclass(frozen=True)
class NominalProblem:
    """
    The least-squares problem of the nominal fit: vector -> model -> residuals.

    The vector is [l, phi1..phi4, f, free effects...]; `held` are the effects in the model
    with the free ones at their starts; `average` (G, 2) and `average_heading` (G,) (None
    when the heading is not matched) are the target's.
    """

    initial: ModelParameters
    start_pose: tuple[float, float, float]
    t: FloatArray
    average: FloatArray
    average_heading: FloatArray | None
    held: Effects
    settings: NominalFitSettings

    @classmethod
    def of(cls, initial: ModelParameters, start_pose: tuple[float, float, float],
           target: AverageTarget, settings: NominalFitSettings) -> NominalProblem:
        t, average = target.t, target.average
        if len(t) < 3:
            raise DataError('the runs share fewer than three samples of the gait: too short '
                            'for the nominal fit')
        average_heading = target.turn if settings.heading_weight_m > 0 else None
        held = {name: dict(values) for name, values in settings.effects.items()}
        for item in settings.free:
            held.setdefault(item.cause, {})[item.parameter] = float(item.start)
        if settings.mean is not None and settings.mean.scales is not None:
            average_heading = target.turn
        return cls(initial, start_pose, t, average, average_heading, held, settings)

    def build(self, vector: FloatArray) -> tuple[ModelParameters, Effects]:
        """Return the geometry and the effects that `vector` stands for."""
        parameters = replace(self.initial, leg_length=vector[0],
                             touchdown_angles=tuple(vector[1:5]),
                             stride_frequency=vector[5]).with_paper_liftoff()
        model_effects = {name: dict(values) for name, values in self.held.items()}
        for item, value in zip(self.settings.free, vector[6:]):
            model_effects[item.cause][item.parameter] = float(value)
        return parameters, check_effects(model_effects)

    @property
    def gait(self) -> GaitTarget | None:
        mean = self.settings.mean
        return mean.gait if mean is not None else None

    def runs_of(self, parameters: ModelParameters, model_effects: Effects) -> FloatArray:
        """Return the model's (runs, T', 3) runs: one deterministic, or the simulated ones."""
        mean = self.settings.mean
        if mean is None:
            return deterministic_path(parameters, self.start_pose, self.t, model_effects)[None]
        if self.settings.align_gait:
            model_effects = {name: values for name, values in model_effects.items()
                             if name != 'gait_frequency_variation'}
        gait = self.gait
        grid = gait.t if gait is not None else self.t    # t is a prefix of the recorded grid
        return simulated_runs(parameters, self.start_pose, grid, model_effects, mean)

    def path_of(self, parameters: ModelParameters, model_effects: Effects) -> FloatArray:
        """Return the model's (G, 3) path on the target's times."""
        path: FloatArray = self.runs_of(parameters, model_effects)[:, :len(self.t)].mean(axis=0)
        return path

    def residuals(self, vector: FloatArray) -> FloatArray:
        """Return the residuals of the model that `vector` stands for (residual_vector)."""
        parameters, model_effects = self.build(vector)
        runs = self.runs_of(parameters, model_effects)
        path = runs[:, :len(self.t)].mean(axis=0)
        turn_gap = (path[:, 2] - self.start_pose[2] - self.average_heading
                    if self.average_heading is not None else None)
        gait = self.gait
        gait_gap = (np.nanmean(gait.of_runs(runs, parameters.stride_frequency), axis=0)
                    - np.asarray(gait.values) if gait is not None else None)
        scales = self.settings.mean.scales if self.settings.mean is not None else None
        return residual_vector(path[:, :2] - self.average, turn_gap, gait_gap,
                               self.settings.heading_weight_m, scales)

    def bounds(self) -> tuple[list[float], list[float], list[float]]:
        """Return the vector's lower and upper bounds and its scales."""
        free = self.settings.free
        lower = LOWER + [item.lower for item in free]
        upper = UPPER + [item.upper for item in free]
        x_scale = X_SCALE + [max(0.1, 0.05 * (item.upper - item.lower)) for item in free]
        return lower, upper, x_scale

    def starts(self) -> list[FloatArray]:
        """Return the vectors the fit starts from: one per stride-frequency guess, in order."""
        initial = self.initial
        guesses = {initial.stride_frequency}
        if self.settings.multistart:
            guesses.add(stride_frequency_guess(self.average, self.t, initial.stride_frequency))
        lower, upper, _ = self.bounds()
        starts = []
        for frequency in sorted(guesses):
            values = [initial.leg_length, *initial.touchdown_angles,
                      float(np.clip(frequency, LOWER[5] * 1.5, UPPER[5] * 0.95))]
            values += [item.start for item in self.settings.free]
            starts.append(np.clip(values, lower, upper))
        return starts


def solve(problem: NominalProblem, start: FloatArray) -> optimize.OptimizeResult:
    """
    Run least squares from `start`: in one stage with `refine`, else in two.

    Parameters
    ----------
    problem : NominalProblem
        What is fitted.
    start : array, shape (p,)
        The fit's vector (geometry, frequency, free effects).

    """
    lower, upper, x_scale = problem.bounds()
    tolerance = problem.settings.tolerance
    if problem.settings.refine:
        return optimize.least_squares(problem.residuals, start, bounds=(lower, upper),
                                      x_scale=x_scale, ftol=tolerance, xtol=tolerance)
    return two_stage_least_squares(problem.residuals, start, lower, upper, x_scale, tolerance)


def fit_nominal(measured: Paths, initial: ModelParameters | None = None,
                settings: NominalFitSettings | None = None, *,
                start_pose: tuple[float, float, float] | None = None,
                target: AverageTarget | None = None) -> NominalFit:
    """
    Solve eq. (9) on the average of `measured` (module docstring; `NominalFitSettings`).

    `start_pose` (default: the runs' mean start pose) and `target` (from `average_target`)
    skip recomputing what a caller has already.
    """
    check_record('settings', settings, NominalFitSettings)
    settings = settings or NominalFitSettings()
    check_measured(measured)
    initial = initial_geometry(measured, initial)
    start_pose = start_pose or mean_start_pose(measured)
    target = target or average_target(measured, start_pose, initial.stride_frequency,
                                      settings.align_gait)
    problem = NominalProblem.of(initial, start_pose, target, settings)
    solutions = [solve(problem, start) for start in problem.starts()]
    best = min(solutions, key=lambda candidate: candidate.cost)  # the first of equal costs
    parameters, model_effects = problem.build(best.x)
    path = problem.path_of(parameters, model_effects)
    rms = float(np.sqrt(np.mean(np.sum((path[:, :2] - problem.average) ** 2, axis=1))))
    return NominalFit(parameters, start_pose, rms, problem.average, model_effects,
                      float(best.cost), np.asarray(best.jac), tuple(settings.free),
                      settings.heading_weight_m, on_bounds(problem, best.x))


# a solution within this share of an entry's range of a bound is on it
ON_BOUND_SHARE = 1e-6


def on_bounds(problem: NominalProblem, vector: FloatArray) -> tuple[str, ...]:
    """Return the names of the entries of `vector` that lie on a bound of `problem`'s."""
    lower, upper, _ = problem.bounds()
    names = VECTOR_NAMES + tuple(f'{item.cause}.{item.parameter}'
                                 for item in problem.settings.free)
    return tuple(name for name, value, low, high in zip(names, vector, lower, upper)
                 if min(value - low, high - value) <= ON_BOUND_SHARE * (high - low))


def two_stage_least_squares(residuals: Callable[[FloatArray], FloatArray], start: FloatArray,
                            lower: Sequence[float], upper: Sequence[float],
                            x_scale: Sequence[float], tolerance: float = 1e-8
                            ) -> optimize.OptimizeResult:
    """
    Least squares with the stride frequency (index FREQUENCY) held first, then released.

    Parameters
    ----------
    residuals : function of an array of shape (p,)
        Returns the residual vector.
    start : array, shape (p,)
        Where the search starts.
    lower, upper, x_scale : sequences of p floats
        Bounds and scales of the vector's entries.
    tolerance : float
        ftol and xtol of least_squares.

    """
    frequency = start[FREQUENCY]
    free = [i for i in range(len(start)) if i != FREQUENCY]

    def held(vector: FloatArray) -> FloatArray:
        full = np.insert(vector, FREQUENCY, frequency)
        return residuals(full)

    first = optimize.least_squares(held, start[free], bounds=(
        [lower[i] for i in free], [upper[i] for i in free]), x_scale=[x_scale[i] for i in free],
        ftol=tolerance, xtol=tolerance)
    return optimize.least_squares(residuals, np.insert(first.x, FREQUENCY, frequency),
                                  bounds=(lower, upper), x_scale=x_scale, ftol=tolerance,
                                  xtol=tolerance)
