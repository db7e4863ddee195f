"""
Where a whole diagnosis's CPU goes: the detection limits, cause by cause, against the race.

Diagnoses the reference data in bags/ (500 runs) in this process (workers=1, so that every
task of the pool runs here and its CPU seconds are its own) at the default settings, the
detection limits and the paper's validations included, and prints the CPU seconds of each
kind of task `diagnose` hands its pool (diagnosis/diagnose.py): the baseline, the race's
candidates, the final refit, the validations, the detection limits (one row per cause), and
what the adequacy check computes in the main process. A diagnosis with two workers runs these
side by side, so its wall time is about half their sum.

Why it is here: issue 26 asks for a diagnosis of 500 runs in 3 s, and `bench_fit_cost.py`
times a diagnosis without limits; this says how much of the whole the limits are, and which
(docs/diagnosis.md, section 11, "Where the time goes").

Run: .venv/bin/python benchmarks/bench_diagnosis_tasks.py [--seed S]
"""
from __future__ import annotations

import argparse
from collections import defaultdict
import importlib
from pathlib import Path
import time
from typing import Any, Callable

REPO = Path(__file__).resolve().parents[1]
# diagnose.py's functions that run as pool tasks or in the main process (the scoring of each
# step's chosen model, the adequacy check), in the order a diagnosis first calls them
TASKS = ('fit_baseline', 'score_held_out', 'evaluate_candidate', '_final_fit',
         'paper_validation', '_limit', 'discrepancies', 'fit_errors')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seed', type=int, default=1, help='the diagnosis seed')
    arguments = parser.parse_args(argv)

    from octoroach_model.diagnosis import DiagnosisSettings
    from octoroach_model.recordings import load_measured

    # the module, not the function the package exports under the same name
    module = importlib.import_module('octoroach_model.diagnosis.diagnose')
    seconds: dict[str, float] = defaultdict(float)      # CPU seconds of each task
    calls: dict[str, int] = defaultdict(int)
    limit_seconds: dict[str, float] = {}                 # _limit's, cause by cause
    depth = [0]     # a task called inside another (a candidate scores its model) is the outer's

    def timed(name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any, **options: Any) -> Any:
            if depth[0]:
                return function(*args, **options)
            depth[0] += 1
            started = time.process_time()
            try:
                result = function(*args, **options)
            finally:
                depth[0] -= 1
            spent = time.process_time() - started
            seconds[name] += spent
            calls[name] += 1
            if name == '_limit':        # _limit(halves, model, evaluation, ...)
                limit_seconds[args[2].cause] = spent
            return result
        return run

    measured = load_measured([REPO / 'bags'])
    originals = {name: getattr(module, name) for name in TASKS}
    for name, function in originals.items():
        setattr(module, name, timed(name, function))
    try:
        started, wall = time.process_time(), time.perf_counter()
        report = module.diagnose(measured, DiagnosisSettings(seed=arguments.seed, workers=1))
        total, wall = time.process_time() - started, time.perf_counter() - wall
    finally:
        for name, function in originals.items():
            setattr(module, name, function)
    print(f'diagnosis of {measured.n_paths} runs in one process (limits and validations '
          f'included): {total:.1f} CPU-s, {wall:.1f} s wall; causes named: '
          f'{", ".join(cause.cause for cause in report.causes) or "none"}')
    rows = [('detection limits, all' if name == '_limit' else name, calls[name], value)
            for name, value in seconds.items()]
    rows += [(f'limit of {cause}', 1, value) for cause, value in
             sorted(limit_seconds.items(), key=lambda item: -item[1])]
    rows.append(('the rest of diagnose (features of the runs, the split, the choices between '
                 'steps)', 0, total - sum(seconds.values())))
    print('| task | calls | CPU, s | share |')
    print('| --- | --- | --- | --- |')
    for label, count, value in rows:
        print(f'| {label} | {count or ""} | {value:.1f} | {100 * value / total:.0f} % |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
