"""
Does `t_scoring_se` say how far other scored runs move a held-out t? Measured, per case.

A case: runs of the reference robot (Table II) with one term hidden in them, split as the
diagnosis splits; the candidate is the true model, the current one the same without the term
(fits held: no fitting, so only the scored runs move). The held-out t of the candidate over
the current model is computed with the scored runs drawn from `--draws` seeds (both models on
the same seed, as the race scores them), and beside the spread of those t the median of the
`t_scoring_se` each draw reports. A ratio near 1 says the reported error is the scatter; above
1 it is on the safe side (it flags more close calls than need be).

Run: .venv/bin/python benchmarks/bench_scoring_error.py [--draws 24] [--runs 300]
     [--score-runs 800] [--cases NAME ...] [--seeds N ...]
(`--seeds`: the data sets' seeds, one row per case and seed; default 11.)
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
import sys
import time

import numpy as np

# the term hidden in each case, in simulate()'s form (effects or extensions) and as the model's
CASES = {
    'heading_random_walk': ({}, {'heading_random_walk': {'step_std_deg': 1.4}}),
    'lateral_slip': ({'lateral_slip': {'velocity_cm_s': 0.5}}, {}),
    'persistent_turning': ({'persistent_turning': {'yaw_rate_std_deg_s': 4.0}}, {}),
    'measurement_noise': ({'measurement_noise': {'position_std_cm': 0.02}}, {}),
    'run_order_drift:yaw_rate': ({}, {'run_order_drift': {'parameter': 'yaw_rate',
                                                          'change': 4.0}}),
}


@dataclass(frozen=True)
class ScoringError:
    """One case: the held-out t over the draws, its spread, and the reported errors."""

    case: str
    mean_t: float
    t_sd_over_draws: float
    reported_median: float
    reported_range: tuple[float, float]
    cpu_s: float

    @property
    def ratio(self) -> float:
        return self.reported_median / self.t_sd_over_draws


def measure(case: str, draws: int, runs: int, score_runs: int, seed: int = 11) -> ScoringError:
    """Score the case's two true models at `draws` seeds of the scored runs (module docstring)."""
    import importlib

    import octoroach_model as om
    from octoroach_model.diagnosis import DiagnosisSettings
    from octoroach_model.diagnosis.modelfit import FittedModel
    from octoroach_model.diagnosis.scoring import PairedGain, t_scoring_se
    from octoroach_model.fitting import mean_start_pose
    from octoroach_model.model.extensions import family_terms

    race = importlib.import_module('octoroach_model.diagnosis.diagnose')
    effects, extensions = CASES[case]
    measured = om.simulate(runs, seed=seed, effects=effects or None,
                           extensions=extensions or None)
    settings = DiagnosisSettings(score_runs=score_runs, seed=seed)
    halves = race.prepare_halves(measured, settings)
    start = tuple(mean_start_pose(measured))
    current = FittedModel(om.ModelParameters.nominal(), start, 1.0, {})
    candidate = FittedModel(om.ModelParameters.nominal(), start, 1.0,
                            {**effects, **family_terms(extensions)})
    observed = halves.test.features / halves.scales
    started = time.process_time()
    t_values, reported = [], []
    for draw in range(draws):
        simulator = race.Simulator(halves.test, 1000 + draw)
        before = race.score_held_out(simulator, current, halves, settings)
        after = race.score_held_out(simulator, candidate, halves, settings)
        gain = PairedGain.of(after.log - before.log)
        t_values.append(gain.mean / gain.standard_error)
        error = t_scoring_se(after, before, observed, np.random.default_rng([seed, draw]))
        reported.append(np.nan if error is None else error)
    return ScoringError(case, float(np.mean(t_values)), float(np.std(t_values, ddof=1)),
                        float(np.nanmedian(reported)),
                        (float(np.nanmin(reported)), float(np.nanmax(reported))),
                        time.process_time() - started)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[1])
    parser.add_argument('--draws', type=int, default=24)
    parser.add_argument('--runs', type=int, default=300)
    parser.add_argument('--score-runs', type=int, default=800)
    parser.add_argument('--cases', nargs='*', default=list(CASES), choices=list(CASES))
    parser.add_argument('--seeds', nargs='*', type=int, default=[11])
    args = parser.parse_args(argv)
    print(f'{args.runs} runs, {args.score_runs} scored runs a model, {args.draws} draws\n')
    print('| term hidden | data seed | mean t | t SD over draws | reported t_scoring_se: median '
          '(range) | ratio | CPU s |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    for case in args.cases:
        for seed in args.seeds:
            found = measure(case, args.draws, args.runs, args.score_runs, seed)
            low, high = found.reported_range
            print(f'| {case} | {seed} | {found.mean_t:.2f} | {found.t_sd_over_draws:.3f} | '
                  f'{found.reported_median:.3f} ({low:.3f}-{high:.3f}) | {found.ratio:.2f} | '
                  f'{found.cpu_s:.1f} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
