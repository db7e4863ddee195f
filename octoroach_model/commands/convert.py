"""`convert`: any pose input (/tf, Odometry, ROS 1, sqlite3, Vicon CSV, C3D) to a standard bag."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from octoroach_model.commands.common import (
    add_pose_arguments,
    finite_float,
    new_output,
    OneLineParser,
    read_options,
    reading_progress,
    say_warnings,
)


def parser() -> argparse.ArgumentParser:
    """Build the `convert` command line."""
    result = OneLineParser(
        prog='convert', description="Turn pose recordings into the package's standard bag: "
        'TransformStamped on /vicon/SUBJECT/SUBJECT (metres, z up, heading as the yaw) with a '
        'run marker on /SUBJECT/run_start before each run, as `simulate` writes. Inputs: '
        'rosbag2 bags (MCAP or sqlite3) with poses on any pose topic, in an array of named '
        'bodies or on /tf, ROS 1 .bag files, Vicon .csv exports, .c3d files, Qualisys .tsv '
        'exports, TUM, EuRoC and headed CSV trajectory tables (docs/formats.md). Every sample '
        'is copied; markers are kept, or put where runs start. Prints JSON with notes on what '
        'was converted, among them the clock the poses carry.')
    result.add_argument('inputs', nargs='+', type=Path, metavar='INPUT',
                        help='bags, .bag/.mcap/.csv/.c3d/.tsv/.txt files, or folders of them')
    result.add_argument('--out', type=Path, required=True, help='bag directory to create')
    add_pose_arguments(result)
    result.add_argument('--gap-s', type=finite_float, default=0.5,
                        help='without markers in the input, a jump in the stamps longer than '
                        'this (s) starts a run')
    result.add_argument('--dataset', type=Path, default=None,
                        help='also save the runs as a multisample data set (.npz)')
    result.add_argument('--rate-hz', type=finite_float, default=50.0,
                        help='sample rate of the data set')
    return result


def run(args: argparse.Namespace) -> int:
    """Convert, optionally save the data set, print a JSON summary."""
    from octoroach_model.errors import ParameterError
    from octoroach_model.recordings import load_measured, save_dataset
    from octoroach_model.recordings.standard_bag.from_inputs import convert_to_bag

    new_output(args.out, '--out')
    if args.dataset is not None:
        new_output(args.dataset, '--dataset')
    if args.gap_s <= 0:
        raise ParameterError(f'--gap-s must be positive, got {args.gap_s}')
    options = read_options(args)
    report = convert_to_bag(args.inputs, args.out, options=options, subject=args.subject,
                            gap_s=args.gap_s, progress=reading_progress('convert'))
    say_warnings(report.notes)
    summary = {'bag': str(report.bag), 'subject': report.subject,
               'inputs': list(report.inputs), 'poses': report.samples,
               'markers': report.markers, 'non_finite_dropped': report.dropped,
               'notes': list(report.notes)}
    if args.dataset is not None:
        paths = load_measured([report.bag], gap_s=args.gap_s, rate_hz=args.rate_hz)
        save_dataset(args.dataset, paths)
        summary['dataset'] = {'file': str(args.dataset), 'runs': paths.n_paths,
                              'duration_s': float(paths.t[-1]),
                              'notes': list(paths.info.get('notes', []))}
    print(json.dumps(summary, indent=2))
    return 0
