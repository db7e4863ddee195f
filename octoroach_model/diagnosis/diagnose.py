"""The main job: from measured runs, what the model gets wrong, why, and what fixing it gains.

Method (README, "How the diagnosis decides"):
1. Split the runs at random into a calibration half and a held-out half.
2. Calibrate the baseline on the calibration half: the nominal fit (eq. 9, with the average
   heading in the residuals and the runs on a common gait clock) and one spread scale s,
   (sigma1, sigma2) = s (0.12, 0.15), matched to the within-run variance of the per-cycle
   heading change (simulated moments, common random numbers).
3. Discrepancies: every statistic of `statistics.STATISTICS` on all runs against the
   baseline, with bootstrap errors, as z-scores.
4. Every candidate of `candidates.CANDIDATES` gets its parameter on the calibration half: by
   simulated moments, or, for causes that move the average path, jointly with the geometry;
   then its own spread scale.
5. Each fitted candidate and the baseline are scored on the held-out runs with the log score
   of a Gaussian synthetic likelihood of the run features; the per-run gain over the baseline
   is tested with a one-sided paired t-test at level alpha / (number of candidates).
6. The cause is the significant candidate with the largest gain (at least `min_gain` nats per
   run), or `none`.
7. Detection limits: for each cause, the size at which that test reaches 80 % power on data
   sets of the held-out size simulated with the effect.
8. The paper's validation (search 15) runs for the baseline and for the extended model.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from octoroach_model.diagnosis.candidates import (
    CANDIDATES, Candidate, direct_extra_parameters, read_off_curve)
from octoroach_model.diagnosis.features import INDEX, run_features
from octoroach_model.diagnosis.statistics import (
    STATISTICS, energy_scores, gaussian_log_score, paired_improvement, statistics_with_errors)
from octoroach_model.errors import DataError
from octoroach_model.model import ModelParameters
from octoroach_model.paths import Paths
from octoroach_model.validation import (
    FourBarModel, ValidationSettings, chernoff_sample_size, fit_nominal, validate)
from octoroach_model.validation.fit import mean_start_pose

Progress = Callable[[float, str], None]
SIGMA_DIRECTION = (0.12, 0.15)          # Table III: the spread scale moves along this ray
SCALE_GRID = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)
ENERGY_TIMES = (0.2, 0.4, 0.6, 0.8, 1.0)   # fractions of the run where positions are scored
MIN_RUNS = 40


@dataclass(frozen=True)
class DiagnosisSettings:
    """Knobs of the diagnosis; the defaults are what README's figures use.

    calibration_runs / score_runs: simulated runs per calibration point / per scored model;
    heading_weight_m, baseline_heading_weight_m: weight (m per rad) of the average heading in
    the nominal fits; min_gain: nats per held-out run a cause must gain to be named;
    align_gait: fit the nominal model on the gait-aligned average path.
    """

    seed: int = 0
    alpha: float = 0.01
    calibration_runs: int = 400
    score_runs: int = 1500
    bootstrap: int = 100
    heading_weight_m: float = 0.13
    min_gain: float = 0.1
    align_gait: bool = True
    baseline_heading_weight_m: float = 0.13
    validation: ValidationSettings = field(default_factory=ValidationSettings)
    validate_models: bool = True


@dataclass
class _Context:
    """What every step needs: the data halves, the baseline model and its features."""

    measured: Paths
    train: Paths
    test: Paths
    model: FourBarModel
    sigmas: tuple[float, float]
    reference_heading: float
    stride_frequency: float
    seed: np.random.SeedSequence
    nominal_report: dict = field(default_factory=dict)
    train_features: np.ndarray | None = None

    def simulate(self, effects: dict | None, n_runs: int, sigmas=None,
                 model: FourBarModel | None = None,
                 seed: np.random.SeedSequence | None = None) -> Paths:
        t = self.measured.t
        model = replace(model or self.model, effects=effects or {})
        poses = model(sigmas or self.sigmas, seed or self.seed, n_runs, t)
        return Paths(t, poses)

    def features(self, paths: Paths) -> np.ndarray:
        return run_features(paths, self.stride_frequency, self.reference_heading)


def diagnose(measured: Paths, settings: DiagnosisSettings | None = None,
             progress: Progress | None = None) -> dict:
    """Diagnose `measured` runs; returns the report (CONTRACT.md fields and more)."""
    settings = settings or DiagnosisSettings()
    say = progress or (lambda fraction, message: None)
    started = time.monotonic()
    if measured.n_paths < MIN_RUNS:
        raise DataError(f'the diagnosis needs at least {MIN_RUNS} runs, got {measured.n_paths}')
    if not np.isfinite(measured.poses).all():
        raise DataError('the measured runs contain non-finite poses')

    say(0.02, 'calibrating the baseline (nominal fit, eq. 9)')
    context = _calibrate_baseline(measured, settings)
    baseline_train = context.features(context.simulate(None, settings.calibration_runs))
    say(0.10, f'baseline spread scale: sigma1 = {context.sigmas[0]:.3f}, '
              f'sigma2 = {context.sigmas[1]:.3f} rad')

    rng = np.random.default_rng(settings.seed)
    data_features = context.features(measured)
    discrepancies = _discrepancies(context, data_features, rng, settings)
    say(0.20, 'discrepancies measured')

    train_features = context.train_features
    test_features = context.features(context.test)
    baseline_scores = _scores(context, None, test_features, settings)
    candidates = []
    for number, candidate in enumerate(CANDIDATES):
        candidates.append(_evaluate(candidate, context, train_features, baseline_train,
                                    test_features, baseline_scores, settings))
        say(0.20 + 0.45 * (number + 1) / len(CANDIDATES),
            f'candidate {candidate.cause}: gain {candidates[-1]["gain"]:.2f} nats/run, '
            f'p = {candidates[-1]["p_value"]:.2g}')

    threshold = settings.alpha / len(CANDIDATES)
    significant = [c for c in candidates
                   if c['p_value'] < threshold and c['gain'] >= settings.min_gain]
    chosen = max(significant, key=lambda c: c['gain']) if significant else None
    cause = chosen['cause'] if chosen else 'none'
    parameters = chosen['parameters'] if chosen else {}
    extended_effects = {cause: parameters} if chosen else {}
    extended_model = chosen['_model'] if chosen else context.model
    extended_sigmas = (chosen['sigma1'], chosen['sigma2']) if chosen else context.sigmas
    extended_scores = _scores(context, extended_effects, test_features, settings,
                              extended_model, extended_sigmas)
    for candidate in candidates:
        del candidate['_model']

    report = {
        'paths': measured.n_paths,
        'duration_s': float(measured.t[-1]),
        'seed': settings.seed,
        'split': {'calibration': context.train.n_paths, 'held_out': context.test.n_paths},
        'nominal': context.nominal_report,
        'baseline': {'sigma_scale_sigma1': context.sigmas[0],
                     'sigma_scale_sigma2': context.sigmas[1]},
        'extended_sigma_scale': {'sigma1': extended_sigmas[0], 'sigma2': extended_sigmas[1]},
        'discrepancies': discrepancies,
        'candidates': candidates,
        'cause': cause,
        'parameters': parameters,
        'extended': {},
        'gain': {
            'metric': 'held-out log score of the run features under each model '
                      '(Gaussian synthetic likelihood), nats per run, higher is better',
            'baseline': float(baseline_scores['log'].mean()),
            'extended': float(extended_scores['log'].mean()),
            'relative': _relative(baseline_scores['log'].mean(), extended_scores['log'].mean()),
            'energy_score_cm': {
                'metric': 'energy score of positions at 20/40/60/80/100 % of the run on '
                          'held-out runs, cm, lower is better',
                'baseline': float(baseline_scores['energy'].mean()),
                'extended': float(extended_scores['energy'].mean()),
                'relative': _relative(baseline_scores['energy'].mean(),
                                      extended_scores['energy'].mean(), lower_is_better=True)},
        },
        'decision': {'alpha': settings.alpha, 'per_candidate_level': threshold,
                     'min_gain': settings.min_gain,
                     'test': 'one-sided paired t-test of per-run log-score gains, and a gain '
                             'of at least min_gain nats per run'},
    }
    if settings.validate_models:
        say(0.70, "paper's validation of the baseline (search 15)")
        report['baseline'].update(_paper_validation(context, {}, settings))
        say(0.85, "paper's validation of the extended model (search 15)")
        report['extended'] = _paper_validation(context, extended_effects, settings,
                                               extended_model)
        report['extended']['effects'] = extended_effects
    report['_models'] = {'baseline': (context.model, context.sigmas),
                         'extended': (replace(extended_model, effects=extended_effects),
                                      extended_sigmas)}
    report['elapsed_s'] = round(time.monotonic() - started, 2)
    say(1.0, f'cause: {cause}')
    return report


def _calibrate_baseline(measured: Paths, settings: DiagnosisSettings) -> _Context:
    order = np.random.default_rng(settings.seed).permutation(measured.n_paths)
    half = measured.n_paths // 2
    train, test = measured.subset(order[:half]), measured.subset(order[half:])
    nominal = fit_nominal(train, heading_weight_m=settings.baseline_heading_weight_m,
                          align_gait=settings.align_gait)
    start = mean_start_pose(train)
    model = FourBarModel(nominal.parameters, start)
    seed = np.random.SeedSequence([settings.seed, 1])
    context = _Context(measured, train, test, model, SIGMA_DIRECTION, start[2],
                       nominal.parameters.stride_frequency, seed)
    context.nominal_report = nominal.report()
    context.train_features = context.features(train)
    context.sigmas = _calibrate_sigmas(context, model, settings)
    return context


def _calibrate_sigmas(context: _Context, model: FourBarModel,
                      settings: DiagnosisSettings) -> tuple[float, float]:
    """Spread scale s, (sigma1, sigma2) = s (0.12, 0.15), matched to the within-run variance
    of the per-cycle heading change (unmoved by start errors and by a constant turn rate)."""
    target = float(context.train_features[:, INDEX['increment_var']].mean())
    curve = []
    for scale in SCALE_GRID:
        sigmas = (scale * SIGMA_DIRECTION[0], scale * SIGMA_DIRECTION[1])
        simulated = context.features(context.simulate(
            model.effects, settings.calibration_runs // 2, sigmas, model))
        curve.append(simulated[:, INDEX['increment_var']].mean())
    scale = read_off_curve(np.array(SCALE_GRID), np.array(curve), target, signed=False)
    return scale * SIGMA_DIRECTION[0], scale * SIGMA_DIRECTION[1]


def _discrepancies(context: _Context, data_features: np.ndarray, rng: np.random.Generator,
                   settings: DiagnosisSettings) -> list[dict]:
    simulated = context.simulate(None, context.measured.n_paths)
    model_stats = statistics_with_errors(context.features(simulated), simulated,
                                         context.reference_heading, context.stride_frequency,
                                         rng, settings.bootstrap)
    data_stats = statistics_with_errors(data_features, context.measured,
                                        context.reference_heading, context.stride_frequency,
                                        rng, settings.bootstrap)
    rows = []
    for name, (_, unit) in STATISTICS.items():
        data_value, data_error = data_stats[name]
        model_value, model_error = model_stats[name]
        error = math.hypot(data_error, model_error)
        z = (data_value - model_value) / error if error > 0 else 0.0
        rows.append({'statistic': name, 'unit': unit, 'data': data_value, 'model': model_value,
                     'data_se': data_error, 'model_se': model_error, 'z': float(z)})
    rows.sort(key=lambda row: -abs(row['z']))
    return rows


def _scores(context: _Context, effects: dict | None, test_features: np.ndarray,
            settings: DiagnosisSettings, model: FourBarModel | None = None,
            sigmas: tuple[float, float] | None = None) -> dict[str, np.ndarray]:
    simulated = context.simulate(effects, settings.score_runs, sigmas, model)
    features = context.features(simulated)
    log = gaussian_log_score(features, test_features)
    picks = [int(round(f * (len(context.measured.t) - 1))) for f in ENERGY_TIMES]
    model_points = simulated.poses[:, picks, :2].reshape(simulated.n_paths, -1) * 100
    observed = context.test.poses[:, picks, :2].reshape(context.test.n_paths, -1) * 100
    return {'log': log, 'energy': energy_scores(model_points[:500], observed),
            'features': features}


def _evaluate(candidate: Candidate, context: _Context, train_features: np.ndarray,
              baseline_train: np.ndarray, test_features: np.ndarray,
              baseline_scores: dict, settings: DiagnosisSettings) -> dict:
    if candidate.refit_nominal:
        estimate, model, evidence = _estimate_jointly(candidate, context, settings)
    else:
        estimate, evidence = _estimate_by_moments(candidate, context, train_features, settings)
        model = context.model
    extra = direct_extra_parameters(candidate.cause, train_features, baseline_train)
    parameters = {candidate.parameter: round(estimate, 6), **extra}
    effects = {candidate.cause: parameters}
    model = replace(model, effects=effects)
    sigmas = _calibrate_sigmas(context, model, settings)
    scores = _scores(context, effects, test_features, settings, model, sigmas)
    gain, p_value = paired_improvement(scores['log'], baseline_scores['log'])
    limit, power_curve = _detection_limit(candidate, context, settings, baseline_scores)
    evidence['power'] = power_curve
    return {'cause': candidate.cause, 'parameters': parameters, 'gain': gain,
            'p_value': p_value,
            'energy_gain_cm': float(baseline_scores['energy'].mean() - scores['energy'].mean()),
            'statistic': candidate.statistic_name,
            'detectable': {candidate.parameter: limit},
            'nominal': model.parameters.table(),
            'sigma1': sigmas[0], 'sigma2': sigmas[1],
            'estimation': evidence,
            '_model': model}


def _estimate_by_moments(candidate: Candidate, context: _Context, train_features: np.ndarray,
                         settings: DiagnosisSettings) -> tuple[float, dict]:
    """Simulated moments: the statistic over the parameter grid, read off at the data's."""
    grid = np.array(candidate.grid, dtype=float)
    curve = [candidate.statistic(context.features(context.simulate(
        candidate.effects(float(value)), settings.calibration_runs))) for value in grid]
    estimate = read_off_curve(grid, np.array(curve), candidate.statistic(train_features),
                              candidate.signed)
    return estimate, {'method': 'simulated moments', 'grid': grid.tolist(),
                      'statistic_curve': [float(c) for c in curve]}


