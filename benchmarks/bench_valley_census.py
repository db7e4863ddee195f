"""
How often the baseline's starts end in more than one valley: a census over a study's nulls.

For each null data set of a study spec (default: studies/adequacy_few_runs.yaml, every
replicate and run count) it fits the baseline as the diagnosis does (calibration half; the
quick fit's angles and their swapped pairs at the runs' spread, `diagnose.fit_baseline`) and
prints how many starts ended in another valley (`modelfit.distinct_geometries`), with the
costs. Only those data sets carry rivals in the adequacy check (since 902e7ac) and a final fit
from each valley (`diagnose.final_starts`): elsewhere the diagnosis is what it was before
either, so a study's rows for the other data sets stand when only that part changed.

Minutes on one idle core: 0.2-3 a data set (a fast robot of long runs the longest); run two
processes on disjoint --replicates ranges to use both cores.
Run: .venv/bin/python benchmarks/bench_valley_census.py [--spec studies/adequacy_few_runs.yaml]
     [--replicates 0-23] [--runs 40 100]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import time

REPO = Path(__file__).resolve().parents[1]


def replicate_range(text: str) -> range:
    """Parse 'A-B' (both included) or 'A' into a range of replicates."""
    first, _, last = text.partition('-')
    return range(int(first), int(last or first) + 1)


def main(argv: list[str] | None = None) -> int:
    """Print one row per null data set and a count of those with another valley; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--spec', type=Path,
                        default=REPO / 'studies' / 'adequacy_few_runs.yaml')
    parser.add_argument('--replicates', type=replicate_range, default=None,
                        help='A-B, both included (default: all of the spec)')
    parser.add_argument('--runs', type=int, nargs='*', default=None,
                        help='run counts (default: all of the spec)')
    args = parser.parse_args(argv)

    from octoroach_model.diagnosis.diagnose import fit_baseline, halves_as_diagnosed
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import build_tasks, draw_robot
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(args.spec)
    tasks = [task for task in build_tasks(spec) if task.arm.kind == 'null'
             and task.runs_cell is not None
             and (args.replicates is None or task.replicate in args.replicates)
             and (not args.runs or task.runs_cell in args.runs)]
    print(f'{spec.name}: {len(tasks)} null data sets\n')
    print('| replicate | runs | stride Hz | cycles | sample Hz | spread | other valleys '
          '| seconds |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- |')
    found = 0
    for task in sorted(tasks, key=lambda task: (task.replicate, task.runs_cell or 0)):
        started, runs = time.perf_counter(), task.runs_cell or 0
        robot = draw_robot(spec, task.replicate)
        measured = study.simulate_data(spec, robot, runs, {}).paths
        settings = replace(study.task_settings(task, spec, robot.data_seed), workers=1)
        baseline = fit_baseline(halves_as_diagnosed(measured, settings), settings)
        others = len(baseline.alternatives)
        found += others > 0
        print(f'| {task.replicate} | {runs} | {robot.stride_frequency_hz:.2f} | '
              f'{robot.cycles:.0f} | {robot.sample_rate_hz:.0f} | {robot.spread_scale:.2f} | '
              f'{others} | {time.perf_counter() - started:.0f} |', flush=True)
    print(f'\n{found} of {len(tasks)} data sets have a start that ends in another valley')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
