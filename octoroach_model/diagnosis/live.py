"""
One question decided again as every run arrives: is the term there, how many runs to go.

The validator's live guidance (nodes/validator.py) and the plan's checks (studies/plan.py)
ask one question of the runs: is the term C (a cause of the table or an extension term) there,
with a size that matters, and how many runs does it take to name it at the size S a lab cares
about? A full diagnosis answers far more, in seconds to minutes; the question needs only
C's own step of it, which this module takes as the diagnosis takes its first step
(diagnose.evaluate_candidate), with three changes that make it cheap and safe to repeat:

1. **Nested halves.** Each run goes to the calibration or the held-out half by a hash of its
   start time (its index where it has none), so a run keeps its half as more arrive and each
   half only grows (`calibration_mask`).
2. **A held baseline.** The paper's model is fitted on the calibration half (as `diagnose`
   does, its start pose, stride frequency and wobble frequency with it: the ruler every run
   is measured with) when the question is first asked and again whenever the calibration
   half has doubled since (`REFIT_GROWTH`); in between, each look extends the held baseline
   by C alone, as the first step of the forward selection does. `fit_held` is a plain
   function a process pool can run while looks go on with the previous baseline.
3. **Boundaries that hold over every look.** C is named at a look when the lower confidence
   bound of its size clears the floor *and* its held-out gain is significant, as in the
   diagnosis, but each against the anytime-valid boundary of diagnosis/sequential.py (level
   `decision_alpha` for the bound, `alpha` for the test, one question so no division among
   candidates), so the chance of naming C at some look when it is not there stays below
   `alpha` however often one looks. Once named, C stays named (`named_at_runs`): that look's
   decision is the valid one. The interval reported is the 95 % confidence sequence (it
   holds the size at every look at once).

`runs_needed` is how many more runs the live decision needs to name C at size S with the
question's power: the power model of diagnosis/power.py on the current estimate's errors and
the held baseline's simulated held-out gains, with the live boundaries at each run count and
the calibration; its interval is the calibration's (power.py). With `Levels.fixed` the same
decision is the fixed-sample one (the diagnosis's levels): what a study compares it with, and
what the plan checks its predictions against.
"""
from __future__ import annotations

from concurrent.futures import Executor, Future
from dataclasses import dataclass, field, replace
import math

import numpy as np
import numpy.typing as npt

from octoroach_model.arrays import BoolArray, FloatArray, IntArray
from octoroach_model.diagnosis.causes import (
    BY_NAME, CANDIDATES, EstimateKind, MIXTURE_FRACTION, periodic_limit_hz, RunScale)
from octoroach_model.diagnosis.decide import judge
from octoroach_model.diagnosis.diagnose import (
    check_runs, choose_wobble_hz, DiagnosisSettings, evaluate_candidate, Evaluation,
    fit_baseline, Halves, quick_fit, score_held_out, SCORE_PURPOSE, screen, with_wobble)
from octoroach_model.diagnosis.features import INDEX
from octoroach_model.diagnosis.modelfit import FittedModel, RunData, SizeEstimate
from octoroach_model.diagnosis.power import Calibration, gain_sample, PowerModel
from octoroach_model.diagnosis.scoring import PairedGain, Scores
from octoroach_model.diagnosis.sequential import Boundary, PLANNED_RUNS, two_sided_z
from octoroach_model.errors import DataError, ParameterError
from octoroach_model.fitting import mean_start_pose
from octoroach_model.fitting.gait import stride_frequency_estimate
from octoroach_model.paths import Paths
from octoroach_model.settings import unknown_name

REFIT_GROWTH = 2.0          # the baseline is fitted again when the calibration half doubles
INTERVAL_ALPHA = 0.05       # the confidence sequence holds at every look with 95 %
SPLIT_PURPOSE = 0x5EED      # the hash stream that assigns runs to halves


