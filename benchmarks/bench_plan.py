"""
`plan` by the calibrated power model against `plan --method simulate`, the reference.

Three parts:

- `--compare` (default): for each case (a term and a size, Table II's robot), the answer of
  `plan` (the model, two local workers) and of `plan --method simulate` (two local Dask
  workers), each with its 95 % interval and wall time, side by side. The simulated plans take
  minutes each: their answers are kept in out/bench_plan/CASE.json and reused while the
  package's code is the same (`--fresh` runs them again); the model's are measured anew on
  every call.
- `--evidence CASE N1,N2 R`: R more data sets diagnosed in full at run counts N1, N2 (new
  replicates, seeds the plans did not use): the share named at each with its Wilson
  interval, for a case where the two answers disagree.
- `--calibrate`: the calibration of the power model (diagnosis/power.py): for each term at
  one size, the pilots' prediction of the runs for 80 % power, and K simulated checks (the
  term's first step, the diagnosis's levels) at that count; prints the counts per term
  (what power.CALIBRATION_COUNTS holds) and the named share per calibration group.

Run: .venv/bin/python benchmarks/bench_plan.py [--compare [CASE ...]] [--fresh]
     [--evidence CASE N1,N2 R] [--calibrate [--checks K] [--terms TERM ...]] [--workers N]
CASE is TERM=SIZE, e.g. persistent_turning=3.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import json
import math
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / 'out' / 'bench_plan'
CASES = ('persistent_turning=3', 'lateral_slip=0.4', 'initial_pose_error=0.8',
         'run_order_drift:yaw_rate=4')
# one size per term for --calibrate: the pilots' 80 % point at 100-300 runs
CALIBRATION_SIZES = {
    'initial_pose_error': 0.8, 'measurement_noise': 0.0103, 'gait_frequency_variation': 0.01,
    'speed_decay': 0.04, 'lateral_slip': 0.4, 'persistent_turning': 3.0,
    'run_order_drift:stride_frequency': 0.012, 'run_order_drift:yaw_rate': 4.0,
    'run_order_drift:lateral_velocity': 0.6, 'heading_random_walk': 1.5,
    'periodic_heading': 1.5, 'change_point': 0.05, 'run_mixture': 8.0, 'yaw_rate_ramp': 5.0,
    'run_order_drift:touchdown_angle_1': 12.0, 'run_order_drift:touchdown_angle_2': 11.0,
    'run_order_drift:touchdown_angle_3': 9.0, 'run_order_drift:touchdown_angle_4': 14.0}


def package_fingerprint() -> str:
    """
    Return a digest of the package's source: a kept answer is reused only under the same code.

    The answers kept in out/bench_plan come from minutes of diagnoses; read back after a
    change of the package they would print its former behaviour as its present one.
    """
    import hashlib

    digest = hashlib.sha256()
    package = REPO / 'octoroach_model'
    for path in sorted(package.rglob('*.py')):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def kept_answer(path: Path, **fields: object) -> dict | None:
    """Return the answer kept at `path` if it was measured with this code and `fields`."""
    if not path.exists():
        return None
    entry: dict = json.loads(path.read_text())
    wanted = {'package': package_fingerprint(), **fields}
    return entry if all(entry.get(key) == value for key, value in wanted.items()) else None


def keep_answer(path: Path, entry: dict) -> None:
    """Write `entry` to `path` with this code's fingerprint, whole or not at all."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + '.partial')
    partial.write_text(json.dumps({**entry, 'package': package_fingerprint()}, indent=2) + '\n')
    partial.replace(path)


def case_of(text: str) -> tuple[str, float]:
    term, _, size = text.partition('=')
    return term, float(size)


def plan_model(term: str, size: float, workers: int) -> dict:
    """Run `plan` (the model) as a user would, in a process of its own; answer and time."""
    import subprocess

    started = time.perf_counter()
    done = subprocess.run([sys.executable, '-m', 'octoroach_model', 'plan', '--cause', term,
                           '--size', repr(size), '--workers', str(workers)],
                          capture_output=True, text=True, cwd=REPO, check=True)
    answer = json.loads(done.stdout)
    answer['wall_s'] = time.perf_counter() - started
    return answer


