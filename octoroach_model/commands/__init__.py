"""
The offline programs (`python -m octoroach_model X`, `ros2 run octoroach_model X`).

One module per program, each with `parser()` (argparse, parsing only) and `run(args)` (the
work, in the layers below). `run_command` turns every domain error into one line on stderr
and the exit code of its kind (`errors.exit_code`: data 1, usage 2, output 3, interrupted
130), never a traceback.
"""
from __future__ import annotations

import importlib
import sys

from octoroach_model.errors import exit_code, EXIT_DATA, EXIT_INTERRUPTED, OctoroachError

# name -> one line for the dispatcher's usage text; the module octoroach_model.commands.<name>
OFFLINE: dict[str, str] = {
    'simulate': 'writes N model runs to a bag',
    'validate': "the paper's validation of measured runs, as JSON",
    'diagnose': 'what the model gets wrong, the causes, the extended model and its gain',
    'repair': 'makes a bag left by a killed recorder complete (footer, index, metadata.yaml)',
    'convert': 'turns /tf, Odometry, ROS 1, sqlite3 bags and mocap files into a standard bag',
    'study': 'how well the diagnosis does over many simulated data sets (on Dask)',
    'plan': 'how many runs an experiment needs to detect a given effect',
}


def one_line(text: str) -> str:
    """
    Make a message one printable line.

    Whitespace runs become one space, other control characters (read from the names in a
    broken file) '?'.
    """
    return ''.join(ch if ch.isprintable() else '?' for ch in ' '.join(text.split()))


def run_command(name: str, argv: list[str] | None) -> int:
    """Parse argv for command `name` and run it; one-line errors, exit codes 0/1/2/3/130."""
    module = importlib.import_module(f'octoroach_model.commands.{name}')
    try:
        args = module.parser().parse_args(argv)   # defaults come from config files: may fail
        return int(module.run(args) or 0)
    except OctoroachError as error:
        sys.stderr.write(f'error: {name}: {one_line(str(error))}\n')
        return exit_code(error)
    except KeyboardInterrupt:
        sys.stderr.write(f'error: {name}: interrupted\n')
        return EXIT_INTERRUPTED
    except (OSError, ValueError, MemoryError) as error:
        sys.stderr.write(f'error: {name}: {type(error).__name__}: {error}\n')
        return EXIT_DATA
