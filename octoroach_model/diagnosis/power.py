"""
How the power to name one term grows with the runs, predicted from one data set.

`plan` (studies/plan.py) and the validator's live guidance (diagnosis/live.py) both ask how
many runs it takes to name a term of a given size. The detection limits (limits.py) already
predict, from one data set, the probability that the decision names a term of size s: the
size bound clears the floor (P1, from the data's own standard errors) and the held-out test
is significant (P2, from the gains of runs simulated with the term). Both move with the
number of runs in a known way:

- a size's standard error has a part from the measured runs, which shrinks as one over the
  square root of the calibration runs, and a part from the simulated runs the size is read
  against (a moments line's intercept and slope, a drift's, the mean path's antithetic runs
  of a path cause), which does not shrink: the diagnosis simulates as many runs whatever the
  data (`PowerModel.estimate_at`);
- the held-out test's t is that of the per-run gains of the held-out runs: its power at h
  held-out runs is the share of samples of h simulated gains whose t passes
  (`PowerModel.test_power`; the gains are skewed, so not simply the expected t, which
  grows as the square root of h).

So `PowerModel.power(runs, z_bound, z_test)` is P1 x P2 at any run count, with the decision's
critical values there (the diagnosis's fixed ones, or the live decision's anytime boundary).

**Calibration against simulation.** Whether the prediction holds was measured where it
predicts 80 %: for each term at one size, the pilots of `plan` (studies/plan_model.py)
predicted the runs for 80 % power, and 16 data sets with the term at that size and run count
were simulated and the term's first step taken on each, as the plan's checks take it
(`benchmarks/bench_plan.py --calibrate`; docs/measured.md, "How many runs"). The counts are
`CALIBRATION_COUNTS`, per term. The measured power is modelled as Phi(Phi^-1(predicted) +
shift), bent by a slope (below): a shift on the probit scale per group of terms (the six
causes pooled, each extension family apart; `group_counts`), with a normal prior N(0, 1)
(the predictor is right within two probit units), updated by the group's counts. A
question (a term at a size, on a robot) is not its group's average: its own shift is the
group's plus a deviation of the spread the terms' shifts show about their mean
(`question_sd`: the standard deviation that makes CALIBRATION_COUNTS most likely). So a
question's prior is the group's posterior widened by that spread (`Calibration.for_term`),
and the checks of the caller update the question's own shift (`Calibration.updated`): 16
checks that name the term far less often than predicted move it, where pooled with the
group's 96 data sets they would not (initial_pose_error at 15 deg on 10-cycle runs: 7 of 16
named where 72-79 % was predicted; pooled, the shift stayed at +0.04, -0.22 to 0.31, and the
answer below what the checks showed).

**The slope.** A shift moves the predicted curve; a question's true curve may also rise
with the runs more steeply or more slowly than the pilots' (measured on real questions: about
1.5 times for initial_pose_error at 15 deg, 0.4 for lateral_slip at 0.3 cm/s). So the
measured power where p is predicted is Phi(z80 + shift + slope (Phi^-1(p) - z80)), z80 =
Phi^-1(0.8): the slope bends the curve about the point where the pilots predict 80 %, where
the studies' counts were measured and so say nothing of it. Its prior is ln slope ~ N(0,
SLOPE_SD), 0.5 (a factor of 0.37 to 2.7 at 95 %); the spread that makes the counts of eight
real questions most likely, each at three or four run counts, is 0.41 (likelihood interval
0.12 to 1.04; benchmarks/bench_plan_questions.py). Checks at other predicted powers update
it with the shift. The runs for a power q are
where the predicted power is Phi(z80 + (Phi^-1(q) - z80 - shift) / slope): a flatter curve
puts a given shift further away in the runs, so the answer's interval widens where the slope
is uncertain (`Calibration.target_shifts`). The posteriors' 95 % intervals make an answer's
interval; how often that holds the true run count, through plan's checks, is measured by
benchmarks/bench_plan_calibration.py (a true curve 0.6 times as steep as predicted: 87 %
with the slope, 70 % with the shift alone).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cache, lru_cache
import math

import numpy as np
from scipy import optimize, special, stats

from octoroach_model.arrays import FloatArray, IntArray
from octoroach_model.diagnosis.causes import BY_NAME, EstimateKind
from octoroach_model.diagnosis.decide import POWER
from octoroach_model.diagnosis.limits import bound_power, held_out_gains, limit_base
from octoroach_model.diagnosis.modelfit import FittedModel, RunData, Simulator, SizeEstimate

ZFunction = Callable[[float], float]          # information (runs in a half) -> critical z
MOST_RUNS = 1_000_000                         # runs_for gives up beyond this
# named / checks where the pilots predicted 80 % power, per term at one size (16 data sets
# each at bench_plan.py's CALIBRATION_SIZES, Table II's robot; `.venv/bin/python
# benchmarks/bench_plan.py --calibrate` prints these, 3 min; docs/measured.md, "How many runs");
# measurement_noise and the stride frequency's drift at a size just above their floors,
# where the runs needed are many. Measured with the diagnosis of commit 3d875ec; per group
# they were within two data sets of those measured at 7ccf16b-d03aab6 ('causes' 83/96,
# 'run_order_drift' 34/48, periodic_heading 14/16, the others the same); the touchdown
# angles' drifts, a term per leg, with the diagnosis of commit 2825888 (2026-12-02,
# `--calibrate --terms run_order_drift:touchdown_angle_1 ... _4`: 177, 217, 141 and 203 runs
# predicted for 12, 11, 9 and 14 deg; phi3 had 14/16 at 137 runs on 2026-12-01 too)
CALIBRATION_COUNTS: dict[str, tuple[int, int]] = {
    'initial_pose_error': (16, 16),
    'measurement_noise': (16, 16),
    'gait_frequency_variation': (13, 16),
    'speed_decay': (15, 16),
    'lateral_slip': (11, 16),
    'persistent_turning': (11, 16),
    'run_order_drift:stride_frequency': (12, 16),
    'run_order_drift:yaw_rate': (10, 16),
    'run_order_drift:lateral_velocity': (10, 16),
    'run_order_drift:touchdown_angle_1': (9, 16),
    'run_order_drift:touchdown_angle_2': (13, 16),
    'run_order_drift:touchdown_angle_3': (14, 16),
    'run_order_drift:touchdown_angle_4': (11, 16),
    'heading_random_walk': (15, 16),
    'periodic_heading': (13, 16),
    'change_point': (16, 16),
    'run_mixture': (15, 16),
    'yaw_rate_ramp': (14, 16),
}
GAIN_REPEATS = 2                               # simulations pooled in gain_sample
RESAMPLES = 1000                               # samples of the gains per run count
RESAMPLED_RUNS = 2000                          # beyond: the t taken as normal
RESAMPLE_SEED = 54
PRIOR_SD = 1.0                                 # of the probit shift
SHIFTS = np.linspace(-5.0, 5.0, 2001)          # the grid the shift's posterior is taken on
# the prior's sd of ln slope (the calibration's bend; 0.5: a factor within 0.37-2.7 at 95 %;
# benchmarks/bench_plan_questions.py measured 0.41, likelihood interval 0.12-1.04, over eight
# real questions: 0.5 errs wide, as question_sd does), and its grid in units of that sd
SLOPE_SD = 0.5
LOG_SLOPE_STEPS = np.linspace(-3.0, 3.0, 25)


def calibration_group(term: str) -> str:
    """Return the calibration group of a term: 'causes', or its extension family."""
    return BY_NAME[term].family or 'causes'


def group_counts(group: str) -> tuple[int, int]:
    """Return (named, data sets) of CALIBRATION_COUNTS summed over the group's terms."""
    counts = [value for term, value in CALIBRATION_COUNTS.items()
              if calibration_group(term) == group]
    return sum(named for named, _ in counts), sum(total for _, total in counts)


