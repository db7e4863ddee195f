"""
Probabilistic validation (eqs. 13-16) and the search (15) for the widest admissible spread.

The method, its choices and what its guarantee says are in docs/validation.md.

The method does not depend on the model: anything that turns two spreads, a seed and a time
grid into runs (`ModelPlugin`) can be validated. Every evaluation of the search uses the same
seed for the model and the same multisamples, so settings are compared on common random
numbers and the result is reproducible.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import math
from typing import Any, Protocol

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import ParameterError
from octoroach_model.jsonio import fields_jsonable
from octoroach_model.model import check_effects, model_poses, ModelParameters, RandomStreams
from octoroach_model.model.parameters import SIGMA_LIMIT
from octoroach_model.paths import check_paths, Paths
from octoroach_model.settings import (
    check_callable, check_fields, check_record, Progress, setting, shown, unknown_name)
from octoroach_model.validation.multisample import chernoff_sample_size, disjoint_multisamples
from octoroach_model.validation.region import prediction_region, t_multiplier, violations

NOMINAL_MODELS = ('fit', 'table2')   # the nominal model: eq. 9 fitted to the runs, or Table II


class ModelPlugin(Protocol):
    """A stochastic model as the validation sees it."""

    def __call__(self, sigmas: tuple[float, float], seed: np.random.SeedSequence,
                 n_runs: int, t: FloatArray) -> FloatArray:
        """(n_runs, T, 3) poses sampled at t, drawn from `seed` alone."""


@dataclass(frozen=True)
class FourBarModel:
    """The paper's model (optionally extended) as a validation plug-in."""

    parameters: ModelParameters = field(default_factory=ModelParameters.nominal)
    start_pose: tuple[float, float, float] = (0.0, 0.0, math.pi / 2)
    draws: str = 'stance'
    effects: dict[str, dict[str, float]] = field(default_factory=dict)

    def __call__(self, sigmas: tuple[float, float], seed: np.random.SeedSequence,
                 n_runs: int, t: FloatArray) -> FloatArray:
        return model_poses(self.parameters, RandomStreams(seed), n_runs, t, sigmas[0], sigmas[1],
                           self.draws, check_effects(self.effects), None, self.start_pose)


@dataclass(frozen=True)
class ValidationSettings:
    """
    The paper's constants (section V) and the search grid; sigmas in radians.

    Each field's help and range (`settings.setting`) also make the `validate` options and
    the validator node's parameters.

    resolution_m is the narrowest half-width a region may have (the motion capture's
    resolution): without it, runs that all start at one point would make any model fail there.
    """

    rho: float = setting(0.35, 'acceptance level: the largest acceptable probability of '
                         'violation (eq. 15)', low=0.0, high=1.0, open_low=True, open_high=True)
    epsilon: float = setting(0.15, 'accuracy of the estimate of the violation probability '
                             '(eq. 16)', low=0.0, high=1.0, open_low=True, open_high=True)
    delta: float = setting(0.27, 'confidence 1 - delta of the estimate (eq. 16)', low=0.0,
                           high=1.0, open_low=True, open_high=True)
    k: int = setting(11, 'runs per multisample', low=2, high=1000)
    gamma: float = setting(0.95, 'confidence level of the prediction region', low=0.0,
                           high=1.0, open_low=True, open_high=True)
    seed: int = setting(0, 'seed of the multisamples and the model runs (the validator node: '
                        'of its diagnosis too)', low=0)
    sigma1_max: float = setting(0.4, 'largest touchdown spread searched', unit='rad', low=0.0,
                                high=SIGMA_LIMIT, open_low=True, open_high=True)
    sigma2_max: float = setting(0.4, 'largest liftoff spread searched', unit='rad', low=0.0,
                                high=SIGMA_LIMIT, open_low=True, open_high=True)
    grid_points: int = setting(17, 'grid points per spread in the search (15)', low=2, high=101)
    resolution_m: float = setting(1e-4, 'narrowest half-width of a region (the motion '
                                  "capture's resolution)", unit='m', low=0.0, high=0.01)

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def n(self) -> int:
        """Return the number of multisamples, from eq. (16)."""
        return chernoff_sample_size(self.epsilon, self.delta)

    @property
    def runs_needed(self) -> int:
        return self.n * self.k


