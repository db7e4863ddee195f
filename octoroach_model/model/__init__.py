"""The paper's switching four-bar model, its stochastic version and the contract's effects.

Plain numpy; imports nothing from the rest of the package but `paths` and `errors`.
"""
from octoroach_model.model.effects import (
    EFFECT_NAMES, EFFECT_PARAMETERS, PARAMETER_RANGES, check_effects)
from octoroach_model.model.parameters import ModelParameters, nominal_sigmas
from octoroach_model.model.simulate import DRAWS, RandomStreams, model_poses, simulate

__all__ = ['DRAWS', 'EFFECT_NAMES', 'EFFECT_PARAMETERS', 'PARAMETER_RANGES', 'ModelParameters',
           'RandomStreams', 'check_effects', 'model_poses', 'nominal_sigmas', 'simulate']