# the terms' spread of the shift is searched within [0, MOST_QUESTION_SD] (probit units)
# to within QUESTION_SD_TOLERANCE, each term's deviation integrated by Gauss-Hermite
# quadrature on HERMITE_NODES nodes, the mean shift on every MEAN_STEP-th point of SHIFTS
MOST_QUESTION_SD = 2.0
QUESTION_SD_TOLERANCE = 1e-3
HERMITE_NODES = 41
MEAN_STEP = 4


def terms_log_likelihood(spread: float) -> float:
    """
    Return log P(CALIBRATION_COUNTS) with the terms' shifts spread by `spread` (probit).

    Each term's count binomial at Phi(Phi^-1(0.8) + mean + deviation), its deviation
    N(0, spread^2), the mean shift integrated over its N(0, PRIOR_SD) prior (binomial
    coefficients left out: they do not depend on the spread).
    """
    nodes, weights = np.polynomial.hermite_e.hermegauss(HERMITE_NODES)
    means = SHIFTS[::MEAN_STEP]
    probit = special.ndtri(POWER) + means[:, None] + spread * nodes
    total_log = stats.norm.logpdf(means, 0.0, PRIOR_SD)
    for named, total in CALIBRATION_COUNTS.values():
        per_node = count_log_likelihood(named, total, probit)
        total_log = total_log + special.logsumexp(per_node, b=weights / weights.sum(), axis=1)
    return float(special.logsumexp(total_log))


