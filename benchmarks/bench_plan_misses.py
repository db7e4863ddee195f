"""
Where plan's prediction of a term's power falls short: the size bound or the held-out test.

`bench_plan.py --calibrate` counts how often a term's first step names it where the pilots
predict 80 % (power.CALIBRATION_COUNTS). The pilots' power is P1 x P2 (diagnosis/power.py):
the size bound clears the floor, the held-out test passes. This takes the same pilots and
plan's own checks (plan_model.check_task: the term at the size, the diagnosis's
levels) and prints for each check which of the two failed, then each criterion's share with
its Wilson interval beside the pilots' P1 and P2, and the test's share split by whether the
fitted size fell above or below the truth: the power model scores the held-out runs with the
term at the true size, where the test scores them at the size fitted on the other half.

Run: .venv/bin/python benchmarks/bench_plan_misses.py TERM=SIZE [--runs N] [--checks 32]
     [--workers 2]
(--runs: the run count of the checks; default the pilots' 80 % point, as --calibrate takes.)
It also prints the pilots' test power by its expected t (normal approximation) at the true
size and averaged over the error of the size fitted (`averaged_test`).
The figures in docs/measured.md ("How many runs") for the legs' drifts, at the run counts
--calibrate predicted: run_order_drift:touchdown_angle_1=12 --runs 177,
run_order_drift:touchdown_angle_3=9 --runs 141, run_order_drift:touchdown_angle_4=14 --runs
203 (about a minute each on a slow day).
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import math
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

FIRST_CHECK = 1000          # the check replicates --calibrate takes (plan's checks: 1000 on)
PILOT_RUNS = 500            # the runs of a pilot data set, as --calibrate takes them


def averaged_test(term: str, size: float, runs: int, replicate: int, size_se: float,
                  z_test: float) -> tuple[float, float]:
    """
    Return pilot `replicate`'s test power at the true size and averaged over the size's error.

    Both from the expected t of the held-out gains (normal approximation), at
    `runs - runs // 2` held-out runs; the average is `limits.size_averaged_t`'s (three-point
    Gauss-Hermite over `size_se`), which the detection limits take for a path family.
    """
    import numpy as np
    from scipy import stats

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.limits import expected_t, limit_base
    from octoroach_model.diagnosis.live import fit_held, live_halves, Question
    from octoroach_model.diagnosis.modelfit import Simulator
    from octoroach_model.studies.design import draw_robot
    from octoroach_model.studies.plan import default_spec
    from octoroach_model.studies.plan_model import robot_model
    from octoroach_model.studies.replicate import simulate_data

    spec = default_spec(term, size)
    draw = draw_robot(spec, replicate)
    measured = simulate_data(spec, draw, PILOT_RUNS, {}).paths
    settings = spec.diagnosis_settings(draw.data_seed)
    held = fit_held(measured, Question(term, size), settings, robot_model(draw),
                    with_power=False, fitted=False)
    halves = live_halves(measured, held, settings.seed)
    # the simulator of power.gain_sample's first repeat
    simulator = Simulator(halves.test, int(np.random.SeedSequence([settings.seed, 53, 0])
                                           .generate_state(1)[0]))
    base = limit_base(simulator, held.model, halves.scales, settings.score_runs)
    held_out = runs - runs // 2
    at_truth = expected_t(simulator, held.model, base, BY_NAME[term], size, halves.scales,
                          held_out, settings.score_runs)
    averaged = expected_t(simulator, held.model, base, BY_NAME[term], size, halves.scales,
                          held_out, settings.score_runs, z_test=z_test, size_se=size_se)
    return (float(stats.norm.cdf(at_truth.t - z_test)),
            float(stats.norm.cdf(averaged.t - z_test)))


def whole_number(option: str, least: int, most: int) -> Callable[[str], int]:
    """Return the parser of a whole-number option within [least, most], refusing in one line."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{option} takes a whole number') from None
        if not least <= value <= most:
            raise argparse.ArgumentTypeError(f'{option} lies within {least}-{most}')
        return value
    return parse


