"""
Trajectory tables: one pose per line of a text file, in named or known columns.

Three dialects, told apart by their first lines (`detect_table`):

- **TUM trajectory** (the TUM RGB-D benchmark's file format): ``timestamp tx ty tz qx qy qz
  qw`` per line, separated by spaces; the time in seconds (since the Unix epoch), the position
  in metres, the orientation a unit quaternion; lines starting with ``#`` are comments. The
  columns are fixed, so no header is needed.
- **EuRoC/ASL CSV** (the EuRoC MAV data set's ``vicon0/data.csv`` and
  ``state_groundtruth_estimate0/data.csv``): a header ``#timestamp [ns],p_RS_R_x [m],
  p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []`` and more columns
  (velocities, biases) that are not used; the time in integer nanoseconds, the quaternion w
  first (it is found by name, so the order does not matter).
- **A CSV with a header** naming its columns (`COLUMN_NAMES`): a time, x and y, optionally z,
  and an orientation: a quaternion (qx qy qz qw) or a heading (yaw, heading or theta). A
  unit may follow a name in brackets or parentheses (``time [ms]``, ``x (mm)``, ``yaw [deg]``)
  or as a suffix (``time_ns``, ``x_mm``, ``yaw_deg``); without one, seconds, metres and
  radians. The delimiter is a comma, a semicolon, a tab or spaces.

Rows: numbers; comment lines (``#``) anywhere and extra columns are skipped; a row with an
empty or NaN pose cell is a dropped frame, a row with text where a number belongs is skipped;
both are counted in the notes. The time is read exactly to the nanosecond (a float64 of Unix
seconds keeps only about 0.2 us). Positions and quaternions are turned into the z-up world
(`ReadOptions.up_axis`); a heading column is already a yaw about z, so its table is taken as
z up. One file is one stream (``table:<file name>``), cut into runs at pauses like any other.
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
import csv
from dataclasses import dataclass
import math
from pathlib import Path
import re

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.recordings.conventions.axes import (
    forward_angle_rad,
    Orientations,
    to_z_up,
    wrap_angle,
)
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.mocap.shared import (
    ANGLE_UNITS,
    axis_words,
    last_chunk,
    LENGTH_UNITS,
    pose_chunk,
    PoseInput,
    stream_fraction,
    text_lines,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import listed_names, unknown_name

__all__ = ['TableReader', 'COLUMN_NAMES', 'TableLayout', 'detect_table', 'iter_table_pose_chunks']

# The names a column may have (compared in lower case, the unit taken off), by role
COLUMN_NAMES: dict[str, tuple[str, ...]] = {
    't': ('t', 'time', 'timestamp', 'stamp', 'time_stamp'),
    'x': ('x', 'tx', 'px', 'pos_x', 'position_x', 'p_rs_r_x'),
    'y': ('y', 'ty', 'py', 'pos_y', 'position_y', 'p_rs_r_y'),
    'z': ('z', 'tz', 'pz', 'pos_z', 'position_z', 'p_rs_r_z'),
    'qx': ('qx', 'q_x', 'quat_x', 'orientation_x', 'q_rs_x'),
    'qy': ('qy', 'q_y', 'quat_y', 'orientation_y', 'q_rs_y'),
    'qz': ('qz', 'q_z', 'quat_z', 'orientation_z', 'q_rs_z'),
    'qw': ('qw', 'q_w', 'quat_w', 'orientation_w', 'q_rs_w'),
    'yaw': ('yaw', 'heading', 'theta'),
}
_ROLE_OF = {name: role for role, names in COLUMN_NAMES.items() for name in names}
TIME_UNITS_NS = {'s': 1_000_000_000, 'sec': 1_000_000_000, 'ms': 1_000_000, 'us': 1_000,
                 'ns': 1}
QUATERNION = ('qx', 'qy', 'qz', 'qw')
TUM = 'TUM trajectory'
EUROC = 'EuRoC/ASL CSV'
NAMED = 'CSV table'
_TUM_COLUMNS = ('t', 'x', 'y', 'z', 'qx', 'qy', 'qz', 'qw')
_UNIT_IN_BRACKETS = re.compile(r'^(?P<name>.*?)\s*(?:\[(?P<a>[^\]]*)\]|\((?P<b>[^)]*)\))\s*$')
_UNIT_SUFFIX = re.compile(r'^(?P<name>.+?)_(?P<unit>s|sec|ms|us|ns|m|mm|cm|deg|rad)$')
_DECIMAL = re.compile(r'([+-]?)(\d+)(?:\.(\d*))?')
_SNIFF_LINES = 400
MAX_TIME_NS = 1 << 62  # about 146 years of ns: any larger time is damage


@dataclass(frozen=True)
class TableLayout:
    """Where a table keeps its time and pose, and in which units."""

    dialect: str
    delimiter: str | None  # None: runs of spaces
    columns: dict[str, int]  # role -> column index
    names: dict[str, str]  # role -> the column's name in the file
    time_unit: str
    length_unit: str
    angle_unit: str
    width: int  # columns the header (or the first row) has

    @property
    def time_scale_ns(self) -> int:
        """Return the nanoseconds of one time unit."""
        return TIME_UNITS_NS[self.time_unit]


def _delimiter(line: str) -> str | None:
    """Return a line's delimiter: the commonest of , ; and tab, or None (spaces)."""
    counts = {delimiter: line.count(delimiter) for delimiter in (',', ';', '\t')}
    best = max(counts, key=lambda delimiter: counts[delimiter])
    return best if counts[best] else None


