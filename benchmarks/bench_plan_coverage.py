"""
How often `plan --method simulate`'s 95 % interval holds the true run count.

Simulated plans on a known power curve: each of R replicates is named at run count n when
its uniform draw u < power(n) (one draw per replicate: nested data sets, as plan's common
random numbers make them), at five counts around the truth. For each plan, plan's fit
(`studies/power_curve.py`: the profile-likelihood interval scaled for replicates) and,
beside it, two references kept here: the percentile bootstrap over replicates of a logistic
fit to the outcomes as independent trials (what plan used before: 400 resamples), and a
threshold model (each replicate named from some run count on, interval-censored; its plain
profile-likelihood interval). Printed per case and method: coverage with its Wilson
interval, where the misses lay, the median |ln(answer / truth)| and the interval's median
width.

Cases: `nested` (the test's curve, power 80 % at 316 runs), `probit` (the same counts, a
probit curve in ln n: the logistic form is wrong), `independent` (fresh draws at every count:
no common random numbers, the threshold model's worst case).

Run: .venv/bin/python benchmarks/bench_plan_coverage.py [--plans 400] [--replicates 6 20 60]
     [--cases nested probit independent] [--seed 1] [--workers 2]
The figures in docs/studies.md ("How plan decides") come from the default call.
"""
from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
import math
from pathlib import Path
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

COUNTS = (100, 200, 400, 800, 1600)
TRUE_A, TRUE_B = -13.0, 2.5          # logistic: 80 % power at exp((ln 4 + 13) / 2.5) = 316 runs
TARGET = 0.8
BOOTSTRAP = 400


def truth() -> float:
    return math.exp((math.log(TARGET / (1 - TARGET)) - TRUE_A) / TRUE_B)


def power_at(case: str, runs: float) -> float:
    """Return the true power of a case: logistic in ln n, or a probit of the same 80 % point."""
    from scipy import stats

    if case == 'probit':
        # slope chosen so that power goes 50 % -> 80 % over the same span of ln n as the logit
        scale = (math.log(truth()) - (-TRUE_A / TRUE_B)) / float(stats.norm.ppf(TARGET))
        return float(stats.norm.cdf((math.log(runs) + TRUE_A / TRUE_B) / scale))
    return 1.0 / (1.0 + math.exp(-(TRUE_A + TRUE_B * math.log(runs))))


def plan_rows(case: str, replicates: int, seed: int, plan: int) -> list:
    from octoroach_model.studies.rows import Status, StudyRow, TermOutcome
    from octoroach_model.studies.spec import ArmKind

    rng = np.random.default_rng([seed, plan])
    rows = []
    for replicate in range(replicates):
        u = rng.random()
        for runs in COUNTS:
            draw = rng.random() if case == 'independent' else u
            rows.append(StudyRow('', '', ArmKind.ABSOLUTE, replicate, 0, runs,
                                 status=Status.OK, terms={'speed_decay': TermOutcome(
                                     named=draw < power_at(case, runs))}))
    return rows


def bootstrap_interval(rows: list, seed: int) -> tuple[float, float, float]:
    """Return the former answer and interval: logistic MLE, percentile bootstrap."""
    x = np.log([row.runs for row in rows])
    y = np.array([float(row.terms['speed_decay'].named) for row in rows])
    replicate = np.array([row.replicate for row in rows])
    logit = math.log(TARGET / (1 - TARGET))

    def crossing(pick: np.ndarray) -> float:
        a, b = independent_logistic(x[pick], y[pick])
        exponent = (logit - a) / b if b > 1e-9 else math.inf
        return math.exp(exponent) if exponent < 700 else math.inf

    ids = np.unique(replicate)
    members = {r: np.flatnonzero(replicate == r) for r in ids}
    rng = np.random.default_rng(seed)
    draws = [crossing(np.concatenate([members[r] for r in rng.choice(ids, len(ids))]))
             for _ in range(BOOTSTRAP)]
    low, high = np.percentile(np.minimum(draws, 1e300), [2.5, 97.5])
    return (crossing(np.arange(len(rows))), float(low) if low < 1e300 else math.inf,
            float(high) if high < 1e300 else math.inf)