def asked(text: str) -> tuple[str, float]:
    """Return (term, size) of a TERM=SIZE argument, or refuse it in one line (no counts)."""
    from bench_plan_questions import question

    term, size, counts = question(text)
    if counts is not None:
        raise argparse.ArgumentTypeError("give the checks' run count with --runs, not @N")
    return term, size


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('question', metavar='TERM=SIZE', type=asked)
    parser.add_argument('--runs', type=whole_number('--runs', 40, 100_000), default=None)
    parser.add_argument('--checks', type=whole_number('--checks', 1, 1000), default=32)
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args(argv)
    term, size = args.question

    from scipy import stats

    from octoroach_model.diagnosis.causes import CANDIDATES
    from octoroach_model.diagnosis.decide import decision_z
    from octoroach_model.diagnosis.live import Question
    from octoroach_model.studies.plan import default_spec
    from octoroach_model.studies.plan_model import (
        check_task, PILOTS, pilot_task, PredictedCurve, Status)
    from octoroach_model.studies.summary import wilson
    from octoroach_model.workers import executor_for

    started = time.perf_counter()
    everyone = len(CANDIDATES)
    z_bound, z_test = decision_z(0.05, everyone), float(stats.norm.isf(0.01 / everyone))
    spec = default_spec(term, size)
    with executor_for(None, args.workers) as pool:
        pilots = [future.result()[0] for future in [
            pool.submit(pilot_task, spec, Question(term, size), replicate, PILOT_RUNS)
            for replicate in range(PILOTS)]]
        runs = args.runs or int(PredictedCurve(pilots, z_bound, z_test).runs_for(
            0.8, 0.0, 40, 2000))
        bound = sum(model.bound_power(runs, z_bound) for model in pilots) / len(pilots)
        test = sum(model.test_power(runs, z_test) for model in pilots) / len(pilots)
        print(f'{term} at {size:g}, {runs} runs: the pilots predict the size bound clears its '
              f'floor with {bound:.2f}, the held-out test passes with {test:.2f}, named '
              f'{bound * test:.2f}')
        powers = [future.result() for future in [
            pool.submit(averaged_test, term, size, runs, replicate,
                        model.estimate_at(runs // 2).se, z_test)
            for replicate, model in enumerate(pilots)]]
        print('the held-out test by the expected t (normal approximation): '
              f'{sum(p for p, _ in powers) / len(powers):.2f} at the true size, '
              f'{sum(p for _, p in powers) / len(powers):.2f} averaged over the error of the '
              f"size fitted (the pilots' standard errors at {runs // 2} runs: "
              + ', '.join(f'{model.estimate_at(runs // 2).se:.2f}' for model in pilots) + ')')
        print('| check | size fitted (se) | bound clears | test z (critical) | named |')
        print('| --- | --- | --- | --- | --- |')
        results = []
        for future in [pool.submit(check_task, spec, Question(term, size), runs,
                                   FIRST_CHECK + index)
                       for index in range(args.checks)]:
            result = future.result()
            if result.status != Status.OK:
                print(f'| {result.replicate} | failed: {result.note} | | | |', flush=True)
                continue
            results.append(result)
            print(f'| {result.replicate} | {result.estimate:+.2f} ({result.se:.2f}) | '
                  f'{"yes" if result.clears_floor else "no"} | {result.test_z:.2f} '
                  f'({result.test_critical_z:.2f}) | {"yes" if result.named else "no"} |',
                  flush=True)

    def share(flags: list[bool]) -> str:
        rate = wilson(sum(flags), len(flags))
        if rate.interval is None:
            return '-'
        return f'{sum(flags)}/{len(flags)} ({rate.interval[0]:.0%}-{rate.interval[1]:.0%})'

    print(f'\nnamed: {share([r.named for r in results])}, predicted {bound * test:.2f}')
    print(f'size bound cleared its floor: {share([r.clears_floor for r in results])}, '
          f'predicted {bound:.2f}')
    print(f'held-out test passed: {share([r.test_passed for r in results])}, '
          f'predicted {test:.2f}')
    above = [r.test_passed for r in results if r.estimate > size]
    below = [r.test_passed for r in results if r.estimate <= size]
    print(f'  where the size fitted lay above {size:g}: {share(above)}; at or below: '
          f'{share(below)}')
    misses = [r for r in results if not r.named]
    by_bound = sum(not r.clears_floor for r in misses)
    by_test = sum(r.clears_floor and not r.test_passed for r in misses)
    print(f'of {len(misses)} misses: {by_bound} the bound, {by_test} the test alone, '
          f'{len(misses) - by_bound - by_test} neither (screened, or a gain below its minimum)')
    errors = [(r.estimate - size) / r.se for r in results if r.se > 0 and math.isfinite(r.se)]
    if errors:
        mean = sum(errors) / len(errors)
        spread = math.sqrt(sum((e - mean) ** 2 for e in errors) / max(len(errors) - 1, 1))
        print(f'standardised size errors: mean {mean:+.2f}, spread {spread:.2f} (1 if the '
              f'reported se holds)')
    print(f'{time.perf_counter() - started:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
