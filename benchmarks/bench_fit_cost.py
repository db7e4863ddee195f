"""
Where a diagnosis's time goes: the geometry fits, and within them the Jacobians.

Diagnoses the reference data in bags/ (500 runs) in this process (workers=1, so that every
fit is seen) with the default settings, no detection limits and no validations (they decide
nothing; `bench_diagnose.py` times the whole job), and counts, for every least-squares solve
of the nominal and geometry fits: the residual evaluations (each the mean path and gait of
simulated runs), how many of them went into forward-difference Jacobians, and their time.

Why it is here: issue 26 asks for a diagnosis in seconds, and this says what a faster
geometry fit would have to remove (docs/diagnosis.md, section 11, lists what was tried).

Run: .venv/bin/python benchmarks/bench_fit_cost.py [--runs N] [--seed S]
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--runs', type=int, default=500,
                        help='diagnose the first N runs of bags/ (default 500)')
    parser.add_argument('--seed', type=int, default=1, help='the diagnosis seed')
    arguments = parser.parse_args(argv)

    import numpy as np
    from scipy import optimize

    from octoroach_model.diagnosis import DiagnosisSettings, diagnose
    from octoroach_model.fitting import nominal
    from octoroach_model.recordings import load_measured

    measured = load_measured([REPO / 'bags'])
    measured = measured.subset(np.arange(min(arguments.runs, measured.n_paths)))
    solves: list[dict[str, float]] = []
    least_squares = optimize.least_squares

    def counted(fun, x0, **options):         # type: ignore[no-untyped-def]
        calls = {'evaluations': 0, 'seconds': 0.0}

        def residuals(vector):               # type: ignore[no-untyped-def]
            started = time.perf_counter()
            values = fun(vector)
            calls['seconds'] += time.perf_counter() - started
            calls['evaluations'] += 1
            return values

        started = time.perf_counter()
        result = least_squares(residuals, x0, **options)
        solves.append({'parameters': len(x0), 'evaluations': calls['evaluations'],
                       'in_jacobians': calls['evaluations'] - result.nfev,
                       'iterations': result.njev, 'seconds': time.perf_counter() - started,
                       'residual_seconds': calls['seconds']})
        return result

    # scipy's own: only the nominal and geometry fits (fitting/nominal.py) call it
    nominal.optimize.least_squares = counted
    try:
        started = time.perf_counter()
        report = diagnose(measured, DiagnosisSettings(seed=arguments.seed, workers=1,
                                                      validate_models=False,
                                                      detection_limits=False))
        total = time.perf_counter() - started
    finally:
        nominal.optimize.least_squares = least_squares
    evaluations = sum(solve['evaluations'] for solve in solves)
    in_jacobians = sum(solve['in_jacobians'] for solve in solves)
    fit_seconds = sum(solve['seconds'] for solve in solves)
    print(f'diagnosis of {measured.n_paths} runs in one process (no limits, no validations): '
          f'{total:.1f} s')
    print('| measure | value |')
    print('| --- | --- |')
    print(f'| least-squares solves (nominal and geometry fits) | {len(solves)} |')
    print(f'| their time | {fit_seconds:.1f} s ({100 * fit_seconds / total:.0f} % of the '
          'diagnosis) |')
    print(f'| residual evaluations | {evaluations} ({evaluations / max(len(solves), 1):.0f} '
          'a solve) |')
    print(f'| of them for forward-difference Jacobians | {in_jacobians} '
          f'({100 * in_jacobians / max(evaluations, 1):.0f} %) |')
    print(f'| iterations (Jacobians) a solve, median | '
          f'{np.median([solve["iterations"] for solve in solves]):.0f} |')
    print(f'| time of one evaluation, median | '
          f'{1000 * np.median([s["residual_seconds"] / s["evaluations"] for s in solves]):.1f}'
          ' ms |')
    print('causes: ' + (', '.join(c.cause for c in report.causes) or 'none')
          + '; extensions: ' + (', '.join(e.family for e in report.extensions) or 'none'))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
