"""
Studies of the diagnosis, on Dask, and `plan`.

A study measures the diagnosis's operating characteristics over many synthetic data sets;
`plan` says how many runs an experiment needs. Uses model/ and diagnosis/; no rclpy.
"""
from octoroach_model.studies.plan import plan_runs, PlanResult
from octoroach_model.studies.spec import load_spec, parse_spec, StudySpec
from octoroach_model.studies.study import run_study, StudyResult

__all__ = ['PlanResult', 'StudyResult', 'StudySpec', 'load_spec', 'parse_spec', 'plan_runs',
           'run_study']