@dataclass(frozen=True)
class Question:
    """
    What a lab asks: is `term` there, and how many runs name it at `size` with `power`.

    `size` is the main parameter's distance from its value of no effect, in its unit (for
    run_mixture the yaw rate of MIXTURE_FRACTION of the runs, as its limit is stated).
    """

    term: str
    size: float
    power: float = 0.8

    def __post_init__(self) -> None:
        if self.term not in BY_NAME:
            known = [cause.name for cause in CANDIDATES]
            raise ParameterError(f'unknown term, {unknown_name(self.term, known)}; known: '
                                 f'{", ".join(known)}')
        if not (math.isfinite(self.size) and self.size > 0):
            raise ParameterError(f'the size that matters must be positive, got {self.size:g}')
        if not 0 < self.power < 1:
            raise ParameterError(f'power must lie strictly between 0 and 1, got '
                                 f'{self.power:g}')

    @property
    def internal_size(self) -> float:
        """Return the size as the decision weighs it (run_mixture: the spread it adds)."""
        if BY_NAME[self.term].kind == EstimateKind.MIXTURE:
            return self.size * math.sqrt(MIXTURE_FRACTION * (1 - MIXTURE_FRACTION))
        return self.size

    @property
    def parameter(self) -> str:
        return BY_NAME[self.term].parameter


@dataclass(frozen=True)
class Levels:
    """The critical values of the two criteria: the size bound's and the held-out test's."""

    bound: Boundary
    test: Boundary

    @classmethod
    def live(cls, settings: DiagnosisSettings, planned_runs: float = PLANNED_RUNS) -> Levels:
        """Return the anytime-valid levels of one question (module docstring)."""
        return cls(Boundary(settings.decision_alpha, True, planned_runs / 2),
                   Boundary(settings.alpha, True, planned_runs / 2))

    @classmethod
    def fixed(cls, settings: DiagnosisSettings, candidates: int = 1) -> Levels:
        """Return fixed-sample levels, Bonferroni over `candidates` (the diagnosis's: 13)."""
        return cls(Boundary(settings.decision_alpha / candidates, False),
                   Boundary(settings.alpha / candidates, False))


@dataclass
class Held:
    """A baseline fitted on the calibration half, and the ruler it measures runs with."""

    stride_frequency: float
    reference_heading: float
    wobble: tuple[float, tuple[float, float]] | None
    run_scale: RunScale
    model: FittedModel
    calibration_runs: int
    gains: FloatArray | None     # held-out gains at the question's size (power.gain_sample)
    # the baseline's scored runs (features, position points), kept by `baseline_scores`
    scored: tuple[FloatArray, FloatArray] | None = field(default=None, repr=False)


@dataclass(frozen=True)
class Look:
    """What one look at the runs decided (JSON-ready through jsonio)."""

    runs: int
    calibration_runs: int
    held_out_runs: int
    term: str
    parameter: str
    estimate: float
    interval_95: tuple[float, float]        # the confidence sequence (every look at once)
    floor: float
    bound_z: float                          # (lower bound's distance to the floor) in errors
    bound_critical_z: float
    clears_floor: bool
    gain: float                             # held-out log-score gain, nats per run
    test_z: float                           # the gain in standard errors (one-sided)
    test_critical_z: float
    p_value: float
    significant: bool
    named_here: bool
    screened: bool
    power_now: float                        # predicted power at S with the runs so far
    runs_for_power: float | None            # runs in all at which power reaches the target
    runs_for_power_interval: tuple[float | None, float | None]
    baseline_runs: int                      # calibration runs the held baseline was fitted on
    model: PowerModel | None = field(default=None, metadata={'json': False}, repr=False)
    extended: FittedModel | None = field(default=None, metadata={'json': False}, repr=False)


def calibration_mask(measured: Paths, seed: int) -> BoolArray:
    """
    Return which runs belong to the calibration half (True) and which are held out.

    A run's half is a hash of its start time (ns) and `seed`, or of its index where runs have
    no start times: a run keeps its half as more runs arrive, and runs recorded at the same
    time by several robots need not come in a fixed order.
    """
    stamps = measured.info.get('start_stamps_s')
    n = measured.n_paths
    if isinstance(stamps, (list, tuple, np.ndarray)) and len(stamps) == n and all(
            isinstance(s, (int, float, np.number)) and math.isfinite(s) for s in stamps):
        keys = np.rint(np.asarray(stamps, dtype=float) * 1e9).astype(np.int64).view(np.uint64)
    else:
        keys = np.arange(n, dtype=np.uint64)
    mixed = _splitmix64(keys ^ _splitmix64(np.array([seed, SPLIT_PURPOSE], np.uint64))[0])
    in_calibration: BoolArray = (mixed >> np.uint64(63)) == 0
    return in_calibration


