"""The diagnosis: what the simulation gets wrong, the cause, the extension and its gain."""
from octoroach_model.diagnosis.diagnose import DiagnosisSettings, diagnose
from octoroach_model.diagnosis.report import write_report

__all__ = ['DiagnosisSettings', 'diagnose', 'write_report']
