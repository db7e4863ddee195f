"""
A pytest plugin for `bench_decisions.py`: what every diagnosis a test ran decided, and its time.

Loaded with `-p suite_decisions` (benchmarks/ on PYTHONPATH). With OCTOROACH_SUITE_DECISIONS
naming a folder, every call of `octoroach_model.diagnosis.diagnose` made through the package's
public name (`from octoroach_model.diagnosis import diagnose`, `om.diagnose`: the tests' ways)
appends one JSON line to its process's file there: the test, the terms named with their
parameters, whether the model is adequate, and the call's wall time. The package's own calls
(studies, nodes) bind the function inside the package and are not recorded. Without the
variable the plugin changes nothing.
"""
from __future__ import annotations

import functools
import os
import time
from typing import Any

from suite_records import append, current_test

FOLDER_VARIABLE = 'OCTOROACH_SUITE_DECISIONS'


def decision_of(report: Any) -> dict[str, Any]:
    """Return what `report` decided: the causes and extensions named, with their values."""
    from octoroach_model.jsonio import jsonable

    return jsonable({'causes': {cause.cause: cause.parameters for cause in report.causes},
                     'extensions': {term.family: term.parameters
                                    for term in report.extensions},
                     'adequate': report.adequate})


def pytest_configure(config) -> None:
    folder = os.environ.get(FOLDER_VARIABLE)
    if not folder:
        return
    import octoroach_model.diagnosis as package

    original = package.diagnose

    @functools.wraps(original)
    def recorded(*args: Any, **kwargs: Any) -> Any:
        started = time.perf_counter()
        report = original(*args, **kwargs)
        append(folder, {'test': current_test(), 'seconds': time.perf_counter() - started,
                        **decision_of(report)})
        return report

    package.diagnose = recorded
