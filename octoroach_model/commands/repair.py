"""`repair`: a bag left by a killed recorder made complete (footer, index, metadata.yaml)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from octoroach_model.commands.common import new_output, OneLineParser


def parser() -> argparse.ArgumentParser:
    """Build the `repair` command line."""
    result = OneLineParser(
        prog='repair', description='Make a rosbag2 MCAP bag that a killed recorder left '
        'behind (no footer, no index, no metadata.yaml) complete, keeping every message that '
        'survived, as `ros2 bag reindex` would. In place, each damaged file is kept as '
        'NAME.mcap.damaged beside its repaired copy; with --out the input is only read. '
        'Prints JSON: the messages kept per file and what was damaged.')
    result.add_argument('bag', type=Path, metavar='BAG',
                        help='bag directory (or a bare .mcap file) to repair')
    result.add_argument('--out', type=Path, default=None,
                        help='write the repaired bag here instead of in place (a new path)')
    return result


def run(args: argparse.Namespace) -> int:
    """Repair and print what was kept."""
    from octoroach_model.errors import BagError
    from octoroach_model.recordings.bagio.repair import repair_bag

    if not args.bag.exists():
        raise BagError(f'{args.bag}: no such bag (directory or .mcap file)')
    if args.out is not None:
        new_output(args.out, '--out')
    report = repair_bag(args.bag, args.out)
    print(json.dumps({
        'bag': str(report.bag),
        'repaired': report.repaired,
        'messages': report.messages,
        'files': [{'name': file.name, 'messages': file.messages, 'damage': file.damage,
                   'damaged_original': file.kept} for file in report.files],
        'notes': list(report.notes),
    }, indent=2))
    return 0
