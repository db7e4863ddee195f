"""
Why a periodic heading at its detection limit goes unnamed: the race's test, data set by data set.

studies/heading_terms.yaml named periodic_heading at 1x its limit in 7 of 12 data sets. For
each replicate's data set with the term at 1x (rebuilt from the spec and the limit in the
study's table.csv, as the study built it), the race's first step is repeated for the term
alone and printed: the size's lower bound against its floor (the first half of the decision),
the held-out gain's mean and spread over the held-out runs and its t against the critical z
(the second half), and the study's outcome. With `--log-variance`, the same t when the two
variance features (increment_var, stride_length_var) are scored as logarithms, an option
measured and dropped (docs/diagnosis.md, section 8). With `--parts R`, replicate R's gain
feature by feature, beside the pair the limit simulates (the term at its size against the
model without it, spread refit), and the held-out runs that cost the term most. With
`--simulation-seeds K`, only the t on each data set for K seeds of the race's simulations (the
runs and their halves kept): how much of the decision the simulations' draws move. With
`--moment-runs N`, the table with N simulated runs for every statistic matched.

About 25 s per data set on two idle cores.
Run: .venv/bin/python benchmarks/bench_periodic_misses.py [--replicates 0-11] [--log-variance]
     [--parts 3] [--moment-runs 1600] | --replicates 3,0 --simulation-seeds 4
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
SPEC = REPO / 'studies' / 'heading_terms.yaml'
TABLE = REPO / 'out' / 'studies' / 'heading_terms' / 'table.csv'
TERM = 'periodic_heading'
VARIANCE_FEATURES = ('increment_var', 'stride_length_var')


def race_step(replicate: int, null_row: Any, simulation_shift: int = 0,
              moment_runs: int | None = None) -> Any:
    """Return the replicate's data set with the term at 1x, weighed (study_replay.race_step)."""
    from study_replay import race_step as weighed

    return weighed(SPEC, replicate, TERM, null_row, simulation_shift, moment_runs)


def feature_scores(sample: Any, observed: Any, logged: bool) -> Any:
    """Return per-run, per-feature log scores; `logged`: the variance features as logs."""
    import numpy as np

    from octoroach_model.diagnosis.features import INDEX
    from octoroach_model.diagnosis.scoring import feature_log_densities

    if logged:
        sample, observed = sample.copy(), observed.copy()
        for name in VARIANCE_FEATURES:
            for array in (sample, observed):
                array[:, INDEX[name]] = np.log(np.maximum(array[:, INDEX[name]], 1e-6))
    return feature_log_densities(sample, observed)


def scored_runs(step: Any, model: Any) -> Any:
    """Return the model's runs as the held-out test scores them (features in data spreads)."""
    from octoroach_model.diagnosis.diagnose import SCORE_PURPOSE

    paths, positions = step.simulator.runs(model, step.settings.score_runs, SCORE_PURPOSE)
    return step.halves.every.features_of(paths, positions) / step.halves.scales


def t_of(gains: Any, held_out: int) -> float:
    """Return the held-out test's t on `held_out` runs with per-run gains like `gains`."""
    import numpy as np

    return float(gains.mean() / np.std(gains, ddof=1) * math.sqrt(held_out))


def outcomes(replicates: list[int], rows: dict[int, dict[str, Any]], log_variance: bool,
             moment_runs: int | None) -> None:
    """Print the two halves of the decision on each replicate's data set with the term."""
    from scipy import stats

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.decide import decision_z, judge
    from octoroach_model.diagnosis.diagnose import CANDIDATES

    cause = BY_NAME[TERM]
    extra = ' | t, variance features as logs' if log_variance else ''
    print(f'{TERM} at 1x its limit, the first race step (studies/heading_terms.yaml)\n')
    print(f'| replicate | size, deg | lower bound / floor, deg | gain mean, nats/run | '
          f'gain spread | t (critical z) | named in the study{extra} |')
    print('| --- | --- | --- | --- | --- | --- | ---' + (' | ---' if log_variance else '') + ' |')
    for replicate in replicates:
        step = race_step(replicate, rows[replicate]['none'], moment_runs=moment_runs)
        settings, evaluation = step.settings, step.evaluation
        everyone = len(CANDIDATES)
        verdict = judge(evaluation.estimates[TERM], cause.floor(step.halves.run_scale),
                        decision_z(settings.decision_alpha, everyone))
        critical = float(stats.norm.isf(settings.alpha / everyone))
        spread = evaluation.gain.standard_error * math.sqrt(step.halves.test.n)
        t = evaluation.gain.mean / spread * math.sqrt(step.halves.test.n)
        named = ', '.join(rows[replicate][f'{TERM}@1x'].outcome.named) or '(none)'
        cells = [str(replicate), f'{step.effects[TERM]["amplitude_deg"]:.3g}',
                 f'{verdict.lower_bound:.3g} / {verdict.floor:.3g}',
                 f'{evaluation.gain.mean:.3f}', f'{spread:.2f}', f'{t:.2f} ({critical:.2f})',
                 named]
        if log_variance:
            observed = step.halves.test.features / step.halves.scales
            gains = (feature_scores(scored_runs(step, evaluation.model), observed, True)
                     - feature_scores(scored_runs(step, step.baseline), observed, True))
            cells.append(f'{t_of(gains.sum(axis=1), step.halves.test.n):.2f}')
        print('| ' + ' | '.join(cells) + ' |', flush=True)
    print()


