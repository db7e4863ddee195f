"""`diagnose`: the main job, from measured runs to report.json, summary.md and plots."""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import sys

from octoroach_model.commands.common import (
    add_input_arguments, new_output, nonnegative_int, OneLineParser, positive_int,
    progress_printer, read_options)


def parser() -> argparse.ArgumentParser:
    """Build the `diagnose` command line."""
    result = OneLineParser(
        prog='diagnose', description='The main job: calibrates the paper model on measured '
        'runs, shows where it disagrees with them, names the causes, extends the model with '
        'them and measures the gain on held-out runs. Writes DIR/report.json, DIR/summary.md '
        'and PNG plots.')
    add_input_arguments(result)
    result.add_argument('--out', type=Path, required=True,
                        help='directory for the report (new, or an existing empty one)')
    result.add_argument('--seed', type=nonnegative_int, default=0,
                        help='seed of the split, the simulations and the bootstrap')
    result.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    result.add_argument('--workers', type=positive_int, default=2,
                        help='processes for the side-by-side work (1: this process only)')
    return result


def run(args: argparse.Namespace) -> int:
    """Diagnose and write the report; prints where it is."""
    from octoroach_model.diagnosis import DiagnosisSettings, diagnose, write_report
    from octoroach_model.recordings import load_measured

    new_output(args.out, '--out', directory_ok=True)
    if args.out.is_dir() and any(args.out.iterdir()):
        from octoroach_model.errors import ParameterError
        raise ParameterError(f'--out {args.out} is a directory that is not empty; '
                             f'choose a new or empty one')
    measured = load_measured(args.bags, options=read_options(args), gap_s=args.gap_s)
    report = diagnose(measured, DiagnosisSettings(seed=args.seed, workers=args.workers),
                      progress=progress_printer('diagnose'))
    report = replace(report, sources=tuple(str(path) for path in args.bags))
    written = write_report(report, args.out, measured=measured, plots=not args.no_plots)
    named = ', '.join(cause.cause for cause in report.causes) or 'none'
    sys.stderr.write(f'causes: {named}; adequate: {str(report.adequate).lower()}\n')
    print(f'report: {written["report"]}')
    print(f'summary: {written["summary"]}')
    return 0