@cache
def question_sd() -> float:
    """
    Return the spread of a question's shift about its group's (module docstring).

    The standard deviation of the terms' shifts that makes CALIBRATION_COUNTS most likely
    (type II maximum likelihood, `terms_log_likelihood`): the terms, each at one size on one
    robot, stand in for questions. Taken about one mean, it holds the groups' differences
    too, so as a question's spread about its group's shift it errs wide.
    """
    best = optimize.minimize_scalar(lambda spread: -terms_log_likelihood(spread),
                                    bounds=(0.0, MOST_QUESTION_SD), method='bounded',
                                    options={'xatol': QUESTION_SD_TOLERANCE})
    return float(best.x)


@dataclass(frozen=True)
class Calibration:
    """
    The probit shift and slope between predicted and measured power (module docstring).

    The measured power where p is predicted is Phi(z80 + shift + slope (Phi^-1(p) - z80)),
    z80 = Phi^-1(0.8): `shift` moves the curve where the pilots predict 80 % (where the
    studies measured it), `slope` bends it about that point (a true curve steeper or
    flatter in the runs than the pilots' one). `log_likelihood` is on the grid SHIFTS x
    `log_slopes` (ln slope; a 1-D one over SHIFTS holds the slope at 1); `sources` says which
    counts it holds.
    """

    log_likelihood: FloatArray = field(repr=False, compare=False)
    sources: tuple[str, ...]
    log_slopes: tuple[float, ...] = (0.0,)

    def __post_init__(self) -> None:
        table = np.asarray(self.log_likelihood, dtype=float).reshape(len(SHIFTS), -1)
        if table.shape[1] != len(self.log_slopes):
            raise ValueError(f'log_likelihood has {table.shape[1]} columns for '
                             f'{len(self.log_slopes)} slopes')
        object.__setattr__(self, 'log_likelihood', table)

    @classmethod
    def for_term(cls, term: str, spread: float | None = None,
                 slope_sd: float | None = None) -> Calibration:
        """
        Return the prior of a question's shift and slope: its group's shift, widened.

        `spread` (probit units) is how far a question's shift may lie from its group's
        (default `question_sd()`; 0 takes the group's shift as the question's); `slope_sd`
        the prior's standard deviation of ln slope (default SLOPE_SD; 0 holds the slope at
        1, the pilots' curve only shifted).
        """
        group = calibration_group(term)
        named, total = group_counts(group)
        spread = question_sd() if spread is None else float(spread)
        slope_sd = SLOPE_SD if slope_sd is None else float(slope_sd)
        prior = stats.norm.logpdf(SHIFTS, 0.0, PRIOR_SD)
        counts = count_log_likelihood(named, total, special.ndtri(POWER) + SHIFTS)
        said = (f'calibration: {group} named in {named} of {total} data sets where 80 % was '
                'predicted' if total else f'calibration: none measured for {group} yet (the '
                'prior alone: the predictor right within two probit units)')
        question = (f'this question: its own shift, within {spread:.2f} probit units (one sd) '
                    "of the group's (the spread of the terms' shifts)")
        shift_log = _widened(prior + counts, spread)
        if slope_sd <= 0:
            return cls(shift_log, (said, question))
        log_slopes = LOG_SLOPE_STEPS * slope_sd
        bend = ("its slope: the pilots' curve steeper or flatter by a factor whose ln has "
                f'sd {slope_sd:.2f}')
        table = shift_log[:, None] + stats.norm.logpdf(log_slopes, 0.0, slope_sd)[None, :]
        return cls(table, (said, question, bend), tuple(float(v) for v in log_slopes))

    def updated(self, predicted: Sequence[float], named: Sequence[bool], what: str
                ) -> Calibration:
        """Return the calibration with outcomes of simulated checks at `predicted` powers."""
        total = np.array(self.log_likelihood)
        for power, outcome in zip(predicted, named):
            total += count_log_likelihood(int(bool(outcome)), 1, self._probits(power))
        return Calibration(total, (*self.sources, what), self.log_slopes)

    def _probits(self, predicted: float) -> FloatArray:
        return measured_probit(predicted, SHIFTS, np.exp(np.asarray(self.log_slopes)))

    def _weights(self) -> FloatArray:
        log_p = self.log_likelihood
        weights = np.exp(log_p - log_p.max())
        posterior: FloatArray = weights / weights.sum()
        return posterior

    def shift_posterior(self) -> FloatArray:
        """Return the shift's marginal posterior on SHIFTS (weights that sum to 1)."""
        marginal: FloatArray = self._weights().sum(axis=1)
        return marginal

    @property
    def shift(self) -> float:
        """Return the posterior median of the shift."""
        return self.quantile(0.5)

    @property
    def interval_95(self) -> tuple[float, float]:
        """Return the shift's equal-tailed 95 % posterior interval."""
        return self.quantile(0.025), self.quantile(0.975)

    def quantile(self, q: float) -> float:
        """Return the shift's posterior quantile `q`."""
        cumulative = np.cumsum(self.shift_posterior())
        return float(np.interp(q, cumulative, SHIFTS))

    @property
    def slope(self) -> float:
        """Return the posterior median of the slope factor (1: the pilots' curve's)."""
        return self.slope_quantile(0.5)

    @property
    def slope_interval_95(self) -> tuple[float, float]:
        """Return the slope factor's equal-tailed 95 % posterior interval."""
        return self.slope_quantile(0.025), self.slope_quantile(0.975)

    def slope_quantile(self, q: float) -> float:
        """Return the slope factor's posterior quantile `q`."""
        if len(self.log_slopes) == 1:
            return math.exp(self.log_slopes[0])
        # the grid's own points (an interpolated quantile of a coarse grid is half a step
        # off where the posterior sits on one point)
        cumulative = np.cumsum(self._weights().sum(axis=0))
        index = min(int(np.searchsorted(cumulative, q)), len(self.log_slopes) - 1)
        return math.exp(self.log_slopes[index])

    def target_shifts(self, target: float) -> tuple[float, tuple[float, float]]:
        """
        Return the shifts that put the pilots' curve where the measured one reaches `target`.

        The runs a question needs for power `target` are where the predicted power is
        Phi(z80 + (Phi^-1(target) - z80 - shift) / slope): where the pilots' curve, shifted by
        Phi^-1(target) - that probit, reaches `target`. Returned: the posterior median of
        that equivalent shift and its 95 % interval, so that a caller finds the answer and
        its interval with the shifted pilots' curve (`shifted`).
        """
        if self.log_slopes == (0.0,):
            return self.shift, self.interval_95
        equivalent, order = _equivalent_shifts(float(target), self.log_slopes)
        median, low, high = _weighted_quantiles(equivalent, order, self._weights().reshape(-1))
        return median, (low, high)

    def power_band(self, predicted: float) -> tuple[float, float, float]:
        """Return the measured power's posterior median and 95 % interval where `predicted` is."""
        probits = self._probits(predicted).reshape(-1)
        quantiles = _weighted_quantiles(probits, np.argsort(probits, kind='stable'),
                                        self._weights().reshape(-1))
        median, low, high = (float(special.ndtr(value)) for value in quantiles)
        return median, low, high


