"""
What every offline program shares: the parser, argument types, progress lines, exit codes.

Exit codes: the one table of `octoroach_model.errors` (README, "Exit codes"): 0 success, 1
the data or a value cannot be used (`error: ...` on stderr), 2 a usage error (unknown option,
missing argument, malformed value), 3 the output cannot be written, 130 interrupted.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import math
import os
from pathlib import Path
import sys
import time
from typing import Any, NoReturn

from octoroach_model.errors import (
    EXIT_DATA, EXIT_INTERRUPTED, EXIT_OK, EXIT_OUTPUT, EXIT_USAGE, OutputError)
from octoroach_model.fileio import check_writable, is_empty_directory
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import check_value, Progress, settings_of

EXIT_ERROR = EXIT_DATA
__all__ = ['EXIT_DATA', 'EXIT_ERROR', 'EXIT_INTERRUPTED', 'EXIT_OK', 'EXIT_OUTPUT',
           'EXIT_USAGE']


class HelpFormatter(argparse.HelpFormatter):
    """--help shows the default of every option that has one."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ''
        default = action.default
        shown = not (default is None or default is False or default == argparse.SUPPRESS)
        if shown and '%(default)' not in text:
            text += ' (default: %(default)s)'
        return text


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line (and exit 2), not usage + error."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault('formatter_class', HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f'error: {self.prog}: {message} (see --help)\n')


# A long reading says where it is at least this often, even when it moves less than a percent
PROGRESS_EVERY_S = 5.0
# Reading that will last at least this long (at its pace after one second) prints progress
READING_LASTS_S = 4.0


def progress_printer(label: str, *, after_s: float = 0.0, lasting_s: float = 0.0) -> Progress:
    """
    Progress lines on stderr, one per percent step (and every PROGRESS_EVERY_S), for long work.

    With `after_s` and `lasting_s`, lines start once `after_s` seconds have passed and the
    work, at the pace so far, will last at least `lasting_s` seconds in all: work that is over
    at once (reading a small file) prints nothing, long work speaks from its first second.
    """
    state = {'last': -1.0, 'start': time.monotonic(), 'said': -math.inf}

    def report(fraction: float, message: str) -> None:
        now = time.monotonic()
        elapsed = now - state['start']
        if state['said'] == -math.inf:   # nothing said yet: is this work long enough?
            lasting = elapsed / fraction if fraction > 0 else math.inf
            if elapsed < after_s or lasting < lasting_s or (fraction >= 1.0 and after_s):
                return
        due = fraction - state['last'] >= 0.01 or now - state['said'] >= PROGRESS_EVERY_S
        if due or (fraction >= 1.0 and state['last'] < 1.0):
            state['last'], state['said'] = fraction, now
            sys.stderr.write(f'[{label} {fraction * 100:5.1f}% {elapsed:6.1f}s] {message}\n')
            sys.stderr.flush()
    return report


def reading_progress(label: str) -> Progress:
    """Progress lines of reading the inputs, from the first second of a reading that lasts."""
    return progress_printer(f'{label}: read', after_s=1.0, lasting_s=READING_LASTS_S)


def positive_int(text: str) -> int:
    """Read a whole number >= 1 (an argparse type)."""
    value = _whole(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be a positive whole number, got {text}')
    return value


def nonnegative_int(text: str) -> int:
    """Read a whole number >= 0, such as a seed (an argparse type)."""
    value = _whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'must be a non-negative whole number, got {text}')
    return value