def _split(line: str, delimiter: str | None) -> list[str]:
    if delimiter is None:
        return line.split()
    return [cell.strip() for cell in next(csv.reader([line], delimiter=delimiter), [])]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    """Split a column name into (name, unit): 'x [mm]', 'x (mm)', 'x_mm'; unit None if none."""
    text = cell.strip().lstrip('#').strip().lower()
    match = _UNIT_IN_BRACKETS.match(text)
    if match:
        unit = match.group('a') if match.group('a') is not None else match.group('b')
        return match.group('name').strip(), unit.strip()
    match = _UNIT_SUFFIX.match(text)
    if match and match.group('name') in _ROLE_OF:
        return match.group('name'), match.group('unit')
    return text, None


def _header(cells: Sequence[str], delimiter: str | None) -> TableLayout | None:
    """Read a header line's names into a layout; None unless it names a time and x."""
    columns: dict[str, int] = {}
    names: dict[str, str] = {}
    units: dict[str, str | None] = {}
    for index, cell in enumerate(cells):
        name, unit = _name_and_unit(cell)
        role = _ROLE_OF.get(name)
        if role is None or role in columns:
            continue
        columns[role], names[role], units[role] = index, cell.strip().lstrip('#').strip(), unit
    if 't' not in columns or 'x' not in columns:
        return None
    euroc = 'p_rs_r_x' in {_name_and_unit(cell)[0] for cell in cells}
    tum = delimiter is None and [_name_and_unit(cell)[0] for cell in cells] == [
        'timestamp', 'tx', 'ty', 'tz', 'qx', 'qy', 'qz', 'qw']
    dialect = EUROC if euroc else TUM if tum else NAMED

    def unit_of(roles: Sequence[str], default: str) -> str:
        found = sorted({units[role] or '' for role in roles if role in units} - {''})
        return '|'.join(found) if found else default   # two units for one quantity: refused

    return TableLayout(dialect, delimiter, columns, names,
                       unit_of(['t'], 'ns' if euroc else 's'),
                       unit_of(['x', 'y', 'z'], 'm'), unit_of(['yaw'], 'rad'), len(cells))


def detect_table(lines: Sequence[str]) -> TableLayout | None:
    """Tell a trajectory table by its first non-blank lines; None if it is not one."""
    comment: str | None = None
    for line in lines[:_SNIFF_LINES]:
        text = line.strip()
        if not text:
            continue
        if text.startswith('#'):
            comment = text
            continue
        delimiter = _delimiter(text)
        cells = _split(text, delimiter)
        if cells and all(_is_number(cell) for cell in cells if cell) and _is_number(cells[0]):
            if comment is not None:
                named = _header(_split(comment.lstrip('#').strip(),
                                       _delimiter(comment)), delimiter)
                if named is not None:
                    return named
            if delimiter is None and len(cells) == len(_TUM_COLUMNS):
                return TableLayout(TUM, None, dict(zip(_TUM_COLUMNS, range(8))),
                                   dict(zip(_TUM_COLUMNS, ('timestamp', 'tx', 'ty', 'tz', 'qx',
                                                           'qy', 'qz', 'qw'))),
                                   's', 'm', 'rad', 8)
            return None
        return _header(cells, delimiter)
    return None


