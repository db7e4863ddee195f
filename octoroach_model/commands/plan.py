"""`plan`: how many runs an experiment needs to detect a cause of a given size."""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

from octoroach_model.commands.common import (
    add_setting, finite_float, nonnegative_int, OneLineParser, positive_int, Progress)
from octoroach_model.commands.simulate import OrderedEffectAction
from octoroach_model.commands.study import add_where_arguments
from octoroach_model.errors import ParameterError


def parser() -> argparse.ArgumentParser:
    """Build the `plan` command line (the search's options: the fields of PlanSettings)."""
    from octoroach_model.diagnosis.causes import FAMILIES
    from octoroach_model.studies.plan import PlanSettings
    from octoroach_model.studies.terms import TERMS

    result = OneLineParser(
        prog='plan', description='How many runs to record: the number of runs with which the '
        'diagnosis names CAUSE at SIZE with the requested power on a robot (default Table II, '
        '10 cycles at 50 Hz), with its 95 % interval and the power curve it came from. By '
        'default from a calibrated model of the power curve, checked by simulation within '
        '--budget-s seconds; --method simulate diagnoses many data sets on Dask, like a '
        'study (minutes). docs/studies.md says how plan decides. Prints progress lines on '
        'stderr and the answer as JSON; with --out also plan.json, the data sets (checks.csv '
        'or table.csv) and power_curve.png.')
    result.add_argument('--cause', required=True, choices=TERMS, metavar='CAUSE',
                        help='the cause or extension term to detect: a cause of the table, '
                        'or ' + ', '.join(family.name for family in FAMILIES))
    result.add_argument('--size', type=finite_float, required=True,
                        help="size of the cause's main parameter in its unit (e.g. "
                        'yaw_rate_std_deg_s for persistent_turning; for change_point the '
                        "speed factor's distance from 1)")
    add_setting(result, PlanSettings, 'power')
    result.add_argument('--param', action=OrderedEffectAction, dest='effect_param',
                        metavar='KEY=VALUE', help='another parameter of the cause (e.g. '
                        'position_std_cm=0.3 for initial_pose_error); repeatable')
    robot = result.add_argument_group('robot (default Table II)')
    robot.add_argument('--cycles', type=finite_float, default=10.0, help='gait cycles per run')
    robot.add_argument('--stride-frequency-hz', type=finite_float, default=None,
                       help='gait cycles per second (default Table II: 2)')
    robot.add_argument('--sample-rate-hz', type=finite_float, default=None,
                       help='motion-capture rate (default 50)')
    robot.add_argument('--leg-length-cm', type=finite_float, default=None,
                       help='leg length l (default 2.1)')
    robot.add_argument('--touchdown-deg', type=finite_float, nargs=4, default=None,
                       metavar=('PHI1', 'PHI2', 'PHI3', 'PHI4'),
                       help='touchdown angles (default Table II)')
    robot.add_argument('--spread-scale', type=finite_float, default=None,
                       help="multiple of Table III's angle spreads (default 1)")
    search = result.add_argument_group('search')
    add_setting(search, PlanSettings, 'method')
    add_setting(search, PlanSettings, 'budget_s')
    add_setting(search, PlanSettings, 'checks', type=nonnegative_int, metavar='N')
    add_setting(search, PlanSettings, 'replicates')
    search.add_argument('--runs', type=positive_int, nargs='+', default=None, metavar='N',
                        help='for --method simulate: start from these run counts instead of '
                        "the pilot's guess")
    add_setting(search, PlanSettings, 'max_runs')
    add_setting(search, PlanSettings, 'seed')
    add_where_arguments(result)
    result.add_argument('--out', type=Path, default=None, metavar='DIR',
                        help='also write plan.json, the data sets (checks.csv, or table.csv '
                        'for --method simulate) and power_curve.png here')
    return result


def robot_values(args: argparse.Namespace) -> dict:
    """Return the robot keys given on the command line (the rest stay Table II)."""
    values: dict = {'cycles': args.cycles}
    for key, option in (('stride_frequency_hz', 'stride_frequency_hz'),
                        ('sample_rate_hz', 'sample_rate_hz'), ('leg_length_cm', 'leg_length_cm'),
                        ('spread_scale', 'spread_scale')):
        if getattr(args, option) is not None:
            values[key] = getattr(args, option)
    if args.touchdown_deg is not None:
        values['touchdown_angles_deg'] = list(args.touchdown_deg)
    return values


def progress_lines() -> Progress:
    """One stderr line per diagnosed data set, with the time since the start."""
    import time

    started = time.monotonic()

    def report(fraction: float, message: str) -> None:
        sys.stderr.write(f'[plan {time.monotonic() - started:7.1f}s] {message}\n')
        sys.stderr.flush()
    return report


def run(args: argparse.Namespace) -> int:
    """Plan; prints the answer (JSON) and, with --out, where the files are."""
    from octoroach_model.commands.simulate import parse_effects
    from octoroach_model.jsonio import dumps
    from octoroach_model.studies import plan_runs

    pairs = [('effect', args.cause)] + list(getattr(args, 'effect_pairs', None) or [])
    parameters = parse_effects(pairs)[args.cause]
    if args.size <= 0:
        raise ParameterError(f'--size must be positive (a magnitude), got {args.size:g}')
    result = plan_runs(args.cause, args.size, power=args.power, robot=robot_values(args),
                       parameters=parameters, replicates=args.replicates, run_counts=args.runs,
                       max_runs=args.max_runs, seed=args.seed, scheduler=args.scheduler,
                       workers=args.workers, progress=progress_lines(), out=args.out,
                       connect_timeout_s=args.connect_timeout_s, method=args.method,
                       budget_s=args.budget_s, checks=args.checks)
    sys.stderr.write(f'plan: {result.statement}\n')
    print(dumps(result, indent=2))
    return 0