def finite_float(text: str) -> float:
    """Read a finite number (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text}')
    return value


def _whole(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a whole number, got {text!r}') from None


def new_output(path: Path, option: str, *, directory_ok: bool = False) -> Path:
    """
    Check before any work that `path` can be written; OutputError (exit 3) if not.

    It must not exist (with `directory_ok`: or be an empty directory), and a file must be
    creatable where it goes (`fileio.check_writable`).
    """
    if os.path.lexists(path) and not (directory_ok and is_empty_directory(path)):
        kind = 'is a directory that is not empty' if directory_ok and path.is_dir() \
            else 'exists already'
        raise OutputError(f'{option} {path} {kind}; choose a new path')
    return check_writable(path, option)


def say_warnings(notes: Any) -> None:
    """
    Print the notes a user must see on stderr, as `note:` lines.

    Those are runs given twice (`recordings.runs.duplicates`) and an up axis that looks wrong
    (`recordings.poses.streams`); every other note is in the program's JSON or report.
    """
    from octoroach_model.recordings.runs.duplicates import REPEATED_RUNS
    from octoroach_model.recordings.poses.streams import UP_AXIS_NOTE

    for note in notes:
        if REPEATED_RUNS in note or UP_AXIS_NOTE in note:
            sys.stderr.write(f'note: {note}\n')


def say_repeated_runs(measured: Any) -> None:
    """Print the notes of measured runs a user must see (`say_warnings`)."""
    say_warnings(measured.info.get('notes', ()))


def add_workers_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """Add --workers, with the one meaning every program gives it (study, plan, diagnose)."""
    parser.add_argument('--workers', type=nonnegative_int, default=None, metavar='N',
                        help=f'worker processes for {what}, one thread each (default: one '
                        'per core); 0 runs everything in this process, one after another')


def add_setting(parser: argparse.ArgumentParser | argparse._ArgumentGroup, record: Any,
                name: str, **overrides: Any) -> argparse.Action:
    """
    Add the option of field `name` of settings record `record` (`settings.setting`).

    Help, unit, range and default come from the field; the option's type only reads the value
    (a number, a whole number, one of the choices): the range is the record's to check (or
    `settings.check_value`'s), so an out-of-range value is a value that cannot be used (exit 1).
    `overrides` are argparse's keywords where the program differs (a default of its own).
    """
    default, described = settings_of(record)[name]
    keywords: dict[str, Any] = {'default': default, 'dest': name, 'help': described.help_text()}
    if described.choices:
        keywords['choices'] = described.choices
    elif isinstance(default, bool):
        keywords['action'] = 'store_true'
    elif isinstance(default, int):
        keywords['type'] = whole_number_type(described.low)
    elif isinstance(default, float):
        keywords['type'] = finite_float
    keywords.update(overrides)
    return parser.add_argument(described.option or '--' + name.replace('_', '-'), **keywords)


def whole_number_type(low: float | None) -> Callable[[str], int]:
    """Return the argparse type of a whole number that must be at least `low`, if it can."""
    if low is not None and low >= 1:
        return positive_int
    if low is not None and low >= 0:
        return nonnegative_int
    return _whole


def add_input_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of the measured runs: bags, mocap files or data sets, how to split."""
    parser.add_argument('bags', nargs='+', type=Path, metavar='BAG',
                        help='rosbag2 bags (MCAP or sqlite3), .mcap files, ROS 1 .bag files, '
                        'Vicon .csv exports, .c3d files, Qualisys .tsv exports, TUM, EuRoC or '
                        'headed CSV trajectory tables, .npz data sets, or folders of them '
                        '(docs/formats.md)')
    add_pose_arguments(parser)
    add_gap_argument(parser)


def add_gap_argument(parser: argparse.ArgumentParser) -> None:
    """Add --gap-s: the pause that splits runs where there is no run marker."""
    from octoroach_model.recordings import DEFAULT_GAP_S
    from octoroach_model.recordings.options import GAP_S

    parser.add_argument('--gap-s', type=finite_float, default=DEFAULT_GAP_S, dest='gap_s',
                        help=GAP_S.help_text())


def add_pose_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the robot's pose is in an input (ReadOptions)."""
    add_setting(parser, ReadOptions, 'topic')
    parser.add_argument('--frame', default=None, metavar='CHILD_FRAME',
                        help='/tf bags: the child frame to follow (default: the only moving '
                        'one)')
    parser.add_argument('--subject', default=None, metavar='NAME',
                        help='Vicon CSV / C3D: the subject or object (default: the only one)')
    parser.add_argument('--markers', default=None, metavar='A,B,C',
                        help='C3D / Vicon CSV / Qualisys TSV trajectories: the markers on the '
                        'rigid body, comma-separated, Subject:Marker or bare names (default: '
                        "all of the subject's, modelled and virtual markers left out)")
    parser.add_argument('--accept-loose-fit', action='store_true',
                        help='fit the marker body even when its markers do not move as one '
                        'rigid body (typical residual above 5 mm); refused otherwise')
    add_setting(parser, ReadOptions, 'forward_axis')
    add_setting(parser, ReadOptions, 'up_axis')


def check_gap(gap_s: float) -> None:
    """Raise ParameterError when --gap-s lies outside its range (`recordings.options.GAP_S`)."""
    from octoroach_model.recordings.options import GAP_S

    check_value('gap_s', gap_s, GAP_S)


def read_options(args: argparse.Namespace) -> ReadOptions:
    """Return the ReadOptions of parsed pose arguments (--gap-s checked where there is one)."""
    if hasattr(args, 'gap_s'):
        check_gap(args.gap_s)
    markers = tuple(name.strip() for name in (args.markers or '').split(',') if name.strip())
    return ReadOptions(topic=args.topic, frame=args.frame, subject=args.subject,
                       markers=markers, forward_axis=args.forward_axis, up_axis=args.up_axis,
                       accept_loose_fit=args.accept_loose_fit)
