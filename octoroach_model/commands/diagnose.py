"""`diagnose`: the main job, from measured runs to report.json, summary.md and plots."""
from __future__ import annotations

import argparse
from collections.abc import Iterator
from concurrent.futures import Executor
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
import sys
import time

from octoroach_model.commands.common import (
    add_input_arguments, add_setting, add_workers_argument, new_output, OneLineParser,
    progress_printer, read_options, reading_progress, say_repeated_runs)
from octoroach_model.workers import default_workers, process_pool


def parser() -> argparse.ArgumentParser:
    """Build the `diagnose` command line (--seed, --simulation-draws: DiagnosisSettings fields)."""
    from octoroach_model.diagnosis import DiagnosisSettings
    from octoroach_model.limit_setting import LIMITS

    result = OneLineParser(
        prog='diagnose', description='The main job: calibrates the paper model on measured '
        'runs, shows where it disagrees with them, names the causes, extends the model with '
        'them and measures the gain on held-out runs. Writes DIR/report.json, DIR/summary.md '
        'and PNG plots, all at once (a stopped run leaves no DIR).')
    add_input_arguments(result)
    result.add_argument('--out', type=Path, required=True,
                        help='directory for the report (new, or an existing empty one)')
    add_setting(result, DiagnosisSettings, 'seed')
    add_setting(result, DiagnosisSettings, 'simulation_draws')
    result.add_argument('--limits', type=limit_choice, default='all', metavar='WHICH',
                        help=LIMITS.help_text())
    result.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    add_workers_argument(result, 'the side-by-side work of the diagnosis')
    return result


def limit_choice(text: str) -> tuple[bool, tuple[str, ...]]:
    """Read --limits (limit_setting.read_limits); argparse says why not, in one line."""
    from octoroach_model.errors import ParameterError
    from octoroach_model.limit_setting import read_limits

    try:
        return read_limits(text)
    except ParameterError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix('limits: ')) from None


@contextmanager
def worker_pool(workers: int) -> Iterator[Executor | None]:
    """
    Yield the executor of `workers` processes (0: None, the diagnosis runs in this process).

    The same meaning as `study --workers`; the pool's processes ignore SIGINT.
    """
    if workers == 0:
        yield None
        return
    with process_pool(workers, command=True) as pool:
        yield pool


def run(args: argparse.Namespace) -> int:
    """Diagnose and write the report; prints where it is."""
    from octoroach_model.diagnosis import DiagnosisSettings, diagnose, write_report
    from octoroach_model.recordings import load_measured

    new_output(args.out, '--out', directory_ok=True)
    settings = DiagnosisSettings(seed=args.seed, simulation_draws=args.simulation_draws,
                                 workers=1, detection_limits=args.limits[0],
                                 limit_terms=args.limits[1])
    reading = time.monotonic()
    measured = load_measured(args.bags, options=read_options(args), gap_s=args.gap_s,
                             progress=reading_progress('diagnose'))
    say_repeated_runs(measured)
    workers = default_workers() if args.workers is None else args.workers
    diagnosing = time.monotonic()
    with worker_pool(workers) as pool:
        report = diagnose(measured, settings, progress=progress_printer('diagnose'),
                          executor=pool)
    read_s = round(diagnosing - reading, 3)
    report = replace(report, sources=tuple(str(path) for path in args.bags),
                     stages_s={'read': read_s, **report.stages_s})
    written = write_report(report, args.out, measured=measured, plots=not args.no_plots)
    named = ', '.join(cause.cause for cause in report.causes) or 'none'
    sys.stderr.write(f'causes: {named}; adequate: {str(report.adequate).lower()}\n')
    print(f'report: {written["report"]}')
    print(f'summary: {written["summary"]}')
    return 0