def _weighted_quantiles(values: FloatArray, order: IntArray, weights: FloatArray
                        ) -> tuple[float, float, float]:
    """Return the median and the 2.5 and 97.5 % points of `values` under `weights`."""
    cumulative = np.cumsum(weights[order])
    last = len(order) - 1
    median, low, high = (float(values[order[min(int(np.searchsorted(cumulative, q)), last)]])
                         for q in (0.5, 0.025, 0.975))
    return median, low, high


@lru_cache(maxsize=8)       # a few powers asked (a validator's question may change)
def _equivalent_shifts(target: float, log_slopes: tuple[float, ...]
                       ) -> tuple[FloatArray, IntArray]:
    """Return `Calibration.target_shifts`' shift at every grid point, and their order."""
    z_target, z80 = float(special.ndtri(target)), float(special.ndtri(POWER))
    slopes = np.exp(np.asarray(log_slopes))
    equivalent: FloatArray = (z_target - z80 - (z_target - z80 - SHIFTS[:, None])
                              / slopes[None, :]).reshape(-1)
    order: IntArray = np.argsort(equivalent, kind='stable')
    return equivalent, order


def measured_probit(predicted: float, shifts: FloatArray, slopes: FloatArray) -> FloatArray:
    """
    Return Phi^-1 of the measured power where `predicted` is: (shifts, slopes) (module doc).

    z80 + shift + slope (Phi^-1(predicted) - z80), z80 = Phi^-1(0.8), a row per shift and a
    column per slope.
    """
    z = float(special.ndtri(min(max(float(predicted), 1e-12), 1 - 1e-12)))
    z80 = float(special.ndtri(POWER))
    probits: FloatArray = z80 + shifts[:, None] + slopes[None, :] * (z - z80)
    return probits


