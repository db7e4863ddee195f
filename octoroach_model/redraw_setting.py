"""
The setting of how many times a diagnosis draws its simulations (diagnosis/redraws.py).

One `Setting` for the library's `DiagnosisSettings`, `diagnose --simulation-draws` and the
validator node's parameter; in a module of its own so that the node's parameters are declared
without loading the diagnosis.
"""
from __future__ import annotations

from octoroach_model.settings import Setting

MAX_DRAWS = 20      # each draw is a diagnosis of its own (without limits and validations)
SIMULATION_DRAWS = Setting(
    'diagnoses of the same halves with the simulations drawn again: the report says how many '
    'named the same terms (1: the decision alone; each further draw costs a diagnosis without '
    'its limits)', low=1, high=MAX_DRAWS)