def _splitmix64(values: npt.NDArray[np.uint64]) -> npt.NDArray[np.uint64]:
    """SplitMix64's finaliser: a fast hash of 64-bit integers, every bit mixed."""
    with np.errstate(over='ignore'):
        z = values.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def live_halves(measured: Paths, held: Held | None, seed: int) -> Halves:
    """
    Return the runs in their nested halves, measured with the held ruler (if any).

    Only the halves' runs are measured: a look needs `every` for its ruler alone (the
    stride frequency, heading and wobble frequency every run is measured with), and no ideal
    score (data predicting data, which only the report's relative gain uses).
    """
    from octoroach_model.diagnosis.scoring import feature_scales, position_points_cm

    frequency = (held.stride_frequency if held is not None
                 else stride_frequency_estimate(measured.poses[..., 2], measured.t))
    heading = held.reference_heading if held is not None else mean_start_pose(measured)[2]
    positions, _ = measured.recording_positions()
    wobble_hz, wobble_interval = (held.wobble if held is not None and held.wobble
                                  else (None, None))
    mask = calibration_mask(measured, seed)
    if mask.sum() < 3 or (~mask).sum() < 3:
        raise DataError('too few runs in one of the halves to decide')

    def half(index: IntArray) -> RunData:
        return RunData(measured.subset(index), frequency, heading, positions[index],
                       wobble_hz, wobble_interval)
    train, test = half(np.flatnonzero(mask)), half(np.flatnonzero(~mask))
    if held is not None:
        run_scale = held.run_scale
    else:
        duration = float(np.median(measured.lengths - 1)) / measured.rate_hz
        progress = np.concatenate([train.features[:, INDEX['end_progress']],
                                   test.features[:, INDEX['end_progress']]])
        path_length = float(np.nanmedian(np.abs(progress))) or 0.01
        run_scale = RunScale(duration, path_length, 2.0 * frequency * duration)
    nothing = np.empty(0)
    return Halves(half(np.arange(min(3, measured.n_paths))), train, test,
                  feature_scales(train.features),
                  position_points_cm(test.paths.positions, test.lengths),
                  Scores(nothing, nothing), run_scale)


def fit_held(measured: Paths, question: Question, settings: DiagnosisSettings,
             start: FittedModel | None = None, with_power: bool = True,
             fitted: bool = True) -> Held:
    """
    Fit the baseline on the calibration half and measure the question's expected t there.

    As `diagnose` fits it (several starts), or from `start` alone where the geometry is known
    to be near (the plan's checks: the robot simulated), or (`fitted` False) `start` itself
    (the plan's pilots: runs of that very model, where a fit finds it again); `with_power`
    False leaves the expected t out (NaN). A plain function: a process pool runs it while
    looks go on with the previous baseline.
    """
    from octoroach_model.workers import single_threaded
    from octoroach_model.diagnosis.modelfit import fit_causes

    check_runs(measured)
    with single_threaded():
        halves = live_halves(measured, None, settings.seed)
        if start is None:
            baseline = fit_baseline(halves, replace(settings, workers=1)).model
        else:
            begin = replace(start, start_pose=mean_start_pose(halves.train.paths), effects={})
            baseline = fit_causes(halves.train, begin, (), settings.fit()).model \
                if fitted else begin
        wobble = choose_wobble_hz(halves.train, baseline, settings)
        halves = with_wobble(halves, wobble)
        gains = question_gains(halves, baseline, question, settings) if with_power else None
    return Held(halves.every.stride_frequency, halves.every.reference_heading, wobble,
                halves.run_scale, baseline, halves.train.n, gains)


