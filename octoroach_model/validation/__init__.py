"""The paper's probabilistic validation (eqs. 13-16); its nominal fit (eq. 9) is fitting/'s."""
from octoroach_model.validation.multisample import chernoff_sample_size, disjoint_multisamples
from octoroach_model.validation.region import prediction_region, t_multiplier, violations
from octoroach_model.validation.validate import (
    FourBarModel, guarantee_text, ModelPlugin, search_sigmas, SearchGrid, SigmaSearch, validate,
    validate_measured, Validation, ValidationResult, ValidationSettings)

__all__ = ['FourBarModel', 'ModelPlugin', 'SearchGrid', 'SigmaSearch',
           'Validation', 'ValidationResult', 'ValidationSettings', 'validate_measured',
           'chernoff_sample_size', 'disjoint_multisamples', 'guarantee_text',
           'prediction_region', 'search_sigmas', 't_multiplier', 'validate', 'violations']
