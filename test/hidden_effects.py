"""
What the tests that hide effects in data share: the suite seed and their diagnosis settings.

`SEED` is the suite's (pytest's header; `OCTOROACH_TEST_SEED=N make test` replays a run).
`FAST` diagnoses with fewer simulated runs than the library's defaults, so that the suite
stays within its minutes; the detection limits are the report's, checked in the report test,
and the others need not pay them.
"""
from __future__ import annotations

import os
import random

from octoroach_model.diagnosis import DiagnosisSettings

SEED = int(os.environ.get('OCTOROACH_TEST_SEED', random.SystemRandom().randrange(10 ** 6)))
FAST = DiagnosisSettings(validate_models=False, score_runs=800, moment_runs=300,
                         mean_path_runs=200, bootstrap=60, workers=1, detection_limits=False)