class Validation:
    """E^_k for one data set: multisamples and their regions, fixed once, reused per sigma."""

    def __init__(self, measured: Paths, settings: ValidationSettings,
                 coordinates: Sequence[int] = (0, 1)) -> None:
        self.measured = measured
        self.settings = settings
        self.coordinates = tuple(coordinates)
        seeds = np.random.SeedSequence(settings.seed).spawn(2)
        self.model_seed = seeds[1]
        groups = disjoint_multisamples(measured.n_paths, settings.n, settings.k,
                                       np.random.default_rng(seeds[0]))
        self.groups = groups
        samples = measured.poses[groups][..., self.coordinates]   # (n, k, T, C)
        self.centre, half_width = prediction_region(samples, settings.gamma)
        # Runs that all start at the same point give a region of zero width there; no
        # instrument resolves that, so the region is never narrower than its resolution.
        self.half_width = np.maximum(half_width, settings.resolution_m)

    def decisions(self, model: ModelPlugin, sigmas: tuple[float, float]) -> FloatArray:
        """(n,) g(xi_i, w_k^(i)): each model run against its own multisample."""
        runs = model(sigmas, self.model_seed, self.settings.n, self.measured.t)
        return violations(runs[..., self.coordinates], self.centre, self.half_width)

    def violation(self, model: ModelPlugin, sigmas: tuple[float, float]) -> float:
        """E^_k(sigma1, sigma2), eq. (14)."""
        return float(self.decisions(model, sigmas).mean())


@dataclass(frozen=True)
class SigmaSearch:
    """Result of problem (15) on a grid."""

    sigma1_grid: FloatArray
    sigma2_grid: FloatArray
    violation_grid: FloatArray     # raw E^_k, (len(sigma1_grid), len(sigma2_grid))
    monotone_grid: FloatArray      # running maximum over smaller sigmas (E grows with sigma)
    sigma1: float
    sigma2: float
    violation: float
    feasible: bool


def search_sigmas(validation: Validation, model: ModelPlugin,
                  progress: Progress | None = None) -> SigmaSearch:
    """
    Largest sigma1 + sigma2 with E^_k <= rho (problem 15), on a grid with CRN.

    E_k grows with the spreads, so the raw estimates are replaced by their running maximum
    over all smaller (sigma1, sigma2): the admissible set is then a staircase and the answer
    on its upper boundary, reproducible for a given seed.
    """
    settings = validation.settings
    sigma1_grid = np.linspace(0.0, settings.sigma1_max, settings.grid_points)
    sigma2_grid = np.linspace(0.0, settings.sigma2_max, settings.grid_points)
    raw = np.empty((len(sigma1_grid), len(sigma2_grid)))
    for i, sigma1 in enumerate(sigma1_grid):
        for j, sigma2 in enumerate(sigma2_grid):
            raw[i, j] = validation.violation(model, (float(sigma1), float(sigma2)))
        if progress:
            progress((i + 1) / len(sigma1_grid), f'sigma search: row {i + 1}/{len(sigma1_grid)}')
    monotone = np.maximum.accumulate(np.maximum.accumulate(raw, axis=0), axis=1)
    feasible = monotone <= settings.rho
    if not feasible.any():
        i, j = 0, 0
    else:
        total = np.add.outer(sigma1_grid, sigma2_grid)
        score = np.where(feasible, total, -np.inf)
        best = np.flatnonzero(score == score.max())
        i, j = np.unravel_index(best[np.argmin(monotone.ravel()[best])], raw.shape)
    return SigmaSearch(sigma1_grid, sigma2_grid, raw, monotone, float(sigma1_grid[i]),
                       float(sigma2_grid[j]), float(raw[i, j]), bool(feasible.any()))