def plan_simulated(term: str, size: float, workers: int, fresh: bool) -> dict:
    """Run (or read back) `plan --method simulate` for the case."""
    import octoroach_model as om

    path = OUT / f'{term.replace(":", ".")}={size:g}.json'
    kept = None if fresh else kept_answer(path)
    if kept is not None:
        return kept
    started = time.perf_counter()
    result = om.plan_runs(term, size, method='simulate', workers=workers)
    answer = json.loads(__import__('octoroach_model.jsonio', fromlist=['dumps']).dumps(result))
    answer['wall_s'] = time.perf_counter() - started
    keep_answer(path, answer)
    return answer


def _answer_text(answer: dict) -> str:
    needed = answer['runs_needed']
    low, high = answer['runs_needed_interval_95']
    if needed is None:
        return answer['status']
    return f'{needed} ({_n(low)}-{_n(high)})'


def _wall(answer: dict) -> float:
    return float(answer.get('wall_s') or answer['elapsed_s'])


def _n(value: float | None) -> str:
    return 'inf' if value is None else f'{value:.0f}'


def compare(cases: list[str], workers: int, fresh: bool) -> None:
    """Print the README table: both answers and their times, case by case."""
    rows = []
    for text in cases:
        term, size = case_of(text)
        simulated = plan_simulated(term, size, workers, fresh)
        model = plan_model(term, size, workers)
        low, high = simulated['runs_needed_interval_95']
        inside = (model['runs_needed'] is not None and low is not None and high is not None
                  and low <= model['runs_needed'] <= high)
        rows.append((term, size, model, simulated, inside))
        print(f'{term}={size:g}: model {_answer_text(model)} in {model["wall_s"]:.1f} s, '
              f'simulate {_answer_text(simulated)} in {_wall(simulated):.0f} s',
              file=sys.stderr, flush=True)
    print('| term, size | plan (model): runs (95 %) | time | checks named | plan --method '
          "simulate: runs (95 %) | time | model inside simulate's interval |")
    print('| --- | --- | --- | --- | --- | --- | --- |')
    for term, size, model, simulated, inside in rows:
        checks = [check for check in model.get('checks') or [] if check['status'] == 'ok']
        print(f'| {term} = {size:g} | {_answer_text(model)} | {model["wall_s"]:.1f} s | '
              f'{sum(check["named"] for check in checks)}/{len(checks)} | '
              f'{_answer_text(simulated)} | {_wall(simulated):.0f} s | '
              f'{"yes" if inside else "no"} |')


def evidence(case: str, counts: list[int], replicates: int, workers: int) -> None:
    """Diagnose `replicates` new data sets at each count in full; print the named shares."""
    from octoroach_model.workers import executor_for
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.plan import _with_runs, default_spec
    from octoroach_model.studies.replicate import run_task
    from octoroach_model.studies.summary import wilson

    term, size = case_of(case)
    first = 100                    # plans use replicates 0-5 (simulate) and 0-30 (model)
    spec = _with_runs(replace(default_spec(term, size), replicates=first + replicates), counts)
    tasks = [task for task in build_tasks(spec) if task.replicate >= first]
    with executor_for(None, workers) as pool:
        rows = [future.result() for future in [pool.submit(run_task, task, spec)
                                               for task in tasks]]
    print(f'{case}: data sets diagnosed in full (replicates {first}-{first + replicates - 1})')
    for runs in counts:
        group = [row for row in rows if row.runs == runs and row.ok]
        rate = wilson(sum(term in row.outcome.named for row in group), len(group))
        low, high = rate.interval or (math.nan, math.nan)
        print(f'  {runs} runs: named in {rate.successes}/{rate.trials} = {rate.rate:.0%} '
              f'({low:.0%}-{high:.0%})')


