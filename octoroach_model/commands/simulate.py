"""`simulate`: N runs of the model written to a bag (and optionally a data set)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from octoroach_model.commands.common import (
    add_setting, finite_float, new_output, nonnegative_int, OneLineParser, positive_int)
from octoroach_model.errors import ParameterError
from octoroach_model.model.extensions import FAMILY_NAMES
from octoroach_model.settings import check_value, settings_of


def parse_effects(pairs: list[tuple[str, str]]) -> dict[str, dict[str, float]]:
    """
    Group --effect NAME and --effect-param KEY=VALUE pairs, in command-line order, by cause.

    A parameter belongs to the --effect before it (or, written NAME.KEY=VALUE, to NAME).
    """
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
        prefix, dot, key = key.rpartition('.')
        name = prefix if dot else current
        if name is None:
            raise ParameterError(f'--effect-param {value} comes before any --effect NAME')
        try:
            effects.setdefault(name, {})[key] = float(number)
        except ValueError:
            raise ParameterError(f'--effect-param {value}: {number!r} is not a number') from None
    return effects


def parse_extensions(pairs: list[tuple[str, str]]
                     ) -> list[tuple[str, dict[str, str | float]]]:
    """
    Group --extension FAMILY and --extension-param KEY=VALUE pairs, in command-line order.

    A parameter belongs to the --extension before it. Every value is a number but
    run_order_drift's `parameter`, which names what drifts; `model.extensions.family_terms`
    checks them.
    """
    extensions: list[tuple[str, dict[str, str | float]]] = []
    for option, value in pairs:
        if option == 'extension':
            extensions.append((value, {}))
            continue
        key, sep, text = value.partition('=')
        if not sep:
            raise ParameterError(f'--extension-param takes KEY=VALUE, got {value!r}')
        if not extensions:
            raise ParameterError(f'--extension-param {value} comes before any --extension NAME')
        if key == 'parameter':
            extensions[-1][1][key] = text
            continue
        try:
            extensions[-1][1][key] = float(text)
        except ValueError:
            raise ParameterError(f'--extension-param {value}: {text!r} is not a number') from None
    return extensions


class OrderedEffectAction(argparse.Action):
    """Keeps --effect, --extension and their parameters in the order they were given."""

    def __call__(self, parser, namespace, values, option_string=None):
        group = 'extension_pairs' if self.dest.startswith('extension') else 'effect_pairs'
        pairs = getattr(namespace, group, None) or []
        pairs.append((self.dest, values))
        setattr(namespace, group, pairs)


def parser() -> argparse.ArgumentParser:
    """Build the `simulate` command line (the model's options are RunSettings' fields)."""
    from octoroach_model.run_settings import RunSettings

    result = OneLineParser(
        prog='simulate', description='Write N runs of the model to a rosbag2 MCAP bag '
        '(VICON convention: TransformStamped on /vicon/octoroach/octoroach at 50 Hz, a run '
        'marker on /octoroach/run_start, and at least 1 s between runs). Without --effect it '
        "is the paper's model exactly (eqs. 3-11), every run starting at x = y = 0 heading +y. "
        'Runs are written in the order drawn: run i is the i-th of the recording (what the '
        'run-order terms of --extension read).')
    result.add_argument('--paths', type=positive_int, required=True, help='number of runs')
    result.add_argument('--seed', type=nonnegative_int, default=0,
                        help='seed of every random draw')
    result.add_argument('--out', type=Path, required=True, help='bag directory to create')
    result.add_argument('--cycles', type=finite_float, default=10.0, help='gait cycles per run')
    for name in ('sigma1', 'sigma2', 'draws', 'stride_frequency'):   # as the simulator's
        add_setting(result, RunSettings, name)
    result.add_argument('--effect', action=OrderedEffectAction, dest='effect',
                        help='a cause from the table of causes (docs/causes.md); repeatable')
    result.add_argument('--effect-param', action=OrderedEffectAction, dest='effect_param',
                        metavar='KEY=VALUE', help='a parameter of the preceding --effect, in '
                        "the table's units (e.g. heading_std_deg=4.5)")
    result.add_argument('--extension', action=OrderedEffectAction, dest='extension',
                        metavar='FAMILY', help='an extension family beyond the table '
                        f'(docs/extensions.md): {", ".join(FAMILY_NAMES)}; repeatable')
    result.add_argument('--extension-param', action=OrderedEffectAction,
                        dest='extension_param', metavar='KEY=VALUE', help='a parameter of the '
                        'preceding --extension in its units (e.g. parameter=stride_frequency, '
                        'change=-0.15)')
    result.add_argument('--dataset', type=Path, default=None,
                        help='also save the runs as a multisample data set (.npz)')
    return result


def run(args: argparse.Namespace) -> int:
    """Simulate and write; prints a JSON summary of what was written."""
    from dataclasses import replace

    from octoroach_model.model import ModelParameters, simulate
    from octoroach_model.fileio import atomic_directory
    from octoroach_model.recordings import save_dataset, write_paths_bag
    from octoroach_model.run_settings import RunSettings

    new_output(args.out, '--out')
    if args.dataset:
        new_output(args.dataset, '--dataset')
    check_value('stride_frequency', args.stride_frequency,
                settings_of(RunSettings)['stride_frequency'][1])
    parameters = replace(ModelParameters.nominal(), stride_frequency=args.stride_frequency)
    effects = parse_effects(getattr(args, 'effect_pairs', None) or [])
    extensions = parse_extensions(getattr(args, 'extension_pairs', None) or [])
    paths = simulate(args.paths, seed=args.seed, sigma1=args.sigma1, sigma2=args.sigma2,
                     cycles=args.cycles, parameters=parameters, draws=args.draws,
                     effects=effects, extensions=extensions)
    # written under a temporary name beside it and renamed when complete: whole or absent
    with atomic_directory(args.out, what='--out') as folder:
        write_paths_bag(folder, paths, bag_name=args.out.name)
    bag = args.out
    if args.dataset:
        save_dataset(args.dataset, paths)
    print(json.dumps({'bag': str(bag), 'paths': paths.n_paths, 'samples_per_run': len(paths.t),
                      'duration_s': float(paths.t[-1]), 'seed': args.seed,
                      'sigma1': args.sigma1, 'sigma2': args.sigma2, 'draws': args.draws,
                      'effects': paths.info['effects'],
                      'extensions': paths.info['extensions']}, indent=2))
    return 0
