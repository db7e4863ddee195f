"""
The model extensions of the table of causes (docs/causes.md), exactly as defined there.

The terms of the extension families (extensions.py) are applied here too, each at its stage
(the touchdown angles' before the kinematics: `worn_angles`),
so that one effects mapping {term: {parameter: value}} describes any model a diagnosis fits.

Two kinds: time warps act on the gait phase before the kinematics are evaluated
(`gait_frequency_variation`, `speed_decay`); the others transform finished runs
(`persistent_turning`, `lateral_slip`, `initial_pose_error`, `measurement_noise`). Parameter
names and units are the table's (cm, deg where the key says so). Each effect draws its own
random numbers from its own generator, so adding one leaves every other draw unchanged
(common random numbers across models).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
import math

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import ParameterError
from octoroach_model.model.extensions import (
    NormalSource, positions_in_order, TERM_BY_NAME, TERM_NAMES, TermContext)
from octoroach_model.model.trig import cos_sin
from octoroach_model.settings import number, shown, unknown_name

# Canonical order of application; also the order of their random streams.
EFFECT_PARAMETERS: dict[str, tuple[str, ...]] = {
    'gait_frequency_variation': ('relative_std',),
    'speed_decay': ('fraction',),
    'persistent_turning': ('yaw_rate_std_deg_s',),
    'lateral_slip': ('velocity_cm_s',),
    'initial_pose_error': ('heading_std_deg', 'position_std_cm'),
    'measurement_noise': ('position_std_cm',),
}
EFFECT_NAMES = tuple(EFFECT_PARAMETERS)
# every term a model run can carry: the causes, then the extension families' terms
MODEL_TERMS = EFFECT_NAMES + TERM_NAMES
TIME_WARPS = ('gait_frequency_variation', 'speed_decay') + tuple(
    term.name for term in TERM_BY_NAME.values() if term.stage in ('clock', 'stretch'))

# Ranges accepted for each parameter (inclusive), in the parameter's own unit.
PARAMETER_RANGES: dict[str, tuple[float, float]] = {
    'relative_std': (0.0, 0.5),
    'fraction': (-0.9, 0.9),
    'yaw_rate_std_deg_s': (0.0, 90.0),
    'velocity_cm_s': (-50.0, 50.0),
    'heading_std_deg': (0.0, 90.0),
    'position_std_cm': (0.0, 50.0),
}

Effects = Mapping[str, Mapping[str, float]]


def parameter_range(term: str, key: str) -> tuple[float, float]:
    """Return the range (inclusive) a cause's or an extension term's parameter `key` takes."""
    if term in EFFECT_PARAMETERS:
        return PARAMETER_RANGES[key]
    found = TERM_BY_NAME[term]
    return found.ranges[found.parameters.index(key)]


def check_effects(effects: Effects | None) -> dict[str, dict[str, float]]:
    """
    Check an effects mapping {name: {parameter: value}}; return a copy, missing ones 0.

    Names are causes of the table or extension terms (extensions.py, their own defaults).
    """
    if effects is not None and not isinstance(effects, Mapping):
        raise ParameterError('effects must be a mapping {cause: {parameter: value}}, got '
                             f'{shown(effects)}')
    checked: dict[str, dict[str, float]] = {}
    for name, params in (effects or {}).items():
        if name not in TERM_BY_NAME and name not in EFFECT_PARAMETERS:   # named before quoted
            raise ParameterError(f'unknown effect, '
                                 f'{unknown_name(name, (*EFFECT_NAMES, *TERM_BY_NAME))}; '
                                 f'known: {", ".join(EFFECT_NAMES)}')
        if not isinstance(params, Mapping):
            raise ParameterError(f'effect {name}: its parameters must be a mapping '
                                 f'{{parameter: value}}, got {shown(params)}')
        if name in TERM_BY_NAME:
            checked[name] = TERM_BY_NAME[name].checked(params)
            continue
        extra = set(params) - set(EFFECT_PARAMETERS[name])
        if extra:
            raise ParameterError(f'effect {name} has no parameter '
                                 f'{unknown_name(sorted(extra)[0], EFFECT_PARAMETERS[name])}; '
                                 f'it takes {", ".join(EFFECT_PARAMETERS[name])}')
        values = {}
        for key in EFFECT_PARAMETERS[name]:
            value = number(f'{name}.{key}', params.get(key, 0.0))
            low, high = PARAMETER_RANGES[key]
            if not (math.isfinite(value) and low <= value <= high):
                raise ParameterError(f'{name}.{key} = {value} is outside [{low}, {high}]')
            values[key] = value
        checked[name] = values
    return {name: checked[name] for name in MODEL_TERMS if name in checked}


def warped_time(effects: Effects, t: FloatArray, n_runs: int,
                rngs: Mapping[str, NormalSource], positions: FloatArray | None = None
                ) -> FloatArray:
    """
    Give the (n, T) gait clock: the times at which the unwarped model is evaluated.

    speed_decay warps first, then the clock terms of the extensions (change_point: the rates
    multiply), then each run's gait_frequency_variation and run-order stretch scale the
    result: clock = (1 + e) (t - fraction t^2 / (2 T)). `positions` (n,): each run's place in
    the recording (extensions.py).

    Parameters
    ----------
    effects : {name: {parameter: value}}
        Checked effects.
    t : array, shape (T,)
        Sample times, s.
    n_runs : int
        n.
    rngs : {name: NormalSource}
        Each term's stream.
    positions : array, shape (n_runs,), or None
        Places in the recording, 0..1.

    Returns
    -------
    array, shape (n_runs, T)
        Gait clock, s.

    """
    duration = float(t[-1]) if len(t) else 0.0
    context = _context(t, n_runs, positions, duration)
    shared = shared_clock(effects, t, rngs, context)
    clock = np.broadcast_to(shared, (n_runs, len(t))).astype(float)
    if 'gait_frequency_variation' in effects:
        std = effects['gait_frequency_variation']['relative_std']
        stretch = 1.0 + std * rngs['gait_frequency_variation'].standard_normal(n_runs)
        clock = clock * stretch[:, None]
    for name, values in _terms(effects, 'stretch'):
        clock = clock * TERM_BY_NAME[name].function(values, replace(
            context, source=rngs[name]))[:, None]
    return clock


def shared_clock(effects: Effects, t: FloatArray,
                 rngs: Mapping[str, NormalSource] | None = None,
                 context: TermContext | None = None) -> FloatArray:
    """
    Give the (T,) gait clock every run shares: speed_decay's, then the extensions' clock terms.

    What `warped_time` scales run by run (gait_frequency_variation, run-order stretches); on
    its own, where a stride begins and ends in a model whose strides lengthen or shorten over
    the run (the per-stride panels of extensions.png). `rngs` and `context` as warped_time's
    (a clock term draws nothing: None is enough for each).
    """
    duration = float(t[-1]) if len(t) else 0.0

    def decayed(times: FloatArray) -> FloatArray:
        if 'speed_decay' in effects and duration > 0:
            return times - effects['speed_decay']['fraction'] * times ** 2 / (2.0 * duration)
        return times

    context = context or _context(t, 1, None, duration)
    shared = decayed(np.asarray(t, dtype=float))
    for name, values in _terms(effects, 'clock'):
        shared = TERM_BY_NAME[name].function(values, replace(
            context, source=rngs[name] if rngs is not None else None, clock_of=decayed))
    return shared


def worn_angles(nominal_angles: FloatArray, effects: Effects, t: FloatArray,
                positions: FloatArray) -> FloatArray:
    """
    Return the nominal angles eta (6,), or each run's (n, 1, 6) where a touchdown angle drifts.

    The 'angles' stage of the extension terms, applied before the random angles are drawn
    about eta. A drifted touchdown angle moves its pair's liftoff angle as the paper's eqs.
    (7)-(8) move it (liftoff = -the pair's least touchdown angle), from the robot's own
    liftoff angle: a fitted geometry's is eqs. (7)-(8)'s (`ModelParameters.
    with_paper_liftoff`), a table's may not be. `positions`: each run's place, 0..1.
    """
    context = _context(t, len(positions), positions, float(t[-1]))
    offsets = [TERM_BY_NAME[name].function(values, context)
               for name, values in _terms(effects, 'angles')]
    if not offsets:
        return nominal_angles
    touchdown = np.broadcast_to(nominal_angles[:4], (len(positions), 4)).copy()
    touchdown += np.sum(offsets, axis=0)
    liftoff = nominal_angles[4:] + np.minimum(nominal_angles[0:4:2], nominal_angles[1:4:2]) \
        - np.minimum(touchdown[:, 0::2], touchdown[:, 1::2])
    return np.concatenate([touchdown, liftoff], axis=1)[:, None, :]


def _terms(effects: Effects, stage: str) -> list[tuple[str, Mapping[str, float]]]:
    """Return the extension terms of `effects` applied at `stage`, in canonical order."""
    return [(name, effects[name]) for name in TERM_NAMES
            if name in effects and TERM_BY_NAME[name].stage == stage]


def _context(t: FloatArray, n_runs: int, positions: FloatArray | None, duration: float
             ) -> TermContext:
    places = positions_in_order(n_runs) if positions is None else np.asarray(positions, float)
    return TermContext(np.asarray(t, dtype=float), places, duration, None)


def mean_gait_rate(effects: Effects, duration_s: float | None = None) -> float:
    """
    Return the gait clock's mean rate over a run, relative to the model's stride frequency.

    speed_decay's clock runs at 1 - fraction t / T, on average 1 - fraction / 2: the stride
    frequency seen in a run (a spectral peak) is the model's times this. With `duration_s`, a
    change_point counts too: its clock runs at speed_factor from time_s on (the rates
    multiply, so the decay's mean is taken over each part).
    """
    decay = float(effects['speed_decay']['fraction']) if 'speed_decay' in effects else 0.0
    if 'change_point' not in effects or not duration_s:
        return 1.0 - 0.5 * decay
    change = effects['change_point']
    split = min(max(float(change['time_s']) / duration_s, 0.0), 1.0)
    before = split * (1.0 - 0.5 * decay * split)
    after = (1.0 - split) * (1.0 - 0.5 * decay * (1.0 + split))
    return before + float(change['speed_factor']) * after


def apply_pose_effects(poses: FloatArray, t: FloatArray, effects: Effects,
                       rngs: Mapping[str, NormalSource], positions: FloatArray | None = None,
                       phase: FloatArray | None = None) -> FloatArray:
    """
    Apply the non-warp effects to runs, in canonical order. poses: (n, T, 3), SI.

    The extensions' heading perturbations come after persistent_turning (their sum turns
    heading and velocity together), their sideways drifts after lateral_slip. `positions`:
    each run's place in the recording; `phase`: the stance phase (n, T) or (T,).

    Parameters
    ----------
    poses : array, shape (n, T, 3)
        x (m), y (m), heading (rad).
    t : array, shape (T,)
        Sample times, s.
    effects : {name: {parameter: value}}
        Checked effects.
    rngs : {name: NormalSource}
        Each term's stream.
    positions : array, shape (n,), or None
        Places in the recording, 0..1.
    phase : array, shape (n, T) or (T,), or None
        Stance phase.

    Returns
    -------
    array, shape (n, T, 3)
        The poses with the effects, same units: a new array, or `poses` itself where no
        effect moves it (it is never changed).

    """
    given = poses
    n_runs = poses.shape[0]
    duration = float(t[-1]) if len(t) else 0.0
    context = replace(_context(t, n_runs, positions, duration), phase=phase)
    if 'persistent_turning' in effects:
        std = math.radians(effects['persistent_turning']['yaw_rate_std_deg_s'])
        yaw_rate = std * rngs['persistent_turning'].standard_normal(n_runs)
        poses = turn_persistently(poses, t, yaw_rate)
    headings = [TERM_BY_NAME[name].function(values, replace(context, source=rngs[name]))
                for name, values in _terms(effects, 'heading')]
    if headings:
        poses = perturb_heading(poses, np.sum(headings, axis=0))
    if 'lateral_slip' in effects:
        velocity = effects['lateral_slip']['velocity_cm_s'] / 100.0
        poses = slip_sideways(poses, t, velocity)
    for name, values in _terms(effects, 'drift'):
        each_run = TERM_BY_NAME[name].function(values, replace(context, source=rngs[name]))
        poses = slip_sideways(poses, t, each_run[:, None, None])
    if 'initial_pose_error' in effects:
        params = effects['initial_pose_error']
        rng = rngs['initial_pose_error']
        dheading = math.radians(params['heading_std_deg']) * rng.standard_normal(n_runs)
        shift = params['position_std_cm'] / 100.0 * rng.standard_normal((n_runs, 2))
        poses = rotate_about_start(poses, dheading)
        add_to_positions(poses, shift[:, None, :])
    if 'measurement_noise' in effects:
        std = effects['measurement_noise']['position_std_cm'] / 100.0
        if poses is given:      # every effect before gives a new array; noise alone copies
            poses = poses.copy()
        add_to_positions(poses, std * rngs['measurement_noise'].standard_normal(
            poses[..., :2].shape))
    return poses


def add_to_positions(poses: FloatArray, offsets: FloatArray) -> None:
    """
    Add (n, T or 1, 2) `offsets` to the x and y of (n, T, 3) `poses`, in place.

    A coordinate at a time, along whole runs: numpy's inner loop runs along the last axis, so
    on a (..., 2) view of the poses it went two numbers at a time (the same sums, 3-5 times
    slower).
    """
    for channel in (0, 1):
        poses[..., channel] += offsets[..., channel]


def rotate_about_start(poses: FloatArray, dheading: FloatArray) -> FloatArray:
    """
    Rotate each run by its own angle about its first position.

    Parameters
    ----------
    poses : array, shape (n, T, 3)
        x (m), y (m), heading (rad).
    dheading : array, shape (n,)
        Angle of each run, rad.

    Returns
    -------
    array, shape (n, T, 3)

    """
    cos_d, sin_d = (value[:, None] for value in cos_sin(dheading))
    x, y = poses[..., 0], poses[..., 1]
    x0, y0 = x[:, :1], y[:, :1]
    # each coordinate apart (contiguous), no copy of the poses first: the same numbers bit
    # for bit, a quarter faster for 1200 runs of 251 samples (timed once, script not kept)
    rel_x, rel_y = x - x0, y - y0
    out = np.empty_like(poses)
    out[..., 0] = x0 + cos_d * rel_x - sin_d * rel_y
    out[..., 1] = y0 + sin_d * rel_x + cos_d * rel_y
    out[..., 2] = poses[..., 2] + dheading[:, None]
    return out


def turn_persistently(poses: FloatArray, t: FloatArray, yaw_rate: FloatArray) -> FloatArray:
    """
    Turn each run at its rate w: theta + w t, p(0) + integral of R(w s) p_dot(s) ds.

    The integral is a sum over sample steps, each step rotated by w at its midpoint time.

    Parameters
    ----------
    poses : array, shape (n, T, 3)
        x (m), y (m), heading (rad).
    t : array, shape (T,)
        Sample times, s.
    yaw_rate : array, shape (n,)
        w, rad/s.

    Returns
    -------
    array, shape (n, T, 3)

    """
    mid_angle = yaw_rate[:, None] * 0.5 * (t[1:] + t[:-1])[None, :]
    return _turned_steps(poses, mid_angle, poses[..., 2] + yaw_rate[:, None] * t[None, :])


def perturb_heading(poses: FloatArray, perturbation: FloatArray) -> FloatArray:
    """
    Turn each run by a(t): theta + a, p(0) + integral of R(a(s)) p_dot(s) ds.

    `perturbation` (n, T); each sample step is rotated by a at its midpoint (as
    turn_persistently, of which this is the general form).

    Parameters
    ----------
    poses : array, shape (n, T, 3)
        x (m), y (m), heading (rad).
    perturbation : array, shape (n, T)
        a(t), rad.

    Returns
    -------
    array, shape (n, T, 3)

    """
    mid_angle = 0.5 * (perturbation[:, 1:] + perturbation[:, :-1])
    return _turned_steps(poses, mid_angle, poses[..., 2] + perturbation)


def _turned_steps(poses: FloatArray, angle: FloatArray, heading: FloatArray) -> FloatArray:
    """
    Return the runs with each sample step turned by its `angle` (n, T - 1), and `heading`.

    Each position is the first plus the sum of the turned steps before it; x and y are summed
    apart (no (n, T, 2) stack of the steps), the same additions in the same order.
    """
    out = np.empty_like(poses)
    out[..., 2] = heading
    if poses.shape[1] == 0:
        return out
    x, y = poses[..., 0], poses[..., 1]
    step_x, step_y = x[:, 1:] - x[:, :-1], y[:, 1:] - y[:, :-1]
    cos_a, sin_a = cos_sin(angle)
    out[:, 0, :2] = poses[:, 0, :2]
    np.cumsum(cos_a * step_x - sin_a * step_y, axis=1, out=out[:, 1:, 0])
    np.cumsum(sin_a * step_x + cos_a * step_y, axis=1, out=out[:, 1:, 1])
    add_to_positions(out[:, 1:], poses[:, :1, :2])
    return out


def slip_sideways(poses: FloatArray, t: FloatArray, velocity: float | FloatArray
                  ) -> FloatArray:
    """
    Add a sideways drift: p + integral of v r(theta) ds, r = (sin theta, -cos theta).

    The integral follows the trapezoid rule on the sample times; `velocity` is one number or
    one per run, shaped (n, 1, 1).

    Parameters
    ----------
    poses : array, shape (n, T, 3)
        x (m), y (m), heading (rad).
    t : array, shape (T,)
        Sample times, s.
    velocity : float or array, shape (n, 1, 1)
        v, m/s.

    Returns
    -------
    array, shape (n, T, 3)

    """
    cos_h, sin_h = cos_sin(poses[..., 2])
    dt = np.diff(t)[None, :]
    speed = velocity[..., 0] if isinstance(velocity, np.ndarray) else velocity
    out = poses.copy()
    # x and y apart; r's y is -cos, and every step of the sum is exact under a sign change
    out[:, 1:, 0] += np.cumsum(0.5 * (sin_h[:, 1:] + sin_h[:, :-1]) * dt, axis=1) * speed
    out[:, 1:, 1] -= np.cumsum(0.5 * (cos_h[:, 1:] + cos_h[:, :-1]) * dt, axis=1) * speed
    return out