def exact_ns(text: str, scale_ns: int) -> int | None:
    """
    Read a time cell exactly into int ns (`scale_ns` per unit).

    None if it is not a number or lies beyond MAX_TIME_NS (no clock reaches it; an int64
    would overflow).
    """
    match = _DECIMAL.fullmatch(text.strip())
    if match is None:
        try:
            value = float(text)
        except ValueError:
            return None
        if not (math.isfinite(value) and abs(value) * scale_ns <= MAX_TIME_NS):
            return None
        return int(round(value * scale_ns))
    sign, whole, fraction = match.groups()
    if len(whole) > 19:
        return None
    fraction = (fraction or '')[:18]
    ns = int(whole) * scale_ns
    if fraction:
        tenths = 10 ** len(fraction)
        ns += (2 * int(fraction) * scale_ns + tenths) // (2 * tenths)
    if ns > MAX_TIME_NS:
        return None
    return -ns if sign == '-' else ns


def _check(where: str, layout: TableLayout, options: ReadOptions) -> tuple[float, float]:
    """Check that the table has what a pose needs; return the length and angle scales."""
    has_quaternion = all(role in layout.columns for role in QUATERNION)
    if not has_quaternion and 'yaw' not in layout.columns:
        some = [layout.names[role] for role in QUATERNION if role in layout.columns]
        raise BagError(f'{where}: {layout.dialect} without an orientation: it needs '
                       'quaternion columns qx qy qz qw or a heading column (yaw, heading, '
                       f'theta){"; it has only " + listed_names(some) if some else ""}')
    if 'y' not in layout.columns:
        raise BagError(f'{where}: {layout.dialect} without a y column')
    for unit, table, what, expected in (
            (layout.time_unit, TIME_UNITS_NS, 'time', ', '.join(TIME_UNITS_NS)),
            (layout.length_unit, LENGTH_UNITS, 'length', 'm, cm or mm'),
            (layout.angle_unit, ANGLE_UNITS, 'angle', 'rad or deg')):
        if unit not in table:
            refused = f'{unit.count("|") + 1} different {what} units' if '|' in unit else \
                f'unknown {what} unit, {unknown_name(unit, list(table))}'
            raise BagError(f'{where}: {refused}; expected {expected}')
    length_scale = LENGTH_UNITS[layout.length_unit]
    angle_scale = ANGLE_UNITS[layout.angle_unit]
    if not has_quaternion and (options.up_axis != 'z' or options.forward_axis in ('z', '-z')):
        raise BagError(f'{where}: a heading column is a yaw about z: its table is z up with '
                       'the body moving in x-y; leave out --up-axis and a vertical '
                       '--forward-axis')
    if options.up_axis != 'z' and 'z' not in layout.columns:
        raise BagError(f'{where}: no z column, so --up-axis {options.up_axis} cannot turn the '
                       'positions')
    return length_scale, angle_scale


def _describe(layout: TableLayout, used: int) -> str:
    names = layout.names
    position = ' '.join(names[role] for role in ('x', 'y', 'z') if role in names)
    if all(role in names for role in QUATERNION):
        orientation = 'quaternion ' + ' '.join(names[role] for role in QUATERNION)
    else:
        orientation = f'heading {names["yaw"]} in {layout.angle_unit}'
    delimiter = {None: 'spaces', ',': 'commas', ';': 'semicolons', '\t': 'tabs'}[
        layout.delimiter]
    ignored = layout.width - used
    return (f'{layout.dialect} separated by {delimiter}: time {names["t"]} in '
            f'{layout.time_unit}, position {position} in {layout.length_unit}, '
            f'{orientation}' + (f'; {ignored} other column(s) ignored' if ignored > 0 else ''))


class TableReader(PoseInput):
    """A trajectory table's pose streams (`iter_table_pose_chunks`), for `POSE_READERS`."""

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the file's pose streams, chunk by chunk."""
        return iter_table_pose_chunks(self.path, self.options, self.notes, chunk_size)