def question_gains(halves: Halves, baseline: FittedModel, question: Question,
                   settings: DiagnosisSettings) -> FloatArray:
    """
    Return the held-out test's gains of runs simulated with the term at the question's size.

    As the detection limit takes it (diagnose._limit): run_mixture at MIXTURE_FRACTION of the
    runs turning, periodic_heading at PERIODIC_LIMIT_PERIODS per run (the runs measured
    there), change_point at half the runs (modelfit.at_size's default time).
    """
    cause = BY_NAME[question.term]
    fitted: dict[str, float] = {}
    if cause.kind == EstimateKind.MIXTURE:
        fitted['fraction'] = MIXTURE_FRACTION
    if cause.name == 'periodic_heading':
        reference = periodic_limit_hz(halves.train.median_duration_s,
                                      halves.train.stride_frequency)
        halves = with_wobble(halves, (reference, (reference, reference)))
        fitted = dict(quick_fit(halves.train, baseline, cause, settings).model.effects[
            cause.name])
    return gain_sample(halves.test, baseline, cause.name, question.internal_size,
                       halves.scales, settings.score_runs, settings.seed, fitted)


def decide(measured: Paths, held: Held, question: Question, settings: DiagnosisSettings,
           levels: Levels, calibration: Calibration | None = None,
           t_values: FloatArray | None = None, warm: FittedModel | None = None) -> Look:
    """
    Decide the question on the runs so far, against the held baseline (module docstring).

    `calibration` (default: the term's, power.Calibration.for_term) shifts the predicted
    power of `runs_needed`; `t_values`, the resampled t statistics of the held baseline's
    gains (PowerModel.t_values) where a look before computed them; `warm`, the extended
    model an earlier look fitted against the same baseline (`evaluate`).
    """
    from octoroach_model.workers import single_threaded

    check_runs(measured)
    cause = BY_NAME[question.term]
    with single_threaded():
        halves = live_halves(measured, held, settings.seed)
        base_scores = baseline_scores(halves, held, settings)
        n_cal, n_test = halves.train.n, halves.test.n
        z_bound, z_test = levels.bound.z(n_cal), levels.test.z(n_test)
        evaluation = evaluate(halves, held.model, base_scores, cause.name,
                              replace(settings, workers=1), z_bound, warm)
    estimate = evaluation.estimates[cause.name]
    floor = cause.floor(halves.run_scale)
    verdict = judge(estimate, floor, z_bound)
    gain = evaluation.gain
    significant = (not evaluation.screened and gain.p_value < levels.test.p(n_test)
                   and gain.mean >= settings.min_gain)
    test_z = (gain.mean / gain.standard_error if gain.standard_error > 0
              else (math.inf if gain.mean > 0 else 0.0))
    model = PowerModel(cause.name, question.internal_size, floor, estimate, n_cal,
                       held.gains if held.gains is not None else np.empty(0), t_values)
    calibration = calibration or Calibration.for_term(cause.name)
    n = measured.n_paths
    power_now, needed = math.nan, [math.inf] * 3
    if held.gains is not None:
        power_now = calibration.power_band(model.power(n, levels.bound.z, levels.test.z))[0]
        shift, (low_shift, high_shift) = calibration.target_shifts(question.power)
        needed = [model.runs_for(question.power, levels.bound.z, levels.test.z, value)
                  for value in (shift, high_shift, low_shift)]
    return Look(
        n, n_cal, n_test, cause.name, cause.parameter, stated_size(cause.name, estimate.size),
        confidence_sequence(estimate, n_cal, levels.bound.planned),
        stated_size(cause.name, floor), _bound_z(estimate, floor), z_bound,
        verdict.clears_floor, gain.mean, test_z, z_test, gain.p_value, significant,
        bool(verdict.clears_floor and significant), evaluation.screened, power_now,
        _finite(needed[0]), (_finite(needed[1]), _finite(needed[2])),
        held.calibration_runs, model, evaluation.model)


