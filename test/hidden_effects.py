"""
What the tests that hide effects in data share: the suite seed and their diagnosis settings.

`FEW_SIMULATED_RUNS` is for the tests of machinery (a study's table, a plan, a resumed study,
a reproducible report): they need a diagnosis to run, not its precision.

`SEED` is the suite's (pytest's header; `OCTOROACH_TEST_SEED=N make test` replays a run).
`FAST` diagnoses with fewer simulated runs than the library's defaults, so that the suite
stays within its minutes: a mean path of 120 simulated runs (300 by default) is a geometry
refit's main cost, and its simulation noise is in the fitted sizes' standard errors (at 120
instead of 200 the hidden-effect tests passed at suite seeds 4242, 523917, 2026 and 320706,
in about four fifths of the time). The detection limits are the report's, checked in the
report test, and the others need not pay them.

`WEAR_SETTINGS` is FAST with the library's moment_runs (400, not 300), for the leg-wear tests:
the sizes they hide are 1.3-2.6 times the limits the reports gave at the library's settings,
and a simulated trend point's own noise is about a third of a leg term's variance. At suite
seed 168603, phi1 worn +19.4 deg was read +11.9 with an error of 3.95 deg, 1.9-2.3 of it the
simulated point's at 300 runs; its size bound was 0.91 for a floor of 1 and nothing was
named. At 400 it is named at +14.5 (+8.1 to +20.9), as with all the defaults.
"""
from __future__ import annotations

from dataclasses import replace
import os
import random

from octoroach_model.diagnosis import DiagnosisSettings

SEED = int(os.environ.get('OCTOROACH_TEST_SEED', random.SystemRandom().randrange(10 ** 6)))
FEW_SIMULATED_RUNS = {'score_runs': 120, 'moment_runs': 60, 'mean_path_runs': 50,
                      'bootstrap': 10}
FAST = DiagnosisSettings(validate_models=False, score_runs=800, moment_runs=300,
                         mean_path_runs=120, bootstrap=60, workers=1, detection_limits=False)
WEAR_SETTINGS = replace(FAST, moment_runs=DiagnosisSettings().moment_runs)
