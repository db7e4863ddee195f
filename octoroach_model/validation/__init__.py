"""The paper's probabilistic validation (eqs. 13-16) and its nominal fit (eq. 9)."""
from octoroach_model.validation.fit import NominalFit, fit_nominal
from octoroach_model.validation.multisample import chernoff_sample_size, disjoint_multisamples
from octoroach_model.validation.region import prediction_region, t_multiplier, violations
from octoroach_model.validation.validate import (
    FourBarModel, ModelPlugin, SearchGrid, SigmaSearch, Validation, ValidationResult,
    ValidationSettings, guarantee_text, search_sigmas, validate, validate_measured)

__all__ = ['FourBarModel', 'ModelPlugin', 'NominalFit', 'SearchGrid', 'SigmaSearch',
           'Validation', 'ValidationResult', 'ValidationSettings', 'validate_measured', 'chernoff_sample_size', 'disjoint_multisamples',
           'fit_nominal', 'guarantee_text', 'prediction_region', 'search_sigmas',
           't_multiplier', 'validate', 'violations']