def independent_logistic(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """expit(a + b x) by Newton steps on the outcomes per distinct x, b in [0, 20], ridge."""
    from scipy.special import expit, log_expit

    centre = float(x.mean())
    levels, index = np.unique(x, return_inverse=True)
    trials = np.bincount(index).astype(float)
    successes = np.bincount(index, weights=y)
    design = np.stack([np.ones_like(levels), levels - centre], axis=1)

    def loss(theta: np.ndarray) -> float:
        eta = design @ theta
        return float(-(successes * log_expit(eta) + (trials - successes) * log_expit(-eta)).sum()
                     + 1e-3 * (theta @ theta))

    theta, current = np.zeros(2), loss(np.zeros(2))
    for _ in range(100):
        p = expit(design @ theta)
        gradient = design.T @ (trials * p - successes) + 2e-3 * theta
        hessian = (design.T * (trials * p * (1 - p))) @ design + 2e-3 * np.eye(2)
        step = np.linalg.solve(hessian, gradient)
        for _ in range(40):
            trial = theta - step
            trial[1] = min(max(trial[1], 0.0), 20.0)
            value = loss(trial)
            if value <= current:
                break
            step = step / 2
        else:
            break
        done = abs(current - value) < 1e-12
        theta, current = trial, value
        if done:
            break
    return float(theta[0] - theta[1] * centre), float(theta[1])


def threshold_interval(rows: list) -> tuple[float, float, float]:
    """Return the threshold model's: each replicate's span of ln T, plain profile."""
    from scipy.special import expit

    from octoroach_model.studies.power_curve import LIKELIHOOD_RATIO_95, MAX_SLOPE, MIN_SLOPE

    seen: dict[int, list[tuple[float, bool]]] = {}
    for row in rows:
        seen.setdefault(row.replicate, []).append(
            (math.log(row.runs), bool(row.terms['speed_decay'].named)))
    spans = []
    for outcomes in seen.values():
        named = [x for x, hit in outcomes if hit]
        missed = [x for x, hit in outcomes if not hit]
        first, last = min(named, default=math.inf), max(missed, default=-math.inf)
        spans.append((last, first) if last < first else (
            max((x for x in missed if x < first), default=-math.inf),
            min((x for x in named if x > last), default=math.inf)))
    x = np.log(COUNTS)
    crossings = np.linspace(x[0] - math.log(64), x[-1] + math.log(64), 1601)
    c, b = crossings[:, None], np.geomspace(MIN_SLOPE, MAX_SLOPE, 300)[None, :]
    logit = math.log(TARGET / (1 - TARGET))
    below = {edge: expit(logit + b * (edge - c)) for edge in x}
    below[-math.inf], below[math.inf] = np.zeros_like(c * b), np.ones_like(c * b)
    likelihood = sum(np.log(np.maximum(below[high] - below[low], 1e-300))
                     for low, high in spans)
    likelihood = likelihood - 1e-3 * ((logit - b * (c - x.mean())) ** 2 + b ** 2)
    profile = likelihood.max(axis=1)
    best = int(np.argmax(profile))
    inside = np.flatnonzero(2 * (profile[best] - profile) <= LIKELIHOOD_RATIO_95)
    return (math.exp(crossings[best]), 0.0 if inside[0] == 0 else math.exp(crossings[inside[0]]),
            math.inf if inside[-1] == len(crossings) - 1 else math.exp(crossings[inside[-1]]))


METHODS = ('plan (profile likelihood, scaled for replicates)',
           'former (percentile bootstrap)', 'threshold model (plain profile)')


def one_plan(job: tuple[str, int, int, int]) -> tuple[tuple[float, float, float], ...]:
    from octoroach_model.studies.power_curve import fit_power_curve

    case, replicates, seed, plan = job
    rows = plan_rows(case, replicates, seed, plan)
    fit = fit_power_curve(rows, 'speed_decay', TARGET)
    return ((fit.runs_at_target, *fit.interval_95), bootstrap_interval(rows, plan),
            threshold_interval(rows))


def summary(label: str, answers: list[tuple[float, float, float]]) -> str:
    from octoroach_model.studies.summary import wilson

    true = truth()
    held = sum(low < true < high for _, low, high in answers)
    below = sum(high <= true for _, _, high in answers)
    rate = wilson(held, len(answers))
    assert rate.interval is not None
    errors = [abs(math.log(answer / true)) if 0 < answer < math.inf else math.inf
              for answer, _, _ in answers]
    widths = [math.log(high / low) if 0 < low and high < math.inf else math.inf
              for _, low, high in answers]
    return (f'{label}: {held}/{len(answers)} = {rate.rate:.1%} ({rate.interval[0]:.1%}-'
            f'{rate.interval[1]:.1%}); misses below the truth {below}, above '
            f'{len(answers) - held - below}; median |ln(answer / truth)| '
            f'{np.median(errors):.3f}; median width ln(high / low) {np.median(widths):.3f}')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--plans', type=int, default=400)
    parser.add_argument('--replicates', type=int, nargs='+', default=[6, 20, 60])
    parser.add_argument('--cases', nargs='+', default=['nested', 'probit', 'independent'],
                        choices=['nested', 'probit', 'independent'])
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args(argv)
    print(f'true run count at {TARGET:.0%} power: {truth():.1f}; counts {COUNTS}; '
          f'{args.plans} plans per case, seed {args.seed}', flush=True)
    with ProcessPoolExecutor(args.workers) as pool:
        for case in args.cases:
            for replicates in args.replicates:
                started = time.perf_counter()
                jobs = [(case, replicates, args.seed, plan) for plan in range(args.plans)]
                results = list(pool.map(one_plan, jobs, chunksize=8))
                print(f'\n{case}, {replicates} replicates '
                      f'({time.perf_counter() - started:.0f} s)', flush=True)
                for number, method in enumerate(METHODS):
                    print('  ' + summary(method, [result[number] for result in results]),
                          flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
