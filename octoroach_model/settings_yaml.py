"""
The params files config/NODE.yaml, made from the nodes' parameters (and so from the fields).

Each file holds every parameter of one node at its default, under `NODE: ros__parameters:`,
with a comment giving its help, unit and range: what `NODE --help` says, because both come
from the same `ParamSpec`s, which come from the settings' fields (`settings`). Run
`python -m octoroach_model.settings_yaml` after changing a setting to write the files again;
`--check` only says which differ (test_settings.py fails while one does).
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
import sys
import textwrap

import yaml

from octoroach_model.errors import OutputError
from octoroach_model.fileio import write_text_atomic
from octoroach_model.nodes.common import ParamSpec, ParamValue

CONFIG_DIR = Path(__file__).resolve().parent.parent / 'config'
WIDTH = 99
# what each node is, for the first line of its file
TITLES = {
    'simulator': 'the model as a live VICON stream',
    'recorder': 'VICON topics to a rosbag2 MCAP bag',
    'validator': 'validation and diagnosis as services',
    'replay': 'a recorded bag played again',
}
# the comment above a group of parameters NAME.KEY (written nested: NAME: {KEY: ...})
GROUPS = {
    'effect_params': 'parameters of the causes, in their own units: only those of `effect` '
                     'are used',
    'extension_params': 'parameters of the extension families, in their own units: only those '
                        'of `extension` are used',
}


def node_specs() -> dict[str, Callable[[], list[ParamSpec]]]:
    """Return {node: its parameters, in --help order}."""
    from octoroach_model.nodes import recorder, replay, simulator, validator

    return {'simulator': simulator.simulator_specs,
            'recorder': recorder.recorder_specs,
            'validator': lambda: [*validator.ARRAYS, *validator.validator_specs()],
            'replay': replay.replay_specs}


def comment(spec: ParamSpec) -> str:
    """Return what a params file says about a parameter: help, unit, range, read-only."""
    text = spec.description + (' (read-only)' if spec.read_only else '')
    text += f' [{spec.unit}]' if spec.unit else ''
    if '' in spec.choices:
        text += '; one of ' + ', '.join(repr(choice) if choice == '' else choice
                                        for choice in spec.choices)
    elif spec.range_text():
        text += '; ' + spec.range_text()
    return text


def scalar(value: ParamValue) -> str:
    """Write a value as YAML that reads back as the same value and type (50.0, not 50)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, list):
        return '[' + ', '.join(scalar(item) for item in value) + ']'
    plain = value if value and yaml.safe_load(value) == value else None
    return plain if plain is not None else "'" + value.replace("'", "''") + "'"


def params_file(node: str, specs: Sequence[ParamSpec]) -> str:
    """Return the text of config/NODE.yaml."""
    lines = [f'# ROS parameters of the {node} node ({TITLES[node]}), each at its default.',
             f'# python -m octoroach_model {node} --ros-args --params-file config/{node}.yaml',
             f'# (ros2 run: share/octoroach_model/config/{node}.yaml); {node} --help lists them.',
             '# Written by `python -m octoroach_model.settings_yaml` from the settings: edit '
             'those, not this file.',
             f'{node}:', '  ros__parameters:']
    group = ''
    for spec in specs:
        prefix, _, key = spec.name.rpartition('.')
        indent = '    ' + '  ' * bool(prefix)
        if prefix and prefix != group:
            lines += wrapped(GROUPS[prefix], '    ') + [f'    {prefix}:']
        group = prefix
        lines += wrapped(comment(spec), indent) + [f'{indent}{key}: {scalar(spec.default)}']
    return '\n'.join(lines) + '\n'


def wrapped(text: str, indent: str) -> list[str]:
    """Return `text` as comment lines of at most WIDTH characters."""
    return textwrap.wrap(text, WIDTH, initial_indent=indent + '# ',
                         subsequent_indent=indent + '# ', break_on_hyphens=False)


def params_files() -> dict[str, str]:
    """Return {file name: text} of every node's params file."""
    return {f'{node}.yaml': params_file(node, specs())
            for node, specs in node_specs().items()}


def main(argv: Sequence[str] | None = None) -> int:
    """Write config/NODE.yaml for every node (or, with --check, say which differ)."""
    parser = argparse.ArgumentParser(
        prog='python -m octoroach_model.settings_yaml',
        description="Write the params files config/NODE.yaml from the nodes' settings.")
    parser.add_argument('--out', type=Path, default=CONFIG_DIR,
                        help=f'folder of the files (default: {CONFIG_DIR})')
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 and name the files that differ')
    args = parser.parse_args(argv)
    stale = []
    for name, text in params_files().items():
        path = args.out / name
        if path.is_file() and path.read_text() == text:
            continue
        stale.append(str(path))
        if not args.check:
            try:    # atomic, and a link at the name is replaced, never written through
                write_text_atomic(path, text, replace=True, what='params file')
            except OutputError as error:
                sys.stderr.write(f'error: {error}\n')
                return 1
    if args.check and stale:
        sys.stderr.write('error: not as the settings say (python -m '
                         f'octoroach_model.settings_yaml writes them): {", ".join(stale)}\n')
        return 1
    for path in stale:
        print(f'wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
