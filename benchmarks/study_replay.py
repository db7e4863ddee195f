"""
A study's data set rebuilt as the study built it, and one term weighed as the race weighs it.

For the benchmarks that look inside one row of a study's table (bench_heading_limits,
bench_periodic_misses, bench_seed_agreement): the robot and seed of a replicate, the term at
the size the study put in (read off the null row's limit), the halves the diagnosis splits,
the baseline fitted to the calibration half, the heading wobble chosen, and the term's first
race step.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple


class RaceStep(NamedTuple):
    """One data set as the race's first step weighs one term on it."""

    draw: Any            # the replicate's robot (studies.design.RobotDraw)
    effects: dict[str, dict[str, float]]
    settings: Any
    halves: Any
    baseline: Any
    evaluation: Any
    simulator: Any


class DataSet(NamedTuple):
    """One row's data set as its study built it, and the settings it was diagnosed with."""

    draw: Any            # the replicate's robot (studies.design.RobotDraw)
    effects: dict[str, dict[str, float]]
    measured: Any        # Paths
    settings: Any        # DiagnosisSettings


def rebuilt(spec: Any, task: Any, null_row: Any) -> DataSet:
    """Return `task`'s data set of `spec` (the null row gives a limit multiple's size)."""
    from octoroach_model.studies import replicate as study
    from octoroach_model.studies.design import draw_robot

    draw = draw_robot(spec, task.replicate)
    effects = study.task_effects(task, spec, null_row, draw.duration_s)
    measured = study.simulate_data(spec, draw, task.runs(draw), effects).paths
    return DataSet(draw, effects, measured, study.task_settings(task, spec, draw.data_seed))


def at_its_limit(task: Any, term: str) -> bool:
    """Return whether `task` puts `term` alone at 1x its limit (whatever the arm's sign)."""
    return task.arm.cause == term and task.arm.limit_multiple == 1.0


def race_step(spec_path: Path | Any, replicate: int, term: str, null_row: Any,
              simulation_shift: int = 0, moment_runs: int | None = None) -> RaceStep:
    """
    Rebuild the replicate's data set with `term` at 1x its limit and weigh the term on it.

    `spec_path`: the study's spec file, or the spec itself (a StudySpec).

    `simulation_shift` moves the seed of every simulation (fits, wobble choice, scores) and
    keeps the split of the runs into halves, which the study's seed makes; `moment_runs`
    replaces the study's simulated runs for every statistic matched (the spread scale's too).
    """
    from octoroach_model.diagnosis.diagnose import halves_as_diagnosed
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.spec import load_spec

    spec = load_spec(spec_path) if isinstance(spec_path, (str, Path)) else spec_path
    task = next(task for task in build_tasks(spec)
                if task.replicate == replicate and at_its_limit(task, term))
    draw, effects, measured, settings = rebuilt(spec, task, null_row)
    halves = halves_as_diagnosed(measured, settings)
    settings = replace(settings, seed=settings.seed + simulation_shift,
                       moment_runs=moment_runs or settings.moment_runs)
    halves, baseline, evaluation, simulator = first_step(halves, term, settings)
    return RaceStep(draw, effects, settings, halves, baseline, evaluation, simulator)


def first_step(halves: Any, term: str, settings: Any, z_decision: float = 0.0
               ) -> tuple[Any, Any, Any, Any]:
    """
    Weigh `term` at the race's first step on `halves`, as the race weighs it.

    Returns the halves with the wobble chosen, the baseline fitted to the calibration half,
    the term's Evaluation and the held-out Simulator; `z_decision` is the step's bound
    level, which decides the screen (diagnose.screen).
    """
    from octoroach_model.diagnosis.diagnose import (
        choose_wobble_hz, evaluate_candidate, fit_baseline, score_held_out, with_wobble)
    from octoroach_model.diagnosis.modelfit import Simulator

    baseline = fit_baseline(halves, settings).model
    halves = with_wobble(halves, choose_wobble_hz(halves.train, baseline, settings))
    simulator = Simulator(halves.test, settings.seed)
    scores = score_held_out(simulator, baseline, halves, settings)
    evaluation = evaluate_candidate(halves, baseline, scores, term, settings, z_decision)
    return halves, baseline, evaluation, simulator
