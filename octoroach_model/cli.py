"""
Command-line entry points. Parsing only: the work is in the layers below.

Each executable `X` has a function `X_main(argv=None) -> int`, used both by the console
scripts that `ros2 run` finds (setup.py) and by `python -m octoroach_model X`.
"""
from __future__ import annotations

import sys

NODES = ('simulator', 'recorder', 'validator', 'replay')


def _offline() -> dict[str, str]:
    from octoroach_model.commands import OFFLINE
    return OFFLINE


def _node_main(name: str, argv: list[str] | None) -> int:
    import faulthandler
    import importlib

    from octoroach_model.nodes.common import shutdown_watchdog

    # a crash in the middleware (a node has ended with SIGSEGV on SIGINT once in several
    # hundred stops under load) prints every thread's Python stack to the node's log
    faulthandler.enable()
    module = importlib.import_module(f'octoroach_model.nodes.{name}')
    code = int(module.main(argv) or 0)
    shutdown_watchdog(name, code)      # the process exits now; a stuck thread must not hold it
    return code


def _command_main(name: str, argv: list[str] | None) -> int:
    from octoroach_model.commands import run_command
    return run_command(name, argv)


def simulator_main(argv: list[str] | None = None) -> int:
    return _node_main('simulator', argv)


def recorder_main(argv: list[str] | None = None) -> int:
    return _node_main('recorder', argv)


def validator_main(argv: list[str] | None = None) -> int:
    return _node_main('validator', argv)


def replay_main(argv: list[str] | None = None) -> int:
    return _node_main('replay', argv)


def simulate_main(argv: list[str] | None = None) -> int:
    return _command_main('simulate', argv)


def validate_main(argv: list[str] | None = None) -> int:
    return _command_main('validate', argv)


def diagnose_main(argv: list[str] | None = None) -> int:
    return _command_main('diagnose', argv)


def repair_main(argv: list[str] | None = None) -> int:
    return _command_main('repair', argv)


def convert_main(argv: list[str] | None = None) -> int:
    return _command_main('convert', argv)


def study_main(argv: list[str] | None = None) -> int:
    return _command_main('study', argv)


def plan_main(argv: list[str] | None = None) -> int:
    return _command_main('plan', argv)


def usage() -> str:
    """Return what `python -m octoroach_model --help` prints."""
    offline = _offline()
    lines = ['usage: python -m octoroach_model {' + ','.join((*NODES, *offline)) + '} ...',
             '  ROS nodes: ' + ', '.join(NODES),
             '  offline programs:']
    lines += [f'    {name:<10} {text}' for name, text in offline.items()]
    lines += ['  X --help explains X. Exit codes: 0 done, 1 bad data or value, 2 usage error, '
              '3 output cannot be written, 130 interrupted.']
    return '\n'.join(lines) + '\n'


def dispatch(argv: list[str]) -> int:
    """Run executable argv[0] with the rest of argv."""
    if not argv or argv[0] in ('-h', '--help'):
        (sys.stdout if argv else sys.stderr).write(usage())
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name in NODES:
        return _node_main(name, rest)
    if name in _offline():
        return _command_main(name, rest)
    sys.stderr.write(f'error: unknown executable {name!r}\n{usage()}')
    return 2
