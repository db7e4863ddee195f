"""The diagnosis: what the simulation gets wrong, the causes, the extension and its gain."""
from octoroach_model.diagnosis.diagnose import diagnose, DiagnosisSettings
from octoroach_model.diagnosis.report import DiagnosisReport, summary_text, write_report

__all__ = ['DiagnosisReport', 'DiagnosisSettings', 'diagnose', 'summary_text', 'write_report']