def iter_table_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                           chunk_size: int = 10_000) -> Iterator[PoseChunk]:
    """
    Pose samples of a trajectory table, chunk by chunk (the mapping: module docstring).

    The stream ends with one chunk whose `is_last` is True; what was read, dropped or
    skipped goes to `notes`. Raises BagError with a one-line reason for a file that is not a
    table or lacks a column a pose needs.
    """
    path = Path(path)
    where = str(path)
    try:
        size = max(1, path.stat().st_size)
        with path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
            head = [line for _, line in zip(range(_SNIFF_LINES),
                                            text_lines(stream, where, 'a trajectory table'))]
    except OSError as exc:
        raise BagError(f'{where}: cannot read: {exc.strerror or exc}') from None
    layout = detect_table(head)
    if layout is None:
        raise BagError(f'{where}: not a trajectory table (no header naming a time and x '
                       'column, and not 8 numbers per line as in a TUM trajectory)')
    length_scale, angle_scale = _check(where, layout, options)
    quaternion = all(role in layout.columns for role in QUATERNION)
    roles = ['x', 'y'] + (['z'] if 'z' in layout.columns else []) + \
        (list(QUATERNION) if quaternion else ['yaw'])
    wanted = [layout.columns['t']] + [layout.columns[role] for role in roles]
    notes.append(f'{where}: {_describe(layout, len(wanted))}; {axis_words(options)}')
    topic = f'table:{path.stem}'
    state = _Counts()
    orientations = Orientations()
    sequence = 1
    width = max(wanted) + 1
    with path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
        rows: list[list[str]] = []
        started = False
        for line in text_lines(stream, where, 'a trajectory table'):
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            cells = _split(text, layout.delimiter)
            if not started:
                if not (cells and _is_number(cells[0])):
                    continue  # the header
                started = True
            if len(cells) < width:
                cells += [''] * (width - len(cells))
            rows.append([cells[index] for index in wanted])
            if len(rows) == chunk_size:
                chunk = _chunk(where, topic, sequence, rows, roles, layout, length_scale,
                               angle_scale, options, state, orientations,
                               stream_fraction(stream, size))
                rows = []
                if chunk is not None:
                    sequence += len(chunk.stamp_ns)
                    yield chunk
        if rows:
            chunk = _chunk(where, topic, sequence, rows, roles, layout, length_scale,
                           angle_scale, options, state, orientations, 1.0)
            if chunk is not None:
                sequence += len(chunk.stamp_ns)
                yield chunk
    notes.extend(state.notes(where))
    notes.extend(orientations.notes(where))
    if sequence == 1:
        raise BagError(f'{where}: {layout.dialect} without a single readable pose row')
    yield last_chunk(where, topic, sequence)


@dataclass
class _Counts:
    unreadable: int = 0
    no_pose: int = 0

    def notes(self, where: str) -> list[str]:
        said = []
        if self.no_pose:
            said.append(f'{where}: {self.no_pose} row(s) without a full pose (empty or NaN '
                        'cells) dropped')
        if self.unreadable:
            said.append(f'{where}: {self.unreadable} unreadable row(s) (text where a number '
                        'belongs) skipped')
        return said


def _chunk(where: str, topic: str, sequence: int, rows: list[list[str]], roles: list[str],
           layout: TableLayout, length_scale: float, angle_scale: float,
           options: ReadOptions, counts: _Counts, orientations: Orientations,
           read_fraction: float) -> PoseChunk | None:
    """Parse a block of rows into a chunk; None when none of them holds a pose."""
    scale = layout.time_scale_ns
    stamps = [exact_ns(row[0], scale) for row in rows]
    values = np.full((len(rows), len(roles)), np.nan)
    keep = np.zeros(len(rows), dtype=bool)
    for index, (row, stamp) in enumerate(zip(rows, stamps)):
        if stamp is None:
            counts.unreadable += 1
            continue
        try:
            values[index] = [float(cell) if cell else math.nan for cell in row[1:]]
        except ValueError:
            counts.unreadable += 1
            continue
        keep[index] = True
    full = keep & np.isfinite(values).all(axis=1)
    counts.no_pose += int((keep & ~full).sum())
    if not full.any():
        return None
    times = np.array([stamp for stamp, use in zip(stamps, full) if use], dtype=np.int64)
    values = values[full]
    position = values[:, :2] * length_scale
    has_z = 'z' in roles
    z = values[:, 2] * length_scale if has_z else np.zeros(len(values))
    position = to_z_up(np.column_stack([position, z]), options.up_axis)
    if 'yaw' in roles:
        heading = wrap_angle(values[:, -1] * angle_scale
                             + forward_angle_rad(options.forward_axis))
    else:
        heading = orientations.quaternion_headings(values[:, -4:], options.up_axis,
                                                   options.forward_axis)
    return pose_chunk(where, topic, sequence, times, position[:, 0], position[:, 1], heading,
                      z=position[:, 2] if has_z else None, read_fraction=read_fraction)