def _estimate_jointly(candidate: Candidate, context: _Context, settings: DiagnosisSettings
                      ) -> tuple[float, FourBarModel, dict]:
    """Least squares of the geometry and the effect's parameter together (eq. 9 extended):
    the effect moves the average path, which the geometry alone would bend to mimic."""
    bounds = (min(candidate.grid), max(candidate.grid))
    # restarts: from the baseline geometry (which may have bent to mimic the effect) and from
    # Table II, with the effect at zero and at half its range either way; the best fit wins
    starts = [(context.model.parameters, 0.0)] + [
        (replace(ModelParameters.nominal(),
                 stride_frequency=context.model.parameters.stride_frequency), value)
        for value in (0.0, 0.5 * bounds[0], 0.5 * bounds[1]) if bounds[0] <= value <= bounds[1]]
    fits = [fit_nominal(context.train, initial=initial,
                        free_effect=(candidate.cause, candidate.parameter),
                        free_effect_bounds=bounds, free_effect_start=value,
                        heading_weight_m=settings.heading_weight_m, multistart=False,
                        align_gait=settings.align_gait)
            for initial, value in starts]
    fit = min(fits, key=lambda f: f.cost)
    estimate = float(fit.effects[candidate.cause][candidate.parameter])
    model = replace(context.model, parameters=fit.parameters)
    return estimate, model, {'method': 'joint least squares with the geometry (eq. 9)',
                             'rms_error_cm': fit.rms_error_m * 100}


