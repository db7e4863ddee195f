"""
octoroach_model: the OctoRoACH's stochastic kinematic model, validated and diagnosed.

>>> import octoroach_model as om
>>> paths = om.simulate(10, seed=0)
>>> paths.t.shape, paths.poses.shape
((251,), (10, 251, 3))
"""
from octoroach_model.errors import BagError, DataError, OctoroachError, ParameterError
from octoroach_model.model import (
    EFFECT_NAMES, EFFECT_PARAMETERS, ModelParameters, simulate)
from octoroach_model.paths import Paths

__all__ = ['EFFECT_NAMES', 'EFFECT_PARAMETERS', 'BagError', 'DataError', 'ModelParameters',
           'OctoroachError', 'ParameterError', 'Paths', 'simulate']
__version__ = '0.1.0'

# The heavier layers load on first use, so `import octoroach_model` stays quick.
_LAZY = {
    'validate': 'octoroach_model.validation', 'ValidationSettings': 'octoroach_model.validation',
    'FourBarModel': 'octoroach_model.validation', 'fit_nominal': 'octoroach_model.fitting',
    'diagnose': 'octoroach_model.diagnosis', 'DiagnosisSettings': 'octoroach_model.diagnosis',
    'write_report': 'octoroach_model.diagnosis', 'load_measured': 'octoroach_model.recordings',
    'read_runs': 'octoroach_model.recordings', 'write_paths_bag': 'octoroach_model.recordings',
    'save_dataset': 'octoroach_model.recordings', 'load_dataset': 'octoroach_model.recordings',
    'run_study': 'octoroach_model.studies', 'plan_runs': 'octoroach_model.studies',
    'load_spec': 'octoroach_model.studies',
}
__all__ += sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
