"""octoroach_model: the OctoRoACH's stochastic kinematic model, validated and diagnosed.

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
