"""
Runs of the stochastic model (eq. 11, docs/model.md), optionally with effects.

Random numbers come in independent streams spawned from one seed: the angle normals of the
first 2 * cycles stances, the normals of any extra stances a faster gait needs, and one stream
per effect. The same seed therefore gives the same angles whatever sigmas or effects are
asked for: common random numbers for every comparison between settings (docs/model.md,
"Random numbers").
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
import math
import numbers

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import ParameterError
from octoroach_model.limits import MAX_SIMULATED_SAMPLES
from octoroach_model.model.effects import (
    apply_pose_effects, check_effects, Effects, MODEL_TERMS, TIME_WARPS, warped_time,
    worn_angles)
from octoroach_model.model.extensions import (
    Extensions, family_form, family_terms, NormalSource, positions_in_order)
from octoroach_model.model.kinematics import integrate_stances, stance_angles
from octoroach_model.model.parameters import ModelParameters, nominal_sigmas, SIGMA_LIMIT
from octoroach_model.paths import Paths
from octoroach_model.settings import number, shown

DRAWS = ('stance', 'run')
DEFAULT_START_POSE = (0.0, 0.0, math.pi / 2)


class AntitheticNormal:
    """
    Standard normals in mirrored pairs along the first axis (run i + n/2 gets -z of run i).

    Every odd moment of a mean over runs is then exactly zero, so a mean path shows no
    random rotation or drift of its own (variance reduction by antithetic variates).
    """

    def __init__(self, generator: np.random.Generator) -> None:
        self.generator = generator

    def standard_normal(self, size: int | tuple[int, ...]) -> FloatArray:
        shape = (size,) if isinstance(size, int) else tuple(size)
        half = self.generator.standard_normal((-(-shape[0] // 2), *shape[1:]))
        return np.concatenate([half, -half], axis=0)[:shape[0]]


class RandomStreams:
    """
    Independent generators for each random ingredient of a model run, from one seed.

    With `antithetic`, every generator gives its normals in mirrored pairs (AntitheticNormal):
    for means over runs (the nominal fit's mean path), not for runs that stand for data.
    Each generator is made when first drawn from (`NamedStreams`): a geometry fit makes a
    RandomStreams for every evaluation of its residuals, and most runs draw from a few of
    its streams (one per term of the model, besides the angles').
    """

    def __init__(self, seed: int | np.random.SeedSequence | None,
                 antithetic: bool = False) -> None:
        # the children are made from the seed's entropy and spawn key (NamedStreams), not by
        # spawn(), which advances the sequence it is called on: the same seed gives the same
        # streams every time (common random numbers), and child i is the same whatever the
        # count, so streams of later terms leave earlier ones
        sequence = seed if isinstance(seed, np.random.SeedSequence) \
            else np.random.SeedSequence(seed)
        self.seed_entropy = sequence.entropy
        self._stances = NamedStreams(sequence, ('angles', 'extra_stances'), 0, antithetic)
        self.effects: Mapping[str, NormalSource] = NamedStreams(
            sequence, MODEL_TERMS, 2, antithetic)

    @property
    def angles(self) -> NormalSource:
        """Return the stream of the angle normals of the first 2 * cycles stances."""
        return self._stances['angles']

    @property
    def extra_stances(self) -> NormalSource:
        """Return the stream of the normals of stances beyond those (a faster gait)."""
        return self._stances['extra_stances']


class NamedStreams(Mapping[str, NormalSource]):
    """
    Named generators of children of one seed sequence, each made when first asked for.

    The name at `names[k]` draws from child `first + k` of `parent`, the sequence
    `parent.spawn` would give in that place, made when the name is first read (spawning all
    sixteen children at every residual evaluation cost more than the draws of most). A
    generator made later draws what it would have drawn made at once, so the streams are those
    of one seed whenever they are made.
    """

    def __init__(self, parent: np.random.SeedSequence, names: Sequence[str], first: int,
                 antithetic: bool) -> None:
        self._parent = parent
        self._index = {name: first + k for k, name in enumerate(names)}
        self._wrap: Callable[[np.random.Generator], NormalSource] = \
            AntitheticNormal if antithetic else (lambda generator: generator)
        self._made: dict[str, NormalSource] = {}

    def __getitem__(self, name: str) -> NormalSource:
        if name not in self._made:
            parent = self._parent
            child = np.random.SeedSequence(parent.entropy, pool_size=parent.pool_size,
                                           spawn_key=(*parent.spawn_key, self._index[name]))
            self._made[name] = self._wrap(np.random.default_rng(child))
        return self._made[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)


def _count(value: float) -> str:
    """Write a count as people read it: 40 000 000, or 2.51e+11 past a trillion."""
    return f'{int(value):,}'.replace(',', ' ') if value < 1e12 else f'{value:.3g}'


def simulate(n_paths: int, *, seed: int | None = None, sigma1: float | None = None,
             sigma2: float | None = None, cycles: float = 10,
             parameters: ModelParameters | None = None,
             draws: str = 'stance', effects: Effects | None = None,
             start_pose: Sequence[float] = DEFAULT_START_POSE,
             t: FloatArray | None = None, extensions: Extensions | None = None,
             positions: FloatArray | None = None) -> Paths:
    """
    `n_paths` runs of the stochastic model on a common time grid.

    Parameters
    ----------
    n_paths : int
        Number of runs.
    seed : int or None
        Seed of all random draws (None: fresh entropy, recorded in the result's info).
    sigma1, sigma2 : float or None
        Spread (rad) of the touchdown and of the liftoff angles (eq. 11); None means
        Table III as config/table2.yaml gives it (`nominal_sigmas`).
    cycles : float
        Gait cycles per run; sets the time grid unless `t` is given.
    parameters : ModelParameters or None
        Geometry, nominal angles and timing (default Table II from config/table2.yaml,
        `ModelParameters.nominal`).
    draws : {'stance', 'run'}
        'stance' draws new angles at every stance, 'run' once per run.
    effects : dict or None
        {cause: {parameter: value}} from the table of causes (docs/causes.md).
    start_pose : sequence of 3 floats
        x [m], y [m], heading [rad] at t = 0 (before any initial_pose_error).
    t : (T,) array or None
        Sample times in seconds starting at 0; default `parameters.time_grid(cycles)`.
    extensions : dict, sequence of pairs, or None
        Extension families beyond the table of causes, {family: {parameter: value}}
        (docs/extensions.md), e.g. {'run_order_drift': {'parameter': 'stride_frequency',
        'change': -0.15}}; or (family, parameters) pairs.
    positions : (n_paths,) array or None
        Each run's place in the recording, 0 (first) to 1 (last), which the run-order terms
        read; default i / (n_paths - 1): the runs in the order drawn.

    Returns
    -------
    Paths with .t (T,) and .poses (n_paths, T, 3).

    Examples
    --------
    >>> paths = simulate(3, seed=1)
    >>> paths.poses.shape
    (3, 251, 3)

    """
    parameters = parameters or ModelParameters.nominal()
    default_sigma1, default_sigma2 = nominal_sigmas()
    sigma1 = default_sigma1 if sigma1 is None else number('sigma1', sigma1)
    sigma2 = default_sigma2 if sigma2 is None else number('sigma2', sigma2)
    if (isinstance(n_paths, bool) or not isinstance(n_paths, numbers.Real)
            or not (1 <= n_paths < math.inf) or int(n_paths) != n_paths):
        raise ParameterError(f'n_paths must be a positive whole number, got {shown(n_paths)}')
    if isinstance(seed, (bool, float, str)):
        raise ParameterError(f'seed must be a non-negative whole number or None, got '
                             f'{shown(seed)}')
    if not (0 <= sigma1 < SIGMA_LIMIT and 0 <= sigma2 < SIGMA_LIMIT):
        raise ParameterError(f'sigma1, sigma2 must lie in [0, {SIGMA_LIMIT}) rad, '
                             f'got {sigma1}, {sigma2}')
    if draws not in DRAWS:
        raise ParameterError(f'draws must be one of {DRAWS}, got {shown(draws)}')
    cycles = number('cycles', cycles)
    if not (cycles > 0 and math.isfinite(cycles)):
        raise ParameterError(f'cycles must be a positive finite number, got {cycles}')
    checked = check_effects(effects)
    terms = family_terms(extensions)
    checked.update(terms)
    if t is not None:
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or not len(t) or not np.all(np.isfinite(t)):
            raise ParameterError(f't must be a 1-D array of finite sample times, got shape '
                                 f'{t.shape}')
    samples = int(n_paths) * (parameters.samples(cycles) if t is None else len(t))
    if samples > MAX_SIMULATED_SAMPLES:
        raise ParameterError(f'{_count(n_paths)} runs of {_count(samples // int(n_paths))} '
                             f'samples are {_count(samples)} samples, above the '
                             f'{_count(MAX_SIMULATED_SAMPLES)} one call simulates (limits.py): '
                             'simulate fewer or shorter runs, or in batches with seeds of '
                             'their own')
    t = parameters.time_grid(cycles) if t is None else t
    try:
        streams = RandomStreams(seed)
    except (TypeError, ValueError) as error:    # numpy's SeedSequence refused it
        raise ParameterError("seed must be a non-negative whole number (or numpy's seed "
                             f'forms) or None: {error}') from None
    if positions is not None:
        positions = np.asarray(positions, dtype=float)
        if positions.shape != (int(n_paths),) or not np.all((positions >= 0) & (positions <= 1)):
            raise ParameterError(f'positions must be {int(n_paths)} numbers in [0, 1]')
    poses = model_poses(parameters, streams, int(n_paths), t, sigma1, sigma2, draws,
                        checked, cycles, start_pose, positions)
    info = {'model': 'four_bar', 'seed': seed, 'seed_entropy': streams.seed_entropy,
            'sigma1': sigma1, 'sigma2': sigma2, 'draws': draws, 'cycles': cycles,
            'effects': {name: values for name, values in checked.items() if name not in terms},
            'extensions': [dict(zip(('family', 'parameters'), family_form(name, values)))
                           for name, values in terms.items()],
            'parameters': parameters.table()}
    return Paths(t, poses, info)


def model_poses(parameters: ModelParameters, streams: RandomStreams, n_runs: int,
                t: FloatArray, sigma1: float, sigma2: float, draws: str = 'stance',
                effects: Effects | None = None, cycles: float | None = None,
                start_pose: Sequence[float] = DEFAULT_START_POSE,
                positions: FloatArray | None = None) -> FloatArray:
    """
    (n, T, 3) poses; the array-level core of `simulate` (no validation of arguments).

    Parameters
    ----------
    parameters : ModelParameters
        Geometry, nominal angles, timing.
    streams : RandomStreams
        Every draw.
    n_runs : int
        n.
    t : array, shape (T,)
        Sample times, s.
    sigma1, sigma2 : float
        Spreads of the touchdown and liftoff angles, rad.
    draws : {'stance', 'run'}
        New angles at every stance or once per run.
    effects : {name: {parameter: value}} or None
        Checked effects.
    cycles : float or None
        Gait cycles drawn for (default: t's span).
    start_pose : sequence of 3 floats
        x (m), y (m), heading (rad).
    positions : array, shape (n_runs,), or None
        Each run's place in the recording, 0 (first) to 1 (last), read by the run-order
        terms only; default i / (n - 1), the runs in the order drawn.

    Returns
    -------
    array, shape (n_runs, T, 3)
        x (m), y (m), heading (rad).

    """
    effects = effects or {}
    positions = positions_in_order(n_runs) if positions is None else positions
    # one shared (T,) gait clock unless a time warp gives each run its own (n, T)
    clock = warped_time(effects, t, n_runs, streams.effects, positions) \
        if any(name in effects for name in TIME_WARPS) else t
    phase = 2.0 * parameters.stride_frequency * clock
    base_stances = int(math.ceil(2 * (cycles if cycles else t[-1] * parameters.stride_frequency)
                                 - 1e-9))
    n_stances = max(base_stances, int(math.ceil(float(np.max(phase)) - 1e-9)), 1)
    normals = streams.angles.standard_normal((n_runs, max(base_stances, 1), 6))
    if n_stances > normals.shape[1]:
        extra = streams.extra_stances.standard_normal((n_runs, n_stances - normals.shape[1], 6))
        normals = np.concatenate([normals, extra], axis=1)
    if draws == 'run':
        normals = np.broadcast_to(normals[:, :1], normals.shape)
    angles = stance_angles(worn_angles(parameters.nominal_angles, effects, t, positions),
                           normals, sigma1, sigma2)
    poses = integrate_stances(angles, phase, start_pose, parameters.leg_length,
                              parameters.hip_distance)
    if any(name not in TIME_WARPS for name in effects):
        poses = apply_pose_effects(poses, t, effects, streams.effects, positions, phase)
    return poses