def _detection_limit(candidate: Candidate, context: _Context, settings: DiagnosisSettings,
                     baseline_scores: dict) -> tuple[float | None, dict]:
    """Smallest effect the decision would catch with 80 % power at this data's size.

    For each positive grid value, data sets of the held-out size are simulated with the effect
    and scored exactly as the real held-out runs are; the expected t statistic of the paired
    test is read off against the one-sided quantile at the per-candidate level."""
    from scipy import stats

    n_test = context.test.n_paths
    level = settings.alpha / len(CANDIDATES)
    needed = float(stats.norm.isf(level) + stats.norm.isf(0.2))
    baseline_features = baseline_scores['features']
    values, t_values = [0.0], [0.0]
    for value in sorted(v for v in candidate.grid if v > 0):
        effects = candidate.effects(float(value))
        model_features = context.features(context.simulate(effects, settings.calibration_runs))
        pseudo = context.features(context.simulate(
            effects, n_test, seed=np.random.SeedSequence([settings.seed, 3])))
        gain = gaussian_log_score(model_features, pseudo) \
            - gaussian_log_score(baseline_features, pseudo)
        spread = float(np.std(gain, ddof=1))
        t = float(gain.mean() / spread * math.sqrt(n_test)) if spread > 0 else (
            math.inf if gain.mean() > 0 else 0.0)
        values.append(float(value))
        # a gain below min_gain would not be named however significant: count it as unseen
        t_values.append(t if gain.mean() >= settings.min_gain else min(t, 0.0))
        if t_values[-1] >= needed:
            break
    curve = {'values': values, 't': t_values, 't_needed': needed}
    envelope = np.maximum.accumulate(np.nan_to_num(t_values, posinf=1e9))
    if envelope[-1] < needed:
        return None, curve
    keep = np.concatenate([[True], np.diff(envelope) > 0])
    return float(np.interp(needed, envelope[keep], np.array(values)[keep])), curve


def _paper_validation(context: _Context, effects: dict, settings: DiagnosisSettings,
                      model: FourBarModel | None = None) -> dict:
    validation_settings = settings.validation
    n = chernoff_sample_size(validation_settings.epsilon, validation_settings.delta)
    note = None
    if context.measured.n_paths < validation_settings.runs_needed:
        k = context.measured.n_paths // n
        if k < 2:
            return {'note': f'{context.measured.n_paths} runs: too few for n = {n} '
                            f'multisamples of 2 runs'}
        validation_settings = replace(validation_settings, k=k)
        note = f'k lowered to {k}: {context.measured.n_paths} runs < n x k'
    model = replace(model or context.model, effects=effects)
    result = validate(context.measured, validation_settings, model)
    plain = result.to_json()
    summary = {key: plain[key] for key in ('sigma1', 'sigma2', 'violation', 'n', 'k',
                                           'rho', 'accepted', 'grid')}
    if note:
        summary['note'] = note
    return summary


def _relative(baseline: float, extended: float, lower_is_better: bool = False) -> float:
    change = (baseline - extended) if lower_is_better else (extended - baseline)
    return float(change / abs(baseline)) if baseline else 0.0
