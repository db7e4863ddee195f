"""The diagnosis: what the simulation gets wrong, the causes, the extension and its gain."""
from octoroach_model.diagnosis.diagnose import diagnose, DiagnosisSettings
from octoroach_model.diagnosis.records import DiagnosisReport
from octoroach_model.diagnosis.report_files import write_report
from octoroach_model.diagnosis.summary import summary_text

__all__ = ['DiagnosisReport', 'DiagnosisSettings', 'diagnose', 'summary_text', 'write_report']
