"""The nominal fit (eq. 9): the deterministic model closest to the average measured path.

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
- `effects` (deterministic ones: lateral_slip, speed_decay) are applied to the model path;
  with `free_effect` = (cause, parameter) that parameter is fitted together with the geometry
  (the geometry alone can mimic a sideways drift with a crab-like gait; the shape of the
  average path over a stance tells the two apart).

The fit runs in two stages: first with the stride frequency held at its guess, then with it
free. Freed from the start, the frequency can slide to one stride more or less over a long
run before the angles settle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize

from octoroach_model.errors import DataError
from octoroach_model.model import ModelParameters, RandomStreams, check_effects, model_poses
from octoroach_model.model.kinematics import integrate_stances
from octoroach_model.paths import Paths
from octoroach_model.validation.gait import gait_aligned_average

LOWER = [0.003, 0.05, 0.05, 0.05, 0.05, 0.2]
UPPER = [0.08, 1.45, 1.45, 1.45, 1.45, 20.0]
X_SCALE = [0.005, 0.1, 0.1, 0.1, 0.1, 0.1]


@dataclass(frozen=True)
class NominalFit:
    """Fitted deterministic model and how well it matches the average path."""

    parameters: ModelParameters
    start_pose: tuple[float, float, float]
    rms_error_m: float
    average_path: np.ndarray     # (T, 2) the measured average it was fitted to
    effects: dict = field(default_factory=dict)   # effects in the model, incl. a fitted one
    cost: float = 0.0            # least-squares cost at the solution (compares restarts)

    def report(self) -> dict:
        return {**self.parameters.table(),
                'start_pose': {'x_cm': self.start_pose[0] * 100, 'y_cm': self.start_pose[1] * 100,
                               'heading_deg': math.degrees(self.start_pose[2])},
                'rms_error_cm': self.rms_error_m * 100}


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


def fit_nominal(measured: Paths, initial: ModelParameters | None = None, *,
                heading_weight_m: float = 0.0, effects: dict | None = None,
                free_effect: tuple[str, str] | None = None, free_effect_bounds=(-50.0, 50.0),
                free_effect_start: float = 0.0, multistart: bool = True,
                align_gait: bool = False) -> NominalFit:
    """Solve eq. (9) on the average of `measured`; see the module docstring for the options.

    `multistart` also starts from the spectral guess of the stride frequency; a refit from a
    good `initial` can skip it. `align_gait` fits the average taken on a common gait clock
    (`gait.gait_aligned_average`), which stride-to-stride frequency spread does not smear.
    """
    initial = (initial or ModelParameters.nominal()).with_paper_liftoff()
    if measured.n_paths < 1 or len(measured.t) < 3:
        raise DataError('the nominal fit needs at least one run of three samples')
    if not np.isfinite(measured.poses).all():
        raise DataError('the measured runs are not finite')
    start_pose = mean_start_pose(measured)
    if align_gait:
        t, average, turn, _ = gait_aligned_average(measured, initial.stride_frequency)
    else:
        t = measured.t
        average = measured.positions.mean(axis=0)
        # mean heading change since the mean start heading (wrap-safe: runs are unwrapped)
        turn = np.angle(np.exp(1j * (measured.poses[..., 2] - start_pose[2]))).mean(axis=0)
    average_heading = turn if heading_weight_m > 0 else None
    fixed_effects = {name: dict(values) for name, values in (effects or {}).items()}
    if free_effect:
        fixed_effects.setdefault(free_effect[0], {})[free_effect[1]] = float(free_effect_start)

    def build(vector):
        parameters = replace(initial, leg_length=vector[0], touchdown_angles=tuple(vector[1:5]),
                             stride_frequency=vector[5]).with_paper_liftoff()
        model_effects = fixed_effects
        if free_effect:
            model_effects = {**fixed_effects, free_effect[0]: {
                **fixed_effects[free_effect[0]], free_effect[1]: float(vector[6])}}
        return parameters, check_effects(model_effects)

    def residuals(vector):
        parameters, model_effects = build(vector)
        path = deterministic_path(parameters, start_pose, t, model_effects)
        parts = [(path[:, :2] - average).ravel()]
        if average_heading is not None:
            parts.append((path[:, 2] - start_pose[2] - average_heading) * heading_weight_m)
        return np.concatenate(parts) * 100.0

    lower, upper, x_scale = list(LOWER), list(UPPER), list(X_SCALE)
    if free_effect:
        lower.append(free_effect_bounds[0])
        upper.append(free_effect_bounds[1])
        x_scale.append(0.1)
    guesses = {initial.stride_frequency}
    if multistart:
        guesses.add(stride_frequency_guess(average, t, initial.stride_frequency))
    best = None
    for frequency in sorted(guesses):
        start = [initial.leg_length, *initial.touchdown_angles,
                 float(np.clip(frequency, LOWER[5] * 1.5, UPPER[5] * 0.95))]
        if free_effect:
            start.append(float(fixed_effects[free_effect[0]][free_effect[1]]))
        start = np.clip(start, lower, upper)
        solution = _two_stage_least_squares(residuals, start, lower, upper, x_scale)
        if best is None or solution.cost < best.cost:
            best = solution
    parameters, model_effects = build(best.x)
    path = deterministic_path(parameters, start_pose, t, model_effects)
    rms = float(np.sqrt(np.mean(np.sum((path[:, :2] - average) ** 2, axis=1))))
    return NominalFit(parameters, start_pose, rms, average, model_effects, float(best.cost))


def _two_stage_least_squares(residuals, start, lower, upper, x_scale):
    """Least squares with the stride frequency (index 5) held first, then released."""
    frequency = start[5]
    free = [i for i in range(len(start)) if i != 5]

    def held(vector):
        full = np.insert(vector, 5, frequency)
        return residuals(full)

    first = optimize.least_squares(held, start[free], bounds=(
        [lower[i] for i in free], [upper[i] for i in free]), x_scale=[x_scale[i] for i in free])
    return optimize.least_squares(residuals, np.insert(first.x, 5, frequency),
                                  bounds=(lower, upper), x_scale=x_scale)