def baseline_scores(halves: Halves, held: Held, settings: DiagnosisSettings) -> Scores:
    """
    Score the held-out runs under the held baseline (diagnose.score_held_out).

    Its simulated runs are kept with it while every held-out run is whole: they are then the
    same runs at every look (the same random numbers, nothing cut, and no term of the
    baseline reads a run's place), and only the score against the growing half is new.
    """
    from octoroach_model.diagnosis.modelfit import Simulator
    from octoroach_model.diagnosis.scoring import position_points_cm, score_model

    whole = bool(np.all(halves.test.lengths == len(halves.test.paths.t)))
    kept = held.scored if whole and not held.model.order_dependent else None
    if kept is None:
        paths, positions = Simulator(halves.test, settings.seed).runs(
            held.model, settings.score_runs, SCORE_PURPOSE)
        kept = (halves.every.features_of(paths, positions),
                position_points_cm(paths.positions, paths.lengths))
        if whole and not held.model.order_dependent:
            held.scored = kept
    return score_model(kept[0], kept[1], halves.test.features, halves.test_points_cm,
                       halves.scales, held.model.order_dependent)


def evaluate(halves: Halves, baseline: FittedModel, base_scores: Scores, term: str,
             settings: DiagnosisSettings, z: float, warm: FittedModel | None = None
             ) -> Evaluation:
    """
    Extend the baseline by the term and score it: the diagnosis's step (evaluate_candidate).

    A term fitted with the geometry (path, trend, mixture) starts, given `warm` (the extended
    model of an earlier look on the same baseline), from there alone: the diagnosis's
    second start (touchdown angles made equal, against a geometry bent to mimic the term)
    is what the first look took, and a look goes on from where that one ended. A term the
    diagnosis screens before its refit (`screened_first`: the families, the table's causes
    sized by their moments) is screened here too where its bound is out of reach: the screen
    alone (`screen`), not the diagnosis's whole step, whose refit from all starts a warm look
    would throw away.
    """
    from octoroach_model.diagnosis.modelfit import fit_causes, Simulator

    cause = BY_NAME[term]
    if warm is None or term not in warm.effects or cause.kind == EstimateKind.MOMENTS:
        return evaluate_candidate(halves, baseline, base_scores, term, settings, z)
    screened = screen(halves, baseline, base_scores, term, settings, z)
    if screened is not None:
        return screened
    start = replace(baseline, parameters=warm.parameters,
                    effects={**baseline.effects, term: dict(warm.effects[term])})
    fitted = fit_causes(halves.train, start, (*baseline.causes, term), settings.fit(),
                        geometry=True, rounds=1)
    scores = score_held_out(Simulator(halves.test, settings.seed), fitted.model, halves, settings)
    return Evaluation(term, fitted.model, fitted.estimates, scores,
                      PairedGain.of(scores.log - base_scores.log),
                      float(np.mean(base_scores.energy_cm - scores.energy_cm)))


def pilot_model(measured: Paths, question: Question, settings: DiagnosisSettings,
                start: FittedModel | None = None) -> PowerModel:
    """
    Return the power model of the question from one data set (the plan's pilot).

    The baseline fitted as `fit_held` does (or `start` itself: the model the runs were
    simulated from), the term's first step taken at the diagnosis's
    levels (all candidates in the race); periodic_heading's size is estimated where its limit
    is stated, as diagnose._limit does.
    """
    held = fit_held(measured, question, settings, start, fitted=start is None)
    look = decide(measured, held, question, settings, Levels.fixed(settings, len(CANDIDATES)))
    assert look.model is not None
    if question.term != 'periodic_heading':
        return look.model
    halves = live_halves(measured, held, settings.seed)
    reference = periodic_limit_hz(halves.train.median_duration_s, halves.train.stride_frequency)
    halves = with_wobble(halves, (reference, (reference, reference)))
    quick = quick_fit(halves.train, held.model, BY_NAME[question.term], settings)
    return replace(look.model, estimate=quick.estimates[question.term])


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def stated_size(term: str, size: float) -> float:
    """Return a size as the question states it (run_mixture: the yaw rate of its share)."""
    if BY_NAME[term].kind == EstimateKind.MIXTURE:
        return size / math.sqrt(MIXTURE_FRACTION * (1 - MIXTURE_FRACTION))
    return size