def count_log_likelihood(named: int, total: int, probit: FloatArray) -> FloatArray:
    """Return log P(`named` of `total`) at the powers Phi(probit), binomial coefficient out."""
    log_likelihood: FloatArray = (named * special.log_ndtr(probit)
                                  + (total - named) * special.log_ndtr(-probit))
    return log_likelihood


def _widened(log_likelihood: FloatArray, spread: float) -> FloatArray:
    """Return the log density of a shift that is one of `log_likelihood` plus N(0, spread)."""
    step = float(SHIFTS[1] - SHIFTS[0])
    if 6 * spread < step:          # narrower than the grid: no widening it can show
        return np.asarray(log_likelihood, dtype=float)
    weights = np.exp(log_likelihood - log_likelihood.max())
    half = int(math.ceil(6 * spread / step))
    kernel = stats.norm.pdf(np.arange(-half, half + 1) * step, 0.0, spread)
    # the full convolution, entry i of the grid at i + half (a kernel wider than the grid
    # too: mode='same' would return the kernel's length)
    density = np.convolve(weights / weights.sum(), kernel / kernel.sum())[half:half + len(SHIFTS)]
    widened: FloatArray = np.log(np.maximum(density, 1e-300))
    return widened


def shifted(power: float, shift: float) -> float:
    """Return the power measured where `power` is predicted (module docstring)."""
    return float(special.ndtr(special.ndtri(min(max(power, 1e-12), 1 - 1e-12)) + shift))