def guarantee_text(violation: float, settings: ValidationSettings) -> str:
    """Say in words what eq. (16) promises about the estimate."""
    low, high = max(0.0, violation - settings.epsilon), min(1.0, violation + settings.epsilon)
    return (f'With probability at least 1 - delta = {1 - settings.delta:.2f} over the draw of '
            f'the n = {settings.n} model runs and multisamples, the true probability of '
            f'violation E_k lies within epsilon = {settings.epsilon} of the estimate '
            f'{violation:.3f}, i.e. in [{low:.3f}, {high:.3f}]; the model is accepted at '
            f'level rho = {settings.rho} when the estimate is at most rho.')


@dataclass(frozen=True)
class ValidationResult:
    """
    The paper's validation of one model against measured runs (JSON: `to_json`).

    `mode` is 'search' (problem 15 over the grid; `grid` holds E^_k at every point) or
    'fixed' (E^_k at the given spreads only). Spreads in radians.
    """

    n: int
    k: int
    rho: float
    epsilon: float
    delta: float
    gamma: float
    seed: int
    paths_available: int
    paths_used: int
    duration_s: float
    samples_per_run: int
    region: str
    mode: str
    sigma1: float
    sigma2: float
    violation: float
    accepted: bool
    guarantee: str
    settings: ValidationSettings
    grid: SearchGrid | None = None
    nominal: Mapping[str, object] | None = None   # the nominal model's table (fit or Table II)
    draws: str = 'stance'
    sources: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()        # what was skipped or repaired in the input

    def to_json(self) -> dict[str, Any]:
        """Give the result as a JSON object (fields in order; `grid` only after a search)."""
        plain = fields_jsonable(self)
        if self.grid is None:
            del plain['grid']
        return plain


@dataclass(frozen=True)
class SearchGrid:
    """E^_k over the search grid: violation[i][j] at (sigma1[i], sigma2[j])."""

    sigma1: tuple[float, ...]
    sigma2: tuple[float, ...]
    violation: tuple[tuple[float, ...], ...]


def validate(measured: Paths, settings: ValidationSettings | None = None,
             model: ModelPlugin | None = None, sigmas: tuple[float, float] | None = None,
             progress: Progress | None = None) -> ValidationResult:
    """
    Validate `model` against measured runs by the paper's method.

    With `sigmas`, only E^_k at those spreads; otherwise the search (15) for the widest
    admissible spreads. `model` defaults to the paper's model at Table II.
    """
    check_paths(measured)
    check_callable('progress', progress)
    check_record('settings', settings, ValidationSettings)
    settings = settings or ValidationSettings()
    model = model or FourBarModel()
    if not callable(model):
        raise ParameterError('model must be a plug-in: a FourBarModel, or a callable (sigmas, '
                             f'seed, n_runs, t) -> poses, got {shown(model)}')
    validation = Validation(measured, settings)
    if sigmas is not None:
        violation = validation.violation(model, sigmas)
        chosen = (float(sigmas[0]), float(sigmas[1]), violation, violation <= settings.rho)
        grid = None
    else:
        search = search_sigmas(validation, model, progress)
        chosen = (search.sigma1, search.sigma2, search.violation, search.feasible)
        grid = SearchGrid(tuple(search.sigma1_grid.tolist()), tuple(search.sigma2_grid.tolist()),
                          tuple(tuple(row) for row in search.violation_grid.tolist()))
    return ValidationResult(
        n=settings.n, k=settings.k, rho=settings.rho, epsilon=settings.epsilon,
        delta=settings.delta, gamma=settings.gamma, seed=settings.seed,
        paths_available=measured.n_paths, paths_used=settings.runs_needed,
        duration_s=float(measured.t[-1]), samples_per_run=len(measured.t),
        region=(f'per sample and coordinate (x, y): mean +- t(k-1) s sqrt(1 + 1/k), '
                f'multiplier {t_multiplier(settings.k, settings.gamma):.3f}, half-width at '
                f'least {settings.resolution_m} m'),
        mode='fixed' if sigmas is not None else 'search',
        sigma1=chosen[0], sigma2=chosen[1], violation=float(chosen[2]),
        accepted=bool(chosen[3]), guarantee=guarantee_text(float(chosen[2]), settings),
        settings=settings, grid=grid)


