"""
A pytest plugin for `bench_path_refits.py`: what a screen before a path cause's refit would see.

Loaded with `-p suite_path_refits` (benchmarks/ on PYTHONPATH). With OCTOROACH_PATH_REFITS
naming a folder, every time a race weighs a path cause of the table (lateral_slip,
speed_decay) not yet in its model, one JSON line is appended to its process's file there: the
test, the cause, the step's decision z and the cause's floor; the size and standard error its
signature reads at each start of the refit (`modelfit.geometry_starts`, the cause set to zero:
what a screen before the refit could use); the refit's size, standard error and whether its
bound cleared the floor; which start's end the refit kept (`modelfit.best_valley`); and the
refit's seconds. Without the variable the plugin changes nothing.
"""
from __future__ import annotations

import importlib
import os
import time
from typing import Any

from suite_records import append, current_test

VARIABLE = 'OCTOROACH_PATH_REFITS'


def pytest_configure(config) -> None:
    folder = os.environ.get(VARIABLE)
    if not folder:
        return
    diagnose = importlib.import_module('octoroach_model.diagnosis.diagnose')
    modelfit = importlib.import_module('octoroach_model.diagnosis.modelfit')
    from octoroach_model.diagnosis.causes import BY_NAME, EstimateKind
    from octoroach_model.diagnosis.decide import judge

    evaluate, best_valley = diagnose.evaluate_candidate, modelfit.best_valley
    kept: list[int] = []

    def keeping(simulator: Any, fits: Any, settings: Any) -> Any:
        chosen = best_valley(simulator, fits, settings)
        kept.append(next(index for index, fit in enumerate(fits) if fit is chosen))
        return chosen

    def recorded(halves: Any, current: Any, current_scores: Any, cause: str, settings: Any,
                 z_decision: float = 0.0) -> Any:
        candidate = BY_NAME[cause]
        if candidate.is_extension or candidate.kind != EstimateKind.PATH \
                or cause in current.causes:
            return evaluate(halves, current, current_scores, cause, settings, z_decision)
        train, fit = halves.train, settings.fit()
        simulator = modelfit.Simulator(train, settings.seed)
        zero = modelfit.at_size(candidate, 0.0, None, train)
        starts = [modelfit.signature_estimate(simulator, start.with_effect(cause, zero),
                                              candidate, fit)
                  for start in modelfit.geometry_starts(
                      simulator, current.with_effect(cause, zero), [cause], fit)]
        kept.clear()
        started = time.perf_counter()
        evaluation = evaluate(halves, current, current_scores, cause, settings, z_decision)
        seconds = time.perf_counter() - started
        estimate = evaluation.estimates[cause]
        floor = candidate.floor(halves.run_scale)
        append(folder, {
            'test': current_test(), 'cause': cause, 'terms_in': len(current.causes),
            'z': z_decision, 'floor': floor,
            'starts': [[start.size, start.se] for start in starts],
            'size': estimate.size, 'se': estimate.se,
            'cleared': judge(estimate, floor, z_decision).clears_floor,
            'kept': list(kept), 'seconds': seconds})
        return evaluation

    modelfit.best_valley = keeping
    diagnose.evaluate_candidate = recorded
