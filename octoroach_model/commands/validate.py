"""`validate`: the paper's probabilistic validation of measured runs, printed as JSON."""
from __future__ import annotations

import argparse

from octoroach_model.commands.common import (
    add_input_arguments, add_setting, OneLineParser, progress_printer, read_options,
    reading_progress, say_repeated_runs)
from octoroach_model.errors import ParameterError
from octoroach_model.settings import settings_of


def parser() -> argparse.ArgumentParser:
    """
    Build the `validate` command line.

    Its options are the fields of ValidationSettings and of the validator's call
    (`validation_jobs.Job`): the same help, unit, range and default as the node's parameters.
    """
    from octoroach_model.validation import ValidationSettings
    from octoroach_model.validation_jobs import Job

    result = OneLineParser(
        prog='validate', description="The paper's probabilistic validation on measured runs: "
        'fits the nominal model (eq. 9), then finds the widest (sigma1, sigma2) whose '
        'estimated probability of violation stays below rho (eq. 15), or with --sigma1 and '
        '--sigma2 only estimates it there. Prints JSON.')
    add_input_arguments(result)
    add_setting(result, Job, 'min_duration_s')
    for name in settings_of(ValidationSettings):
        add_setting(result, ValidationSettings, name)
    add_setting(result, Job, 'sigma1', default=None)    # not given: search, as negative
    add_setting(result, Job, 'sigma2', default=None)
    add_setting(result, Job, 'nominal')
    add_setting(result, Job, 'draws')
    return result


def run(args: argparse.Namespace) -> int:
    """Validate and print the result as JSON."""
    from octoroach_model.jsonio import dumps
    from octoroach_model.recordings import load_measured
    from octoroach_model.validation import ValidationSettings, validate_measured
    from octoroach_model.validation_jobs import Job

    if (args.sigma1 is None) != (args.sigma2 is None):
        raise ParameterError('give both --sigma1 and --sigma2, or neither')
    settings = ValidationSettings(**{name: getattr(args, name)
                                     for name in settings_of(ValidationSettings)})
    job = Job(sources=tuple(str(path) for path in args.bags), gap_s=args.gap_s,
              min_duration_s=args.min_duration_s, nominal=args.nominal, draws=args.draws,
              sigma1=-1.0 if args.sigma1 is None else args.sigma1,
              sigma2=-1.0 if args.sigma2 is None else args.sigma2, settings=settings)
    sigmas = job.sigmas()      # the ranges are checked: the job's, as the validator node's
    measured = load_measured(args.bags, options=read_options(args), gap_s=args.gap_s,
                             min_duration_s=args.min_duration_s or None,
                             progress=reading_progress('validate'))
    say_repeated_runs(measured)
    result = validate_measured(measured, settings, nominal=args.nominal, draws=args.draws,
                               sigmas=sigmas, sources=list(job.sources),
                               progress=progress_printer('validate'))
    print(dumps(result, indent=2))
    return 0
