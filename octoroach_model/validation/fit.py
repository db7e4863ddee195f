"""The nominal fit (eq. 9): the deterministic model closest to the average measured path.

Least squares over zeta = [l, phi1..phi4] (the paper's) plus the stride frequency. The model
starts at the measured mean start pose (Table I's means: x, y and the circular mean heading):
fitting it instead would trade a start offset for a better middle, and the confidence region
is narrowest at the start. Liftoff angles follow from the
touchdown angles by eqs. (7)-(8). The stride frequency starts from the spectral peak of the
average forward speed (one speed oscillation per stance, two per cycle), so the fit does not
lock onto a wrong number of strides.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize

from octoroach_model.errors import DataError
from octoroach_model.model import ModelParameters, RandomStreams, check_effects, model_poses
from octoroach_model.model.kinematics import integrate_stances, stance_angles
from octoroach_model.paths import Paths

LOWER = [0.003, 0.05, 0.05, 0.05, 0.05, 0.2]
UPPER = [0.08, 1.45, 1.45, 1.45, 1.45, 20.0]


@dataclass(frozen=True)
class NominalFit:
    """Fitted deterministic model and how well it matches the average path."""

    parameters: ModelParameters
    start_pose: tuple[float, float, float]
    rms_error_m: float
    average_path: np.ndarray     # (T, 2) the measured average it was fitted to

    def report(self) -> dict:
        return {**self.parameters.table(),
                'start_pose': {'x_cm': self.start_pose[0] * 100, 'y_cm': self.start_pose[1] * 100,
                               'heading_deg': math.degrees(self.start_pose[2])},
                'rms_error_cm': self.rms_error_m * 100}


def deterministic_path(parameters: ModelParameters, start_pose, t: np.ndarray) -> np.ndarray:
    """(T, 3) pose of the model with every angle at its nominal value."""
    n_stances = max(1, int(math.ceil(2 * parameters.stride_frequency * t[-1] - 1e-9)))
    angles = np.broadcast_to(parameters.nominal_angles, (1, n_stances, 6))
    phase = 2 * parameters.stride_frequency * t
    return integrate_stances(angles, phase, start_pose, parameters.leg_length,
                             parameters.hip_distance)[0]


def simulated_mean_path(parameters: ModelParameters, start_pose, t: np.ndarray,
                        normals: np.ndarray, sigmas: tuple[float, float]) -> np.ndarray:
    """(T, 2) average position of stochastic runs driven by the given standard normals."""
    n_stances = max(1, int(math.ceil(2 * parameters.stride_frequency * t[-1] - 1e-9)))
    angles = stance_angles(parameters.nominal_angles, normals[:, :n_stances], *sigmas)
    phase = 2 * parameters.stride_frequency * t
    poses = integrate_stances(angles, phase, start_pose, parameters.leg_length,
                              parameters.hip_distance)
    return poses[..., :2].mean(axis=0)


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


def fit_nominal(measured: Paths, initial: ModelParameters | None = None,
                sigmas: tuple[float, float] = (0.0, 0.0), draws: str = 'stance',
                n_simulated: int = 200, seed: int = 0,
                effects: dict | None = None, multistart: bool = True) -> NominalFit:
    """Solve eq. (9) on the average of `measured` (positions x, y).

    With sigmas = (0, 0) this is the paper's fit: the deterministic path against the average
    path. With spreads, the model's side is the average of `n_simulated` stochastic runs on
    common random numbers (simulated moments): the average of a nonlinear model's runs is not
    its nominal path, and fitting the latter biases the angles enough to put early samples
    outside the narrow confidence region.

    `effects` (deterministic ones: lateral_slip, speed_decay) are applied to the model path,
    so an extension's parameter and the geometry are fitted together instead of the geometry
    bending to mimic the effect.
    """
    initial = (initial or ModelParameters.nominal()).with_paper_liftoff()
    if measured.n_paths < 1 or len(measured.t) < 3:
        raise DataError('the nominal fit needs at least one run of three samples')
    t = measured.t
    average = measured.positions.mean(axis=0)
    if not np.isfinite(average).all():
        raise DataError('the average measured path is not finite')
    start_pose = mean_start_pose(measured)

    def build(vector):
        parameters = replace(initial, leg_length=vector[0], touchdown_angles=tuple(vector[1:5]),
                             stride_frequency=vector[5]).with_paper_liftoff()
        return parameters, start_pose

    stochastic = sigmas[0] > 0 or sigmas[1] > 0
    checked_effects = check_effects(effects)
    normals = np.random.default_rng(seed).standard_normal(
        (n_simulated, int(math.ceil(2 * UPPER[5] * t[-1])) + 1, 6)) if stochastic else None
    if stochastic and draws == 'run':
        normals = np.broadcast_to(normals[:, :1], normals.shape)

    def residuals(vector):
        parameters, start = build(vector)
        if stochastic:
            path = simulated_mean_path(parameters, start, t, normals, sigmas)
        elif effects:
            path = model_poses(parameters, RandomStreams(seed), 1, t, 0.0, 0.0, 'stance',
                               checked_effects, None, start)[0, :, :2]
        else:
            path = deterministic_path(parameters, start, t)[:, :2]
        return (path - average).ravel() * 100.0

    guesses = {initial.stride_frequency}
    if multistart:
        guesses.add(stride_frequency_guess(average, t, initial.stride_frequency))
    best = None
    for frequency in sorted(guesses):
        start = np.array([initial.leg_length, *initial.touchdown_angles,
                          np.clip(frequency, 0.3, 19.0)])
        solution = optimize.least_squares(residuals, start, bounds=(LOWER, UPPER),
                                          x_scale=[0.005, 0.1, 0.1, 0.1, 0.1, 0.1])
        if best is None or solution.cost < best.cost:
            best = solution
    parameters, start_pose = build(best.x)
    rms = float(np.sqrt(np.mean((best.fun / 100.0) ** 2) * 2))
    return NominalFit(parameters, tuple(float(v) for v in start_pose), rms, average)


def mean_start_pose(measured: Paths) -> tuple[float, float, float]:
    """Mean first pose of the runs: x, y and the circular mean of the heading."""
    first = measured.poses[:, 0]
    heading = math.atan2(np.sin(first[:, 2]).mean(), np.cos(first[:, 2]).mean())
    return float(first[:, 0].mean()), float(first[:, 1].mean()), float(heading)
