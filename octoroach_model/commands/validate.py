"""`validate`: the paper's probabilistic validation of measured runs, printed as JSON."""
from __future__ import annotations

import argparse

from octoroach_model.commands.common import (
    add_input_arguments, finite_float, nonnegative_int, OneLineParser, positive_int,
    progress_printer, read_options, reading_progress, say_repeated_runs)
from octoroach_model.errors import ParameterError


def parser() -> argparse.ArgumentParser:
    """Build the `validate` command line."""
    from octoroach_model.validation import ValidationSettings

    defaults = ValidationSettings()
    result = OneLineParser(
        prog='validate', description="The paper's probabilistic validation on measured runs: "
        'fits the nominal model (eq. 9), then finds the widest (sigma1, sigma2) whose '
        'estimated probability of violation stays below rho (eq. 15), or with --sigma1 and '
        '--sigma2 only estimates it there. Prints JSON.')
    add_input_arguments(result)
    result.add_argument('--rho', type=finite_float, default=defaults.rho,
                        help='largest acceptable probability of violation')
    result.add_argument('--epsilon', type=finite_float, default=defaults.epsilon,
                        help='accuracy of the estimate of E_k (eq. 16)')
    result.add_argument('--delta', type=finite_float, default=defaults.delta,
                        help='1 - confidence of the estimate of E_k (eq. 16)')
    result.add_argument('--k', type=positive_int, default=defaults.k,
                        help='runs per multisample')
    result.add_argument('--gamma', type=finite_float, default=defaults.gamma,
                        help='confidence level of the region')
    result.add_argument('--seed', type=nonnegative_int, default=defaults.seed,
                        help='seed of the multisamples and the model runs')
    result.add_argument('--grid-points', type=positive_int, default=defaults.grid_points,
                        help='grid points per spread in the search (15)')
    result.add_argument('--sigma1-max', type=finite_float, default=defaults.sigma1_max,
                        help='largest touchdown spread searched, rad')
    result.add_argument('--sigma2-max', type=finite_float, default=defaults.sigma2_max,
                        help='largest liftoff spread searched, rad')
    result.add_argument('--sigma1', type=finite_float, default=None,
                        help='evaluate at this touchdown spread (rad) instead of searching')
    result.add_argument('--sigma2', type=finite_float, default=None,
                        help='evaluate at this liftoff spread (rad) instead of searching')
    result.add_argument('--nominal', choices=('fit', 'table2'), default='fit',
                        help='fit the nominal model to the data (eq. 9) or use Table II')
    result.add_argument('--draws', choices=('stance', 'run'), default='stance',
                        help='model angles drawn at every stance, or once per run')
    return result


def run(args: argparse.Namespace) -> int:
    """Validate and print the result as JSON."""
    from octoroach_model.jsonio import dumps
    from octoroach_model.recordings import load_measured
    from octoroach_model.validation import ValidationSettings, validate_measured

    if (args.sigma1 is None) != (args.sigma2 is None):
        raise ParameterError('give both --sigma1 and --sigma2, or neither')
    settings = ValidationSettings(rho=args.rho, epsilon=args.epsilon, delta=args.delta,
                                  k=args.k, gamma=args.gamma, seed=args.seed,
                                  sigma1_max=args.sigma1_max, sigma2_max=args.sigma2_max,
                                  grid_points=args.grid_points)
    measured = load_measured(args.bags, options=read_options(args), gap_s=args.gap_s,
                             progress=reading_progress('validate'))
    say_repeated_runs(measured)
    sigmas = None if args.sigma1 is None else (args.sigma1, args.sigma2)
    result = validate_measured(measured, settings, nominal=args.nominal, draws=args.draws,
                               sigmas=sigmas, sources=[str(path) for path in args.bags],
                               progress=progress_printer('validate'))
    print(dumps(result, indent=2))
    return 0