def common_duration(measured: Paths) -> tuple[Paths, str | None]:
    """
    Keep the runs on the common duration that keeps the most samples.

    The paper compares runs sample by sample, so they need one duration: the duration D
    maximising D x (runs that reach D). Runs ending before D are left out rather than every
    run cut to the shortest; the note says how many and where they ended.
    """
    lengths = measured.lengths
    if lengths.min() == len(measured.t):
        return measured, None
    candidates = np.unique(lengths)
    kept = np.array([length * np.count_nonzero(lengths >= length) for length in candidates])
    best = int(candidates[np.flatnonzero(kept == kept.max())[-1]])
    keep = lengths >= best
    short = np.sort(lengths[~keep])
    chosen = Paths(measured.t[:best], measured.poses[keep, :best], dict(measured.info))
    if not short.size:
        return chosen, None
    dt = float(measured.t[1] - measured.t[0])
    return chosen, (f'{short.size} of {measured.n_paths} runs end before '
                    f'{(best - 1) * dt:.2f} s (between {(short[0] - 1) * dt:.2f} and '
                    f"{(short[-1] - 1) * dt:.2f} s) and were left out of the paper's "
                    f'validation, which compares runs on one duration')


def validate_measured(measured: Paths, settings: ValidationSettings | None = None, *,
                      nominal: str = 'fit', draws: str = 'stance',
                      sigmas: tuple[float, float] | None = None,
                      sources: Sequence[str] = (), progress: Progress | None = None
                      ) -> ValidationResult:
    """
    Run the whole chain a user asks for (CLI `validate`, the validator's ~/validate).

    Check the run count, build the nominal model (eq. 9 fit, or Table II at the measured
    mean start pose), validate, and say where the runs came from and what was repaired.
    """
    from dataclasses import replace

    from octoroach_model.errors import DataError
    from octoroach_model.fitting import fit_nominal, mean_start_pose

    check_record('settings', settings, ValidationSettings)
    settings = settings or ValidationSettings()
    measured, duration_note = common_duration(measured)
    if nominal not in NOMINAL_MODELS:
        raise ParameterError(f"nominal must be 'fit' or 'table2', got "
                             f'{unknown_name(nominal, NOMINAL_MODELS)}')
    if measured.n_paths < settings.runs_needed:
        left_out = f'; {duration_note}' if duration_note else ''
        raise DataError(f'{measured.n_paths} runs are too few: n x k = {settings.n} x '
                        f'{settings.k} needs {settings.runs_needed} runs (lower k, or raise '
                        f'epsilon/delta to lower n){left_out}')
    bound_note = None
    if nominal == 'fit':
        fit = fit_nominal(measured)
        model = FourBarModel(fit.parameters, fit.start_pose, draws)
        table: Mapping[str, object] = fit.report()
        if fit.at_bounds:
            bound_note = (f'the nominal fit (eq. 9) ended on the bound of '
                          f'{", ".join(fit.at_bounds)}: its geometry is the edge of the range, '
                          f'not the robot, and the validation against it says little '
                          f'(docs/validation.md, "Where eq. (9) fails"); --nominal table2 '
                          f'validates Table II instead')
    else:
        model = FourBarModel(ModelParameters.nominal(), mean_start_pose(measured), draws)
        table = {**ModelParameters.nominal().table(), 'source': 'Table II'}
    result = validate(measured, settings, model, sigmas, progress)
    notes = tuple(measured.info.get('notes', ())) + tuple(
        note for note in (duration_note, bound_note) if note)
    return replace(result, nominal=table, draws=draws, sources=tuple(map(str, sources)),
                   notes=notes)