def parts(replicate: int, rows: dict[int, dict[str, Any]]) -> None:
    """Print one data set's held-out gain feature by feature, beside the limit's pair."""
    import numpy as np

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.features import INDEX, OUTCOMES
    from octoroach_model.diagnosis.limits import simulated_pair

    step = race_step(replicate, rows[replicate]['none'])
    halves, evaluation = step.halves, step.evaluation
    observed = halves.test.features / halves.scales
    measured = (feature_scores(scored_runs(step, evaluation.model), observed, False)
                - feature_scores(scored_runs(step, step.baseline), observed, False))
    size = step.effects[TERM]['amplitude_deg']
    pair = simulated_pair(step.simulator, step.baseline, scored_runs(step, step.baseline),
                          BY_NAME[TERM], size, halves.scales, step.settings.score_runs,
                          dict(evaluation.model.effects[TERM]), step.settings.fit())
    pseudo = pair.runs / halves.scales
    simulated = (feature_scores(scored_runs(step, pair.extended), pseudo, False)
                 - feature_scores(pair.without_features, pseudo, False))
    names = [name for name, column in INDEX.items() if OUTCOMES[column]]
    print(f'Replicate {replicate}, {TERM} at {size:.3g} deg: the held-out gain by feature '
          f'(nats per run)\n')
    print(f'Spread scales: the race fits {step.baseline.sigma_scale:.3f} without the term and '
          f'{evaluation.model.sigma_scale:.3f} with it; the limit simulates '
          f'{pair.without.sigma_scale:.3f} and {pair.extended.sigma_scale:.3f}.\n')
    print("| feature | measured: mean | spread | the limit's pair: mean | spread |")
    print('| --- | --- | --- | --- | --- |')
    for index, name in enumerate(names):
        if max(np.ptp(measured[:, index]), np.ptp(simulated[:, index])) < 1e-3:
            continue        # a feature both models predict alike (log_noise without noise)
        print(f'| {name} | {measured[:, index].mean():.3f} | '
              f'{np.std(measured[:, index], ddof=1):.2f} | {simulated[:, index].mean():.3f} | '
              f'{np.std(simulated[:, index], ddof=1):.2f} |')
    held_out = halves.test.n
    totals = [gains.sum(axis=1) for gains in (measured, simulated)]
    print(f'| summed (t on {held_out} runs) | {totals[0].mean():.3f} | '
          f'{np.std(totals[0], ddof=1):.2f} (t {t_of(totals[0], held_out):.2f}) | '
          f'{totals[1].mean():.3f} | {np.std(totals[1], ddof=1):.2f} '
          f'(t {t_of(totals[1], held_out):.2f}) |')
    total = measured.sum(axis=1)
    quantiles = np.quantile(total, [0.0, 0.01, 0.05, 0.5, 0.95, 1.0])
    print('\nPer-run gain, quantiles 0, 1, 5, 50, 95, 100 %: '
          + ', '.join(f'{value:.2f}' for value in quantiles))
    print('The held-out runs that cost the term most (feature, its share of the loss):')
    for run in np.argsort(total)[:5]:
        worst = np.argsort(measured[run])[:2]
        print(f'- run {run}: {total[run]:.2f} nats (' + ', '.join(
            f'{names[index]} {measured[run, index]:.2f}' for index in worst) + ')')
    print()


def simulation_seeds(replicates: list[int], rows: dict[int, dict[str, Any]], seeds: int) -> None:
    """Print the race's t on the same data and halves for `seeds` seeds of its simulations."""
    import numpy as np

    print(f'{TERM} at 1x: the held-out t on the same runs and halves, the simulations drawn '
          f'with {seeds} seeds (the study used the first)\n')
    print('| replicate | spread scale without / with the term | t | spread of t |')
    print('| --- | --- | --- | --- |')
    for replicate in replicates:
        scales, ts = [], []
        for shift in range(seeds):
            step = race_step(replicate, rows[replicate]['none'], shift)
            gain = step.evaluation.gain
            ts.append(gain.mean / gain.standard_error)
            scales.append(f'{step.baseline.sigma_scale:.3f} / '
                          f'{step.evaluation.model.sigma_scale:.3f}')
        print(f'| {replicate} | {", ".join(scales)} | {", ".join(f"{t:.2f}" for t in ts)} | '
              f'{np.std(ts, ddof=1):.2f} |', flush=True)
    print()


def replicate_list(text: str) -> list[int]:
    """Parse '0-11' or '2,3,5'."""
    if '-' in text:
        first, last = text.split('-')
        return list(range(int(first), int(last) + 1))
    return [int(part) for part in text.split(',')]


def main() -> int:
    """Print the tables."""
    from octoroach_model.studies.table import read_table

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--replicates', type=replicate_list, default=list(range(12)))
    parser.add_argument('--log-variance', action='store_true',
                        help='also the t with the variance features scored as logarithms')
    parser.add_argument('--parts', type=int, default=None, metavar='R',
                        help="replicate R's gain feature by feature")
    parser.add_argument('--moment-runs', type=int, default=None, metavar='N',
                        help="simulated runs for every statistic matched (the study's: 400)")
    parser.add_argument('--simulation-seeds', type=int, default=0, metavar='K',
                        help='only the t on each replicate for K seeds of the simulations')
    args = parser.parse_args()
    if not TABLE.is_file():
        print(f'needs the study table: run studies/heading_terms.yaml into {TABLE.parent}')
        return 1
    rows: dict[int, dict[str, Any]] = {}
    for row in read_table(TABLE)[0]:
        rows.setdefault(row.replicate, {})[row.arm] = row
    replicates = [replicate for replicate in args.replicates if replicate in rows]
    if args.simulation_seeds > 1:
        simulation_seeds(replicates, rows, args.simulation_seeds)
        return 0
    outcomes(replicates, rows, args.log_variance, args.moment_runs)
    if args.parts is not None:
        parts(args.parts, rows)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
