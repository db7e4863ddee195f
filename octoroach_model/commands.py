"""The offline programs: simulate, validate, diagnose.

Arguments are parsed here and handed to the core; every domain error becomes one line on
stderr and a non-zero exit, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from octoroach_model.errors import DataError, OctoroachError, ParameterError

EXIT_ERROR = 1
EXIT_USAGE = 2


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line (and exit 2), not usage + error."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(EXIT_USAGE, f'error: {self.prog}: {message} (see --help)\n')


def progress_printer(label: str):
    """Progress lines on stderr, at most one per percent step, for long work."""
    state = {'last': -1.0, 'start': time.monotonic()}

    def report(fraction: float, message: str) -> None:
        if fraction - state['last'] >= 0.01 or fraction >= 1.0:
            state['last'] = fraction
            elapsed = time.monotonic() - state['start']
            sys.stderr.write(f'[{label} {fraction * 100:5.1f}% {elapsed:6.1f}s] {message}\n')
            sys.stderr.flush()
    return report


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be a positive whole number, got {text}')
    return value


def finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text}')
    return value


def parse_effects(pairs: list[tuple[str, str]]) -> dict[str, dict[str, float]]:
    """--effect NAME and --effect-param KEY=VALUE, in command-line order: a parameter belongs
    to the --effect before it (or, written NAME.KEY=VALUE, to NAME)."""
    effects: dict[str, dict[str, float]] = {}
    current = None
    for option, value in pairs:
        if option == 'effect':
            current = value
            effects.setdefault(value, {})
            continue
        key, sep, number = value.partition('=')
        if not sep:
            raise ParameterError(f'--effect-param takes KEY=VALUE, got {value!r}')
        name, dot, key = key.rpartition('.')
        name = name if dot else current
        if name is None:
            raise ParameterError(f'--effect-param {value} comes before any --effect NAME')
        try:
            effects.setdefault(name, {})[key] = float(number)
        except ValueError:
            raise ParameterError(f'--effect-param {value}: {number!r} is not a number') from None
    return effects


class OrderedEffectAction(argparse.Action):
    """Keeps --effect and --effect-param in the order they were given."""

    def __call__(self, parser, namespace, values, option_string=None):
        pairs = getattr(namespace, 'effect_pairs', None) or []
        pairs.append((self.dest, values))
        namespace.effect_pairs = pairs


def simulate_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog='simulate', description='Write N runs of the model to a rosbag2 MCAP bag '
        '(VICON convention: TransformStamped on /vicon/octoroach/octoroach at 50 Hz, a run '
        'marker on /octoroach/run_start, and at least 1 s between runs). Without --effect it '
        "is the paper's model exactly (eqs. 3-11), every run starting at x = y = 0 heading +y.")
    parser.add_argument('--paths', type=positive_int, required=True, help='number of runs')
    parser.add_argument('--seed', type=int, default=0, help='seed of every random draw')
    parser.add_argument('--out', type=Path, required=True, help='bag directory to create')
    parser.add_argument('--cycles', type=finite_float, default=10.0, help='gait cycles per run')
    parser.add_argument('--sigma1', type=finite_float, default=0.12, help='touchdown spread, rad')
    parser.add_argument('--sigma2', type=finite_float, default=0.15, help='liftoff spread, rad')
    parser.add_argument('--draws', choices=('stance', 'run'), default='stance',
                        help='new angles at every stance (default) or once per run')
    parser.add_argument('--stride-frequency', type=finite_float, default=None,
                        help='gait cycles per second (default: config/table2.yaml)')
    parser.add_argument('--effect', action=OrderedEffectAction, dest='effect',
                        help='a cause from the contract table; repeatable')
    parser.add_argument('--effect-param', action=OrderedEffectAction, dest='effect_param',
                        metavar='KEY=VALUE', help="a parameter of the preceding --effect, in "
                        "the contract's units (e.g. heading_std_deg=4.5)")
    parser.add_argument('--dataset', type=Path, default=None,
                        help='also save the runs as a multisample data set (.npz)')
    return parser


def simulate_command(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from octoroach_model.model import ModelParameters, simulate
    from octoroach_model.recordings import save_dataset, write_paths_bag

    if args.out.exists():
        raise ParameterError(f'{args.out} exists already; choose a new --out')
    parameters = ModelParameters.nominal()
    if args.stride_frequency is not None:
        parameters = replace(parameters, stride_frequency=args.stride_frequency)
    effects = parse_effects(getattr(args, 'effect_pairs', None) or [])
    paths = simulate(args.paths, seed=args.seed, sigma1=args.sigma1, sigma2=args.sigma2,
                     cycles=args.cycles, parameters=parameters, draws=args.draws,
                     effects=effects)
    bag = write_paths_bag(args.out, paths)
    if args.dataset:
        save_dataset(args.dataset, paths)
    print(json.dumps({'bag': str(bag), 'paths': paths.n_paths, 'samples_per_run': len(paths.t),
                      'duration_s': float(paths.t[-1]), 'seed': args.seed,
                      'sigma1': args.sigma1, 'sigma2': args.sigma2, 'draws': args.draws,
                      'effects': paths.info['effects']}, indent=2))
    return 0


def add_input_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('bags', nargs='+', type=Path, metavar='BAG',
                        help='bag directories, .mcap files or .npz data sets')
    parser.add_argument('--topic', default=None, help='pose topic (default: the VICON one)')
    parser.add_argument('--gap-s', type=finite_float, default=0.5,
                        help='a pause longer than this splits runs where there is no marker')


def validate_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog='validate', description="The paper's probabilistic validation on measured runs: "
        'fits the nominal model (eq. 9), then finds the widest (sigma1, sigma2) whose '
        'estimated probability of violation stays below rho (eq. 15), or with --sigma1 and '
        '--sigma2 only estimates it there. Prints JSON.')
    add_input_arguments(parser)
    from octoroach_model.validation import ValidationSettings
    defaults = ValidationSettings()
    parser.add_argument('--rho', type=finite_float, default=defaults.rho)
    parser.add_argument('--epsilon', type=finite_float, default=defaults.epsilon)
    parser.add_argument('--delta', type=finite_float, default=defaults.delta)
    parser.add_argument('--k', type=int, default=defaults.k, help='runs per multisample')
    parser.add_argument('--gamma', type=finite_float, default=defaults.gamma,
                        help='confidence level of the region')
    parser.add_argument('--seed', type=int, default=defaults.seed)
    parser.add_argument('--grid-points', type=int, default=defaults.grid_points)
    parser.add_argument('--sigma1-max', type=finite_float, default=defaults.sigma1_max)
    parser.add_argument('--sigma2-max', type=finite_float, default=defaults.sigma2_max)
    parser.add_argument('--sigma1', type=finite_float, default=None,
                        help='evaluate at this touchdown spread (rad) instead of searching')
    parser.add_argument('--sigma2', type=finite_float, default=None)
    parser.add_argument('--nominal', choices=('fit', 'table2'), default='fit',
                        help="fit the nominal model to the data (eq. 9) or use Table II")
    parser.add_argument('--draws', choices=('stance', 'run'), default='stance')
    return parser


def validate_command(args: argparse.Namespace) -> int:
    from octoroach_model.model import ModelParameters
    from octoroach_model.recordings import load_measured
    from octoroach_model.validation import (
        FourBarModel, ValidationSettings, fit_nominal, validate)
    from octoroach_model.validation.fit import mean_start_pose

    if (args.sigma1 is None) != (args.sigma2 is None):
        raise ParameterError('give both --sigma1 and --sigma2, or neither')
    settings = ValidationSettings(rho=args.rho, epsilon=args.epsilon, delta=args.delta,
                                  k=args.k, gamma=args.gamma, seed=args.seed,
                                  sigma1_max=args.sigma1_max, sigma2_max=args.sigma2_max,
                                  grid_points=args.grid_points)
    measured = load_measured(args.bags, topic=args.topic, gap_s=args.gap_s)
    if measured.n_paths < settings.runs_needed:
        raise DataError(f'{measured.n_paths} runs are too few: n x k = {settings.n} x '
                        f'{settings.k} needs {settings.runs_needed} runs (lower k, or raise '
                        f'epsilon/delta to lower n)')
    if args.nominal == 'fit':
        nominal = fit_nominal(measured)
        model = FourBarModel(nominal.parameters, nominal.start_pose, args.draws)
        fit_report = nominal.report()
    else:
        model = FourBarModel(ModelParameters.nominal(), mean_start_pose(measured), args.draws)
        fit_report = {**ModelParameters.nominal().table(), 'source': 'Table II'}
    sigmas = None if args.sigma1 is None else (args.sigma1, args.sigma2)
    result = validate(measured, settings, model, sigmas, progress_printer('validate'))
    result['nominal'] = fit_report
    result['sources'] = [str(path) for path in args.bags]
    result['notes'] = measured.info.get('notes', [])
    print(json.dumps(result, indent=2))
    return 0


def diagnose_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog='diagnose', description='The main job: calibrates the paper model on measured '
        'runs, shows where it disagrees with them, names the cause, extends the model with '
        'it and measures the gain on held-out runs. Writes DIR/report.json, DIR/summary.md '
        'and PNG plots.')
    add_input_arguments(parser)
    parser.add_argument('--out', type=Path, required=True, help='directory for the report')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    return parser


def diagnose_command(args: argparse.Namespace) -> int:
    from octoroach_model.diagnosis import DiagnosisSettings, diagnose, write_report
    from octoroach_model.recordings import load_measured

    measured = load_measured(args.bags, topic=args.topic, gap_s=args.gap_s)
    report = diagnose(measured, DiagnosisSettings(seed=args.seed),
                      progress=progress_printer('diagnose'))
    report['sources'] = [str(path) for path in args.bags]
    written = write_report(report, args.out, measured=measured, plots=not args.no_plots)
    sys.stderr.write(f'cause: {report["cause"]}\n')
    print(f'report: {written["report"]}')
    print(f'summary: {written["summary"]}')
    return 0


COMMANDS = {
    'simulate': (simulate_parser, simulate_command),
    'validate': (validate_parser, validate_command),
    'diagnose': (diagnose_parser, diagnose_command),
}


def run_command(name: str, argv: list[str] | None) -> int:
    """Parse argv for command `name` and run it; one-line errors, exit codes 0/1/2."""
    make_parser, command = COMMANDS[name]
    args = make_parser().parse_args(argv)
    try:
        return command(args)
    except OctoroachError as error:
        sys.stderr.write(f'error: {name}: {error}\n')
        return EXIT_ERROR
    except KeyboardInterrupt:
        sys.stderr.write(f'error: {name}: interrupted\n')
        return 130
    except (OSError, ValueError, MemoryError) as error:
        sys.stderr.write(f'error: {name}: {type(error).__name__}: {error}\n')
        return EXIT_ERROR
