"""
The paper's switching four-bar model, its stochastic version and the causes' effects.

Plain numpy; imports nothing from the rest of the package but `paths`, `errors` and `arrays`.
"""
from octoroach_model.model.effects import (
    check_effects, EFFECT_NAMES, EFFECT_PARAMETERS, PARAMETER_RANGES)
from octoroach_model.model.parameters import (
    load_nominal, ModelParameters, nominal_sigmas, NominalValues)
from octoroach_model.model.simulate import DRAWS, model_poses, RandomStreams, simulate

__all__ = ['DRAWS', 'EFFECT_NAMES', 'EFFECT_PARAMETERS', 'PARAMETER_RANGES', 'ModelParameters',
           'NominalValues', 'RandomStreams', 'check_effects', 'load_nominal', 'model_poses',
           'nominal_sigmas', 'simulate']
