"""
Fitting the model to measured runs: the nominal fit (eq. 9) and the machinery it shares.

Used by the validation (the nominal geometry) and by the diagnosis (geometry with causes);
it imports neither. gait: stride frequency and sway seen in poses; target: what a fit
matches and its residuals; nominal: the nominal fit; covariance: its vector's covariance
without refitting; lines: sizes read off lines through simulated points.
"""
from octoroach_model.fitting.nominal import (
    fit_nominal, FreeEffect, MeanPathSettings, NominalFit, NominalFitSettings)
from octoroach_model.fitting.target import mean_start_pose

__all__ = ['fit_nominal', 'FreeEffect', 'MeanPathSettings', 'mean_start_pose', 'NominalFit',
           'NominalFitSettings']