def _bound_z(estimate: SizeEstimate, floor: float) -> float:
    """Return how far the size lies above the floor, in its standard errors."""
    cause = BY_NAME[estimate.cause]
    if cause.kind == EstimateKind.MOMENTS:
        return ((estimate.u - floor ** 2) / estimate.se_u
                if estimate.se_u > 0 and math.isfinite(estimate.se_u) else 0.0)
    distance = abs(estimate.size - cause.null)
    return (distance - floor) / estimate.se if estimate.se > 0 and math.isfinite(
        estimate.se) else 0.0


def confidence_sequence(estimate: SizeEstimate, calibration_runs: int,
                        planned: float) -> tuple[float, float]:
    """
    Return the 95 % confidence sequence of the size at this look.

    Moments sizes on u = size^2 (square-rooted, as their intervals are), the others on the
    size itself; the half-width in standard errors is sequential.two_sided_z.
    """
    cause = BY_NAME[estimate.cause]
    z = two_sided_z(calibration_runs, INTERVAL_ALPHA, planned)
    if cause.kind == EstimateKind.MOMENTS:
        u, se_u = estimate.u, estimate.se_u

        def root(value: float) -> float:
            return math.sqrt(value) if value > 0 else 0.0
        return root(u - z * se_u), root(u + z * se_u)
    low, high = estimate.size - z * estimate.se, estimate.size + z * estimate.se
    return stated_size(cause.name, low), stated_size(cause.name, high)


class LiveDecision:
    """
    The question decided at every look, the baseline fitted again as the runs double.

    `update(measured)` takes the runs so far (all of them, in any order) and returns the
    look, or None while no baseline is fitted yet (with `refits` running the fits apart).
    Without `refits` every fit runs in `update` itself (studies: the same answer every
    time); with an executor, looks go on with the previous baseline while the next is fitted.
    """

    def __init__(self, question: Question, settings: DiagnosisSettings | None = None,
                 levels: Levels | None = None, calibration: Calibration | None = None
                 ) -> None:
        self.question = question
        self.settings = settings or DiagnosisSettings(validate_models=False,
                                                      detection_limits=False, workers=1)
        self.levels = levels or Levels.live(self.settings)
        self.calibration = calibration or Calibration.for_term(question.term)
        self.held: Held | None = None
        self.named_at_runs: int | None = None
        self._pending: Future[Held] | None = None
        self._t_values: FloatArray | None = None    # the held baseline's, computed once
        self._warm: FittedModel | None = None       # the last look's extended model

    def due(self, measured: Paths) -> bool:
        """Return whether the baseline should be fitted (again) for these runs."""
        if self.held is None:
            return True
        calibration = int(calibration_mask(measured, self.settings.seed).sum())
        return calibration >= REFIT_GROWTH * self.held.calibration_runs

    def update(self, measured: Paths, refits: Executor | None = None) -> Look | None:
        """Decide on the runs so far (class docstring); DataError where they cannot be used."""
        if self._pending is not None and self._pending.done():
            pending, self._pending = self._pending, None
            self._take(pending.result())
        if self.due(measured) and self._pending is None:
            if refits is None:
                self._take(fit_held(measured, self.question, self.settings))
            else:
                check_runs(measured)
                self._pending = refits.submit(fit_held, measured, self.question,
                                              self.settings)
        if self.held is None:
            return None
        look = decide(measured, self.held, self.question, self.settings, self.levels,
                      self.calibration, self._t_values, self._warm)
        if look.model is not None and look.model._t_values is not None:
            self._t_values = look.model._t_values
        if look.extended is not None and not look.screened:
            self._warm = look.extended
        if look.named_here and self.named_at_runs is None:
            self.named_at_runs = look.runs
        return look

    def _take(self, held: Held) -> None:
        """Hold a new baseline; what the looks kept for the old one goes."""
        self.held, self._t_values, self._warm = held, None, None

    @property
    def fitting(self) -> bool:
        """Return whether a baseline is being fitted apart."""
        return self._pending is not None

    @property
    def ready(self) -> bool:
        """Return whether a baseline fitted apart waits to be taken up by the next look."""
        return self._pending is not None and self._pending.done()