@dataclass
class PowerModel:
    """
    The power to name `term` at `size`, as a function of the run count (module docstring).

    `estimate` is the term's size estimate on `calibration_runs` runs (its errors are what
    scale), `gains` the held-out test's per-run gains of runs simulated with the term at
    `size` (limits.held_out_gains), `floor` the smallest size that matters.
    """

    term: str
    size: float
    floor: float
    estimate: SizeEstimate
    calibration_runs: int
    gains: FloatArray = field(repr=False)
    _t_values: FloatArray | None = field(default=None, repr=False, compare=False)

    def estimate_at(self, calibration_runs: float) -> SizeEstimate:
        """Return the estimate with the errors it would have on `calibration_runs` runs."""
        ratio = self.calibration_runs / max(float(calibration_runs), 1.0)
        estimate = self.estimate
        kind = BY_NAME[self.term].kind
        if kind == EstimateKind.MOMENTS:
            return replace(estimate, data_se=estimate.data_se * math.sqrt(ratio),
                           relative_se=estimate.relative_se * math.sqrt(ratio))
        if kind == EstimateKind.TREND:
            slope = abs(estimate.slope) or math.inf
            se = math.hypot(estimate.data_se / slope * math.sqrt(ratio),
                            estimate.intercept_se / slope,
                            estimate.slope_relative_se * self.size)
            return replace(estimate, se=se)
        simulated = min(estimate.simulation_se, estimate.se)
        measured = math.sqrt(max(estimate.se ** 2 - simulated ** 2, 0.0))
        return replace(estimate, se=math.hypot(measured * math.sqrt(ratio), simulated))

    def bound_power(self, runs: float, z: float) -> float:
        """Return P(the size bound clears the floor) with `runs` runs in all."""
        return bound_power(self.estimate_at(runs // 2), self.size, self.floor, z)

    def test_power(self, runs: float, z: float) -> float:
        """
        Return P(the held-out test is significant) with `runs` runs in all.

        The t statistic of `held_out` gains drawn from the simulated ones, as the test takes
        it (one-sided, t distribution), against the critical z. A variance effect's gains are
        skewed (most runs lose a little, a few far out gain much), so the t of some hundred
        runs is not normal around mean / spread x sqrt(runs): fewer samples reach a high
        critical value at first, more a little later (persistent_turning at 3 deg/s against
        3.17: 0.30 at 91 held-out runs where the ratio says 0.38, 0.79 at 150 where it says
        0.70). Beyond RESAMPLED_RUNS held-out runs, where the t is normal, that ratio.
        """
        held_out = int(runs - runs // 2)
        gains = self.gains
        if held_out < 3 or len(gains) < 3:
            return 0.0
        critical = float(stats.norm.sf(z))
        if held_out > RESAMPLED_RUNS:
            spread = float(np.std(gains, ddof=1))
            t = math.inf if spread <= 0 else float(np.mean(gains)) / spread * math.sqrt(
                held_out)
            return float(stats.norm.cdf(t - z)) if math.isfinite(t) else float(t > 0)
        t_values = self.t_values()[:, held_out - 1]
        return float(np.mean(t_values > stats.t.isf(critical, held_out - 1)))

    def t_values(self) -> FloatArray:
        """
        Return the t statistics of RESAMPLES samples of the gains, for 1 ... RESAMPLED_RUNS runs.

        Sample b of h runs is the first h of one draw (common random numbers: the power is
        smooth in the runs); computed once, by running sums.
        """
        if self._t_values is None:
            rng = np.random.default_rng(RESAMPLE_SEED)
            draws = self.gains[rng.integers(0, len(self.gains), (RESAMPLES, RESAMPLED_RUNS))]
            counts = np.arange(1, RESAMPLED_RUNS + 1)
            total = np.cumsum(draws, axis=1)
            squares = np.cumsum(draws ** 2, axis=1)
            del draws
            mean = total / counts
            variance = (np.maximum(squares - counts * mean ** 2, 0.0)
                        / np.maximum(counts - 1, 1))
            with np.errstate(divide='ignore', invalid='ignore'):
                t = mean / np.sqrt(variance / counts)
            t = np.where(variance > 0, t, np.where(mean > 0, np.inf, 0.0))
            self._t_values = t.astype(np.float32)
        return self._t_values

    def power(self, runs: float, z_bound: ZFunction, z_test: ZFunction,
              shift: float = 0.0) -> float:
        """Return P(named) with `runs` runs, critical z's as functions of the half's runs."""
        runs = float(runs)
        predicted = (self.bound_power(runs, z_bound(runs // 2))
                     * self.test_power(runs, z_test(runs - runs // 2)))
        return shifted(predicted, shift) if shift else predicted

    def runs_for(self, target: float, z_bound: ZFunction, z_test: ZFunction,
                 shift: float = 0.0, least: int = 2) -> float:
        """
        Return the fewest runs (in all) with which P(named) reaches `target` (inf: none).

        The power is taken as rising with the runs: the search doubles, then bisects.
        """
        def reaches(runs: float) -> bool:
            return self.power(runs, z_bound, z_test, shift) >= target

        low = float(max(least, 2))
        if reaches(low):
            return low
        high = low
        while not reaches(high):
            low, high = high, high * 2
            if high > MOST_RUNS:
                return math.inf
        while high - low > 1:
            middle = math.floor((low + high) / 2)
            low, high = (middle, high) if not reaches(middle) else (low, middle)
        return high


def gain_sample(test: RunData, without: FittedModel, term: str, size: float,
                scales: FloatArray, score_runs: int, seed: int,
                fitted_values: Mapping[str, float] | None = None,
                repeats: int = GAIN_REPEATS) -> FloatArray:
    """
    Return held-out gains of runs simulated with the term at `size` (limits.held_out_gains).

    From `repeats` independent simulations: one of 1000 runs puts a Monte Carlo error of
    about 10 % on the mean gain of a term near its limit, 20 % on the runs needed.
    """
    values = []
    for repeat in range(repeats):
        simulator = Simulator(test, int(np.random.SeedSequence([seed, 53, repeat])
                                        .generate_state(1)[0]))
        base = limit_base(simulator, without, scales, score_runs)
        values.append(held_out_gains(simulator, without, base, BY_NAME[term], size, scales,
                                     score_runs, fitted_values))
    return np.concatenate(values)


def fixed(z: float) -> ZFunction:
    """Return a critical z that is the same at every run count (a fixed-sample test)."""
    return lambda information: z
