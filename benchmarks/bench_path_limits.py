"""
A path family's detection limit taken apart on one robot: each part of the decision it predicts.

On Table II's robot (500 null runs of 10 strides, `--seed`), for yaw_rate_ramp or
change_point (`--term`), prints

- the term's quick estimate (what the race screens it on) and its joint refit with the
  geometry (what sizes it), each with its standard error (change_point's at half the runs,
  where its limit is stated);
- the detection limit the diagnosis computes (diagnose.path_family_estimates, limits.
  detection_limit) with its two parts, P(size bound clears) and P(held-out test);
- at `--size` (default: that limit), the held-out test's expected t against the model as
  fitted to the null runs (a change point then entering at its strides per run) and against
  the model refit to the robot's runs with the term (its geometry bent to the term's mean:
  limits.geometry_absorbed, which the limit weighs for both terms), and t with the extended
  model at the size 1.7 standard errors of the refit below and above it, with the power they
  average to (limits.size_averaged_t);
- with `--data-sets K`: K data sets of the robot with the term at that size, the race's first
  step on each (the baseline fitted, the term weighed): the size as refit, its lower bound
  against the floor, the held-out t against the critical one (docs/diagnosis.md, section 8).

About a minute on two idle cores, and 20-25 s per data set.
Run: .venv/bin/python benchmarks/bench_path_limits.py [--term yaw_rate_ramp] [--seed 5]
     [--size S] [--data-sets 4]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
import time
from typing import Any

PARAMETERS = {'yaw_rate_ramp': 'final_yaw_rate_deg_s', 'change_point': 'speed_factor'}
RUNS, CYCLES = 500, 10


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--term', choices=sorted(PARAMETERS), default='yaw_rate_ramp')
    parser.add_argument('--seed', type=int, default=5)
    parser.add_argument('--size', type=float, default=None)
    parser.add_argument('--data-sets', type=int, default=0)
    args = parser.parse_args(argv)

    from scipy import stats

    import octoroach_model as om
    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.causes import BY_NAME, CANDIDATES, change_point_limit_s
    from octoroach_model.diagnosis.decide import decision_z, judge
    from octoroach_model.diagnosis.diagnose import (
        DiagnosisSettings, halves_as_diagnosed, path_family_estimates)
    from octoroach_model.diagnosis.modelfit import same_strides
    from study_replay import first_step

    started = time.perf_counter()
    settings = DiagnosisSettings(seed=args.seed)
    cause = BY_NAME[args.term]
    everyone = len(CANDIDATES)
    z_bound = decision_z(settings.decision_alpha, everyone)
    z_test = float(stats.norm.isf(settings.alpha / everyone))

    def weighed(measured: Any) -> tuple[Any, Any, Any, Any]:
        return first_step(halves_as_diagnosed(measured, settings), cause.name, settings, z_bound)

    halves, baseline, evaluation, simulator = weighed(
        om.simulate(RUNS, seed=args.seed, cycles=CYCLES))
    floor = cause.floor(halves.run_scale)
    refit, screen = path_family_estimates(halves, baseline, evaluation, settings)
    print(f"{args.term} on Table II's robot, {RUNS} null runs of {CYCLES} strides, seed "
          f'{args.seed}: floor {floor:.4g}, z of the bound {z_bound:.2f}, of the test '
          f'{z_test:.2f}')
    print(f'  quick estimate {screen.size:+.4g} (se {screen.se:.3g}); joint refit '
          f'{refit.size:+.4g} (se {refit.se:.3g})')
    base = limits.limit_base(simulator, baseline, halves.scales, settings.score_runs)
    # the term's other parameters where the diagnosis states its limit (diagnose._limit):
    # change_point's time at half the runs
    fitted = ({'time_s': change_point_limit_s(float(halves.train.paths.t[-1]))}
              if args.term == 'change_point' else None)
    limit = limits.detection_limit(
        simulator, baseline, refit, floor, z_bound, z_test, halves.scales, halves.test.n,
        settings.score_runs, judge(screen, floor, z_bound).limit, fitted, base,
        settings.fit(), screen)
    print(f'  detection limit {limit.size:.4g}: P(size bound clears) '
          f'{limit.size_bound_power:.3f}, P(held-out test) {limit.test_power:.3f} '
          f'({time.perf_counter() - started:.0f} s)')
    size = args.size if args.size is not None else limit.size
    if size is None:
        return 0
    # the model without the term refit to runs with it, and as fitted to the null runs (a
    # clock term then entering at their strides per run), whichever the limit weighs
    values = limits.at_size(cause, size, fitted, simulator.data)

    def pair_of(refit: bool) -> Any:
        return limits.simulated_pair(simulator, baseline, base,
                                     replace(cause, geometry_mimics=refit), size,
                                     halves.scales, settings.score_runs, values,
                                     settings.fit())

    pair, as_fitted = pair_of(True), pair_of(False)
    used = pair if cause.geometry_mimics else as_fitted      # the pair the limit weighs

    def t_of(chosen: Any, extended: Any = None) -> float:
        return limits.t_statistic(chosen.gains(simulator, halves.scales, settings.score_runs,
                                               extended), halves.test.n)

    t_fitted, t_refit = t_of(as_fitted), t_of(pair)
    duration = float(simulator.data.paths.t[-1])
    moved = [t_of(used, same_strides(used.extended.with_effect(cause.name, limits.at_size(
        cause, max(size + node * refit.se, 0.0), values, simulator.data)), used.extended,
        duration)) for node in limits.SPREAD_NODES[1:]]
    averaged = limits.size_averaged_t(simulator, used, cause, size, refit.se, t_of(used),
                                      halves.scales, halves.test.n, settings.score_runs,
                                      z_test, values)

    def power(t: float) -> str:
        return f'{stats.norm.cdf(t - z_test):.3f}'

    print(f'  at {size:.4g}: expected t against the model as fitted {t_fitted:.2f} (power '
          f'{power(t_fitted)}), against the model refit to runs with the term {t_refit:.2f} '
          f'({power(t_refit)}; the limit weighs the '
          f'{"refit" if cause.geometry_mimics else "fitted"} one); at the size '
          f'{1.7 * refit.se:.3g} below and above: {moved[0]:.2f}, {moved[1]:.2f}; averaged, '
          f'power {power(averaged)} ({time.perf_counter() - started:.0f} s)')
    critical = float(stats.t.isf(settings.alpha / everyone, halves.test.n - 1))
    for data_set in range(args.data_sets):
        terms = {cause.name: values}
        measured = om.simulate(RUNS, seed=args.seed + 100 + data_set, cycles=CYCLES,
                               **({'extensions': terms} if cause.is_extension else
                                  {'effects': terms}))
        evaluation = weighed(measured)[2]
        estimate = evaluation.estimates[cause.name]
        lower = abs(estimate.size - cause.null) - z_bound * estimate.se
        gain = evaluation.gain
        t = gain.mean / gain.standard_error if gain.standard_error > 0 else math.nan
        print(f'  data set {data_set} with the term at {size:.4g}: '
              f'{"screened, " if evaluation.screened else ""}refit {estimate.size:+.4g} '
              f'(se {estimate.se:.3g}), bound {lower:.4g} for a floor of {floor:.4g}; '
              f'held-out t {t:.2f} for {critical:.2f} ({time.perf_counter() - started:.0f} s)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
