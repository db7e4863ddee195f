"""Command-line entry points. Parsing only: the work is in the layers below.

Each executable `X` has a function `X_main(argv=None) -> int`, used both by the console
scripts that `ros2 run` finds and by `python -m octoroach_model X`.
"""
from __future__ import annotations

import sys

NODES = ('simulator', 'recorder', 'validator', 'replay')
OFFLINE = ('simulate', 'validate', 'diagnose')


def _node_main(name: str, argv: list[str] | None) -> int:
    import importlib

    module = importlib.import_module(f'octoroach_model.nodes.{name}')
    return int(module.main(argv) or 0)


def simulator_main(argv: list[str] | None = None) -> int:
    return _node_main('simulator', argv)


def recorder_main(argv: list[str] | None = None) -> int:
    return _node_main('recorder', argv)


def validator_main(argv: list[str] | None = None) -> int:
    return _node_main('validator', argv)


def replay_main(argv: list[str] | None = None) -> int:
    return _node_main('replay', argv)


def simulate_main(argv: list[str] | None = None) -> int:
    from octoroach_model.commands import run_command
    return run_command('simulate', argv)


def validate_main(argv: list[str] | None = None) -> int:
    from octoroach_model.commands import run_command
    return run_command('validate', argv)


def diagnose_main(argv: list[str] | None = None) -> int:
    from octoroach_model.commands import run_command
    return run_command('diagnose', argv)


USAGE = ('usage: python -m octoroach_model {' + ','.join(NODES + OFFLINE) + '} [--help] ...\n'
         '  ROS nodes: ' + ', '.join(NODES) + '\n'
         '  offline:   ' + ', '.join(OFFLINE) + '\n')


def dispatch(argv: list[str]) -> int:
    """Run executable argv[0] with the rest of argv."""
    if not argv or argv[0] in ('-h', '--help'):
        (sys.stdout if argv else sys.stderr).write(USAGE)
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in NODES + OFFLINE:
        sys.stderr.write(f'error: unknown executable {name!r}\n{USAGE}')
        return 2
    return globals()[f'{name}_main'](rest)