def calibrate(workers: int, checks: int, terms: list[str]) -> None:
    """
    Measure the power model's calibration (module docstring) and print the counts.

    Each term's outcome is kept in out/bench_plan/calibration/TERM=SIZE.json and reused
    while the package's code, the size and the number of checks stay the same
    (`kept_answer`). `terms`: those measured, in this order.
    """
    from octoroach_model.diagnosis.causes import CANDIDATES
    from octoroach_model.diagnosis.decide import decision_z
    from octoroach_model.workers import executor_for
    from octoroach_model.diagnosis.live import Question
    from octoroach_model.diagnosis.power import calibration_group
    from octoroach_model.studies.plan import default_spec
    from octoroach_model.studies.plan_model import PredictedCurve, check_task, pilot_task, PILOTS
    from octoroach_model.studies.summary import wilson
    from scipy import stats

    everyone = len(CANDIDATES)          # the race's first step, as the diagnosis's levels
    levels = (decision_z(0.05, everyone), float(stats.norm.isf(0.01 / everyone)))
    groups: dict[str, list[bool]] = {}
    counts: dict[str, tuple[int, int]] = {}
    folder = OUT / 'calibration'
    folder.mkdir(parents=True, exist_ok=True)
    print('| term | size | predicted runs for 80 % | checks named |')
    print('| --- | --- | --- | --- |')
    with executor_for(None, workers) as pool:
        for term in terms:
            size = CALIBRATION_SIZES[term]
            kept = folder / f'{term.replace(":", ".")}={size:g}.json'
            entry = kept_answer(kept, checks=checks)
            if entry is None:
                spec = default_spec(term, size)
                question = Question(term, size)
                pilots = [future.result()[0] for future in [
                    pool.submit(pilot_task, spec, question, replicate, 500)
                    for replicate in range(PILOTS)]]
                runs = PredictedCurve(pilots, *levels).runs_for(0.8, 0.0, 40, 2000)
                named: list[bool] = []
                if math.isfinite(runs) and runs > 40:
                    named = [outcome.named for outcome in [future.result() for future in [
                        pool.submit(check_task, spec, question, int(runs), 1000 + replicate)
                        for replicate in range(checks)]] if outcome.status == 'ok']
                entry = {'term': term, 'size': size, 'runs': runs, 'checks': checks,
                         'named': named}
                keep_answer(kept, entry)
            named = entry['named']
            if not named:
                print(f'| {term} | {size:g} | {entry["runs"]:.0f} | (not checked: at a '
                      f'bound) |')
                continue
            groups.setdefault(calibration_group(term), []).extend(named)
            counts[term] = (sum(named), len(named))
            print(f'| {term} | {size:g} | {entry["runs"]:.0f} | {sum(named)}/{len(named)} |',
                  flush=True)
    print('\nCALIBRATION_COUNTS (named, checks) at a predicted 80 %, per term:')
    for term, (named_count, total) in counts.items():
        print(f"    '{term}': ({named_count}, {total}),")
    print('\nper group (power.group_counts):')
    for group, named in groups.items():
        rate = wilson(sum(named), len(named))
        assert rate.rate is not None and rate.interval is not None
        print(f"    '{group}': ({sum(named)}, {len(named)}),   # {rate.rate:.0%} "
              f'({rate.interval[0]:.0%}-{rate.interval[1]:.0%})')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--compare', nargs='*', default=None, metavar='CASE')
    parser.add_argument('--fresh', action='store_true')
    parser.add_argument('--evidence', nargs=3, default=None, metavar=('CASE', 'COUNTS', 'R'))
    parser.add_argument('--calibrate', action='store_true')
    parser.add_argument('--checks', type=int, default=16)
    parser.add_argument('--terms', nargs='+', default=list(CALIBRATION_SIZES),
                        choices=list(CALIBRATION_SIZES), help='--calibrate: these terms only')
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args(argv)
    if args.calibrate:
        calibrate(args.workers, args.checks, args.terms)
    elif args.evidence:
        case, counts, replicates = args.evidence
        evidence(case, [int(n) for n in counts.split(',')], int(replicates), args.workers)
    else:
        compare(list(args.compare or CASES), args.workers, args.fresh)
    return 0


if __name__ == '__main__':
    sys.exit(main())
