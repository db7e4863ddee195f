"""
Vicon CSV exports (Tracker, Nexus): the pose of a rigid object, streamed row by row.

A Vicon CSV export is a list of sections separated by a blank line. Each section has a
five-line header and then one row per frame:

1. the section name: ``Objects`` (Tracker's rigid objects), ``Segments`` (Nexus),
   ``Trajectories`` (markers), or another (``Devices``, ``Joints``, ``Model Outputs``: skipped);
2. the frame rate in Hz;
3. the names, one at the first column of each group: ``Subject:Segment`` (Nexus), the
   object's name (Tracker, possibly after ``Global Angle`` and a qualifier in parentheses);
4. the column names: ``Frame``, ``Sub Frame``, then per group ``RX RY RZ TX TY TZ`` (a rigid
   object or segment; ``RX RY RZ RW`` with a ``W`` column are a quaternion) or ``X Y Z``
   (a marker);
5. the units: ``mm`` for positions, ``deg`` or ``rad`` for angles.

The mapping (docs/formats_mocap.md): positions are converted to metres and angles to radians.
RX RY RZ are read as a helical (axis-angle) vector, Vicon's global angle, unless the name
says ``Euler`` (Euler XYZ: about x, then the new y, then the new z) or the group has a W
column (quaternion x, y, z, w). The export does not always say which, so the notes give the
largest difference the Euler reading would make to the heading (none for a level body).
Positions (TX TY TZ) are turned into the z-up world (`ReadOptions.up_axis`); heading = yaw
of the body axis `ReadOptions.forward_axis`. A frame whose cells are empty was not tracked:
it is a dropped frame, and so is a quaternion that is not a rotation (`axes`). With no
Objects or Segments section (or when `ReadOptions.markers` names markers), the pose comes from
the markers of a Trajectories section by the same rigid fit as for C3D files. Frame f at rate
r is stamped (f - first frame) / r; one file is one stream (``csv:<object>``), cut into runs by the
splitter at gaps longer than gap_s.
"""
from __future__ import annotations

from collections.abc import Iterator
import csv
import itertools
import math
from pathlib import Path
import re
from typing import Any, NamedTuple

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.recordings.conventions.axes import (
    headings_from_rotations,
    Orientations,
    to_z_up,
)
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.mocap.rigid import rotation_from_euler_xyz, rotation_from_helical
from octoroach_model.recordings.mocap.shared import (
    ANGLE_UNITS,
    axis_words,
    check_rate,
    first_complete_frames,
    last_chunk,
    LENGTH_UNITS,
    length_words,
    MarkerBody,
    pose_chunk,
    PoseInput,
    select_body_markers,
    split_label,
    stamps_ns,
    stream_fraction,
    text_lines,
    unit_scale,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import listed_names

__all__ = ['ViconCsvReader', 'CsvSection', 'iter_csv_pose_chunks', 'read_csv_sections']

POSE_SECTIONS = ('Objects', 'Segments')
MARKER_SECTION = 'Trajectories'
HEADER_WORDS = ('Objects, Segments or Trajectories section name, frame rate, names, '
                '"Frame,Sub Frame,..." and units lines')
HELICAL, EULER_XYZ, QUATERNION = 'helical vector', 'Euler XYZ angles', 'quaternion'
_QUALIFIED_NAME = re.compile(r'^(global\s+angle(?:\s*\([^)]*\))?)\s*(.*)$', re.IGNORECASE)
_DELIMITERS = (',', ';', '\t')
# Headings under the Euler reading that differ by less than this are "the same" in the notes.
_SAME_HEADING_RAD = 1e-9


class CsvSection(NamedTuple):
    """One section of a Vicon CSV export: its header and where its rows are (1-based)."""

    title: str
    rate_hz: float
    names: list[str]
    columns: list[str]
    units: list[str]
    title_line: int
    data_line: int


class _Group(NamedTuple):
    """The columns of one name in a section: an object, segment or marker."""

    label: str
    qualifier: str
    columns: dict[str, int]
    units: dict[str, str]

    @property
    def subject(self) -> str:
        """Return the subject of ``Subject:Segment`` (Nexus), or the object name (Tracker)."""
        subject, name = split_label(self.label)
        return subject or name


def _cells(line: str, delimiter: str) -> list[str]:
    return [cell.strip() for cell in next(csv.reader([line], delimiter=delimiter), [])]


def _lines(stream: Any, where: str) -> Iterator[str]:
    """Yield the lines of `stream`, refusing one longer than `limits.MAX_CSV_LINE`."""
    return text_lines(stream, where, 'a Vicon CSV export')


def _is_blank(line: str) -> bool:
    """Tell an empty line, or one of delimiters only (a section break)."""
    text = line.strip()
    for delimiter in _DELIMITERS:
        text = text.replace(delimiter, '')
    return not text.strip()


def _delimiter(line: str) -> str:
    """Return the delimiter of a column-names line: the commonest of , ; and tab."""
    return max(_DELIMITERS, key=line.count)


def read_csv_sections(path: Path) -> tuple[str, list[CsvSection], int]:
    """
    Return the delimiter, the sections (headers only) and the cut line of an export.

    The file is read once, line by line, without parsing data rows. The cut line is the
    number of the last line when the file does not end with a line break (an export stopped
    mid-row), else 0. Raises BagError naming what a header must hold when it does not fit.
    """
    where = str(path)
    sections: list[CsvSection] = []
    delimiter = ','
    in_data = False
    number, line = 0, ''
    try:
        with path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
            lines = enumerate(_lines(stream, where), 1)
            for number, line in lines:
                if in_data:
                    in_data = not _is_blank(line)
                    continue
                if _is_blank(line):
                    continue
                header = [(number, line)] + list(itertools.islice(lines, 4))
                if not sections and len(header) == 5:
                    delimiter = _delimiter(header[3][1])
                sections.append(_section(where, header, delimiter))
                in_data = True
                number, line = header[-1]
    except OSError as exc:
        raise BagError(f'{where}: cannot read: {exc.strerror or exc}') from None
    except csv.Error:
        raise BagError(f'{where}: line {number + 1}: not a Vicon CSV export header (a cell '
                       f'longer than {csv.field_size_limit()} characters, or a broken '
                       'quote)') from None
    if not sections:
        raise BagError(f'{where}: empty file; a Vicon CSV export starts with the '
                       f'{HEADER_WORDS}')
    cut_line = number if line and not line.endswith(('\n', '\r')) else 0
    return delimiter, sections, cut_line


def _section(where: str, header: list[tuple[int, str]], delimiter: str) -> CsvSection:
    """Parse the five header lines of a section, or raise BagError saying what is wrong."""
    first_number, first_line = header[0]

    def refuse(number: int, line: str, what: str) -> BagError:
        return BagError(f'{where}: line {number}: not a Vicon CSV export header ({what}); '
                        f'expected the {HEADER_WORDS}')

    title_cells = _cells(first_line, delimiter)
    title = title_cells[0] if title_cells else ''
    if not title or any(title_cells[1:]) or _is_number(title):
        raise refuse(first_number, first_line, 'no section name')
    if len(header) < 5:
        raise refuse(first_number, first_line, 'the header is cut short')
    (rate_number, rate_line), (_, names_line), (columns_number, columns_line), \
        (_, units_line) = header[1:]
    rate_cells = _cells(rate_line, delimiter)
    if not rate_cells or not _is_number(rate_cells[0]):
        raise refuse(rate_number, rate_line, 'no frame rate on the line after the section name')
    columns = _cells(columns_line, delimiter)
    if not columns or columns[0].lower() != 'frame':
        raise refuse(columns_number, columns_line, 'no "Frame" column')
    rate_hz = check_rate(float(rate_cells[0]), f'{where}: line {rate_number}')
    return CsvSection(title, rate_hz, _cells(names_line, delimiter), columns,
                      _cells(units_line, delimiter), first_number, first_number + 5)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _groups(section: CsvSection) -> list[_Group]:
    """Return the named column groups of a section, with their components and units."""
    starts = [index for index, name in enumerate(section.names) if name]
    ends = starts[1:] + [max(len(section.columns), len(section.names))]
    groups = []
    for start, end in zip(starts, ends):
        text = section.names[start]
        match = _QUALIFIED_NAME.match(text)
        qualifier, label = (match.group(1), match.group(2)) if match and match.group(2) \
            else ('', text)
        columns: dict[str, int] = {}
        units: dict[str, str] = {}
        for index in range(start, min(end, len(section.columns))):
            component = section.columns[index].upper()
            if component and component not in columns:
                columns[component] = index
                units[component] = section.units[index] if index < len(section.units) else ''
        groups.append(_Group(label, qualifier, columns, units))
    return groups


def _is_pose_group(group: _Group) -> bool:
    return {'TX', 'TY', 'RX', 'RY', 'RZ'} <= set(group.columns)


def _is_marker_group(group: _Group) -> bool:
    return {'X', 'Y', 'Z'} <= set(group.columns)


class ViconCsvReader(PoseInput):
    """A Vicon CSV export's pose streams (`iter_csv_pose_chunks`), for `POSE_READERS`."""

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the file's pose streams, chunk by chunk."""
        return iter_csv_pose_chunks(self.path, self.options, self.notes, chunk_size)


def iter_csv_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                         chunk_size: int = 10_000) -> Iterator[PoseChunk]:
    """
    Pose samples of the rigid object in a Vicon CSV export, chunk by chunk.

    Mapping: module docstring. The stream ends with one chunk whose `is_last` is True; what
    was converted, dropped or assumed goes to `notes`. Raises BagError with a one-line reason
    for an unknown header, an ambiguous subject or missing columns.
    """
    path = Path(path)
    where = str(path)
    delimiter, sections, cut_line = read_csv_sections(path)
    chunk_size = max(1, int(chunk_size))
    pose_groups = [(section, group) for section in sections if section.title in POSE_SECTIONS
                   for group in _groups(section) if _is_pose_group(group)]
    marker_sections = [section for section in sections if section.title == MARKER_SECTION]
    reader = _RowReader(path, delimiter, cut_line)
    if pose_groups and not options.markers:
        section, group = _choose_pose_group(where, pose_groups, options)
        yield from _object_chunks(where, reader, section, group, options, notes, chunk_size)
    elif marker_sections:
        yield from _marker_chunks(where, reader, marker_sections[0], options, notes,
                                  chunk_size)
    elif options.markers:
        raise BagError(f'{where}: --markers names markers, but the export has no '
                       f'{MARKER_SECTION} section; leave --markers out to read its objects')
    else:
        titles = listed_names(dict.fromkeys(section.title for section in sections))
        raise BagError(f'{where}: no pose in this export: no Objects or Segments section with '
                       f'RX RY RZ TX TY TZ columns, and no Trajectories section (it has '
                       f'{titles})')


def _choose_pose_group(where: str, pose_groups: list[tuple[CsvSection, _Group]],
                       options: ReadOptions) -> tuple[CsvSection, _Group]:
    """Choose the object or segment to read: `options.subject`, or the only subject."""
    wanted = options.subject
    if wanted is not None:
        matching = [(s, g) for s, g in pose_groups if wanted in (g.label, g.subject)]
        if not matching:
            found = listed_names(dict.fromkeys(g.label for _, g in pose_groups))
            raise BagError(f'{where}: no object or subject {wanted!r}; it has {found}')
    else:
        subjects = list(dict.fromkeys(g.subject for _, g in pose_groups))
        if len(subjects) > 1:
            raise BagError(f'{where}: several subjects ({listed_names(subjects)}); pass '
                           '--subject NAME')
        matching = pose_groups
    if len(matching) > 1:
        own = [(s, g) for s, g in matching if split_label(g.label)[1] == g.subject]
        if len(own) != 1:
            labels = ', '.join(g.label for _, g in matching)
            raise BagError(f'{where}: several segments ({labels}); pass --subject '
                           'SUBJECT:SEGMENT')
        matching = own
    return matching[0]


def _rotation_kind(where: str, group: _Group) -> tuple[str, bool]:
    """Return how the group states its rotation, and whether the file says so."""
    qualifier = group.qualifier.lower()
    if 'RW' in group.columns:
        return QUATERNION, True
    if 'quaternion' in qualifier:
        raise BagError(f'{where}: {group.label}: a quaternion needs RX RY RZ RW columns')
    if 'euler' in qualifier:
        return EULER_XYZ, True
    return HELICAL, 'helical' in qualifier


def _common_unit(where: str, group: _Group, components: tuple[str, ...], table: dict,
                 what: str) -> tuple[str, float]:
    units = {group.units.get(component, '') for component in components}
    if len(units) != 1 or not next(iter(units)):
        listed = ' '.join(components)
        raise BagError(f'{where}: {group.label}: the units line must give one {what} unit '
                       f'for {listed} (mm or m; deg or rad), got {_units_found(units)}')
    unit = next(iter(units))
    return unit, unit_scale(unit, table, what, f'{where}: {group.label}')


def _units_found(units: set[str]) -> str:
    """Say what a units line gave columns that need one unit, without quoting the file."""
    named = len(units - {''})
    if not named:
        return 'none'
    return (f'{named} different units' if named > 1 else 'a unit') + (
        ' and a column without one' if '' in units else '')


def _headings(kind: str, values: np.ndarray, angle_scale: float, options: ReadOptions,
              orientations: Orientations) -> np.ndarray:
    """Headings of a block of rotation cells, read as `kind`."""
    up, forward = options.up_axis, options.forward_axis
    if kind == QUATERNION:
        return orientations.quaternion_headings(values, up, forward)
    rotation = rotation_from_euler_xyz(values * angle_scale) if kind == EULER_XYZ \
        else rotation_from_helical(values * angle_scale)
    return headings_from_rotations(rotation, up, forward)


def _object_chunks(where: str, reader: _RowReader, section: CsvSection, group: _Group,
                   options: ReadOptions, notes: list[str],
                   chunk_size: int) -> Iterator[PoseChunk]:
    """Yield the chunks of an Objects/Segments group: TX TY and each frame's rotation."""
    kind, stated = _rotation_kind(where, group)
    rotation_columns = ('RX', 'RY', 'RZ', 'RW') if kind == QUATERNION else ('RX', 'RY', 'RZ')
    length_unit, length_scale = _common_unit(where, group, ('TX', 'TY'), LENGTH_UNITS,
                                             'length')
    angle_words = 'a quaternion (x, y, z, w)'
    angle_scale = 1.0
    if kind != QUATERNION:
        angle_unit, angle_scale = _common_unit(where, group, rotation_columns, ANGLE_UNITS,
                                               'angle')
        angle_words = f'{kind} in {angle_unit}' + (
            ' converted to rad' if angle_unit.lower().startswith('deg') else '')
    has_tz = 'TZ' in group.columns
    if not has_tz and options.up_axis != 'z':
        raise BagError(f'{where}: {group.label}: no TZ column, so --up-axis '
                       f'{options.up_axis} cannot turn the positions')
    lengths = ('TX', 'TY', 'TZ') if has_tz else ('TX', 'TY')
    need = [group.columns[name] for name in lengths + rotation_columns]
    topic = f'csv:{group.label}'
    notes.append(f'{where}: Vicon {section.title} section, {group.label} at '
                 f'{section.rate_hz:g} Hz: {length_words(length_unit)}, '
                 f'rotations read as {angle_words}{"" if stated else " (not stated in the file)"}'
                 f'; {axis_words(options)}; stamps from the first tracked frame at 0 s')
    euler_gap = 0.0
    sequence = 1
    first_frame: int | None = None
    orientations = Orientations()
    width = len(lengths)
    for frames, values in reader.blocks(section, need, chunk_size):
        tracked = np.isfinite(values).all(axis=1)
        frames, values = frames[tracked], values[tracked]
        reader.untracked += int((~tracked).sum())
        if not len(frames):
            continue
        if first_frame is None:
            first_frame = int(frames[0])
        cells = values[:, width:]
        heading = _headings(kind, cells, angle_scale, options, orientations)
        if not stated:
            other = _headings(EULER_XYZ, cells, angle_scale, options, orientations)
            gap = np.abs(np.angle(np.exp(1j * (other - heading))))
            euler_gap = max(euler_gap, float(np.nanmax(gap, initial=0.0)))
        position = values[:, :width] * length_scale
        if not has_tz:
            position = np.column_stack([position, np.full(len(position), np.nan)])
        position = to_z_up(position, options.up_axis)
        yield pose_chunk(where, topic, sequence,
                         stamps_ns(frames, first_frame, section.rate_hz),
                         position[:, 0], position[:, 1], heading,
                         z=position[:, 2] if has_tz else None, read_fraction=reader.fraction)
        sequence += len(frames)
    if not stated:
        differs = (f'differ by up to {math.degrees(euler_gap):.3g} deg'
                   if euler_gap > _SAME_HEADING_RAD else 'be the same')
        notes.append(f'{where}: read as Euler XYZ angles instead, the headings would {differs}')
    notes.extend(reader.notes(where, f'for {group.label}'))
    notes.extend(orientations.notes(where))
    yield last_chunk(where, topic, sequence, truncated=reader.truncated)


def _marker_chunks(where: str, reader: _RowReader, section: CsvSection,
                   options: ReadOptions, notes: list[str],
                   chunk_size: int) -> Iterator[PoseChunk]:
    """Yield the chunks of a rigid body fitted to the markers of a Trajectories section."""
    groups = [group for group in _groups(section) if _is_marker_group(group)]
    labels = [group.label for group in groups]
    chosen = select_body_markers(where, labels, options)
    body_groups = [groups[index] for index in chosen]
    names = [group.label for group in body_groups]
    units = {group.units.get(axis, '') for group in body_groups for axis in 'XYZ'}
    if len(units) != 1 or not next(iter(units)):
        raise BagError(f'{where}: the units line must give one length unit for the markers '
                       f'X Y Z (mm or m), got {_units_found(units)}')
    unit = next(iter(units))
    scale = unit_scale(unit, LENGTH_UNITS, 'length', f'{where}: {MARKER_SECTION}')
    need = [group.columns[axis] for group in body_groups for axis in 'XYZ']
    body = MarkerBody(where, names, options)
    blocks = ((frames, values.reshape(len(frames), -1, 3) * scale) for frames, values in
              _RowReader(reader.path, reader.delimiter, reader.cut_line).blocks(
                  section, need, 1000))
    body.set_layout_from_frames(*first_complete_frames(blocks, len(names)))
    subject = split_label(names[0])[0] or options.subject or path_stem(where)
    topic = f'csv:{subject}'
    notes.append(f'{where}: Vicon {MARKER_SECTION} section, {len(names)} body markers '
                 f'({", ".join(names)}) at {section.rate_hz:g} Hz: {length_words(unit)}; '
                 f'pose by a least-squares rigid fit to {body.layout_origin}; '
                 f'{axis_words(options)}; stamps from the first tracked frame at 0 s')
    sequence = 1
    first_frame: int | None = None
    for frames, values in reader.blocks(section, need, chunk_size):
        x, y, z, heading, valid = body.poses(values.reshape(len(frames), -1, 3) * scale)
        if not valid.any():
            continue
        if first_frame is None:
            first_frame = int(frames[0])
        yield pose_chunk(where, topic, sequence,
                         stamps_ns(frames[valid], first_frame, section.rate_hz),
                         x[valid], y[valid], heading[valid], z=z[valid],
                         read_fraction=reader.fraction)
        sequence += int(valid.sum())
    notes.extend(reader.notes(where, ''))
    notes.extend(body.summary.notes(where, ', '.join(names)))
    yield last_chunk(where, topic, sequence, truncated=reader.truncated)


def path_stem(where: str) -> str:
    """Return the file name without its suffix, a stream name of last resort."""
    return Path(where).stem


class _RowReader:
    """
    Data rows of one section in blocks: frame numbers and the wanted cells as floats.

    Empty cells become NaN; rows without a frame number, with text where a number belongs,
    with a non-zero sub frame, or cut by the end of the file are skipped and counted.
    """

    def __init__(self, path: Path, delimiter: str, cut_line: int) -> None:
        """Read rows of `path`; the row on `cut_line` (if any) is cut and skipped."""
        self.path, self.delimiter, self.cut_line = path, delimiter, cut_line
        self.unreadable = 0
        self.sub_frames = 0
        self.untracked = 0
        self.truncated = False
        self.fraction = math.nan  # how much of the file has been read
        self._first_value = 2

    def blocks(self, section: CsvSection, need: list[int],
               block: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Yield frame numbers (F,) and values (F, len(need)) for up to `block` rows."""
        has_sub_frame = len(section.columns) > 1 and \
            section.columns[1].replace(' ', '').lower() == 'subframe'
        wanted = [0] + ([1] if has_sub_frame else []) + list(need)
        self._first_value = 2 if has_sub_frame else 1
        width = max(wanted) + 1
        size = max(1, self.path.stat().st_size)
        with self.path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
            rows = csv.reader(itertools.islice(_lines(stream, str(self.path)),
                                               section.data_line - 1, None),
                              delimiter=self.delimiter)
            try:
                for parsed in self._rows(rows, section, wanted, width, block):
                    self.fraction = stream_fraction(stream, size)
                    yield parsed
            except csv.Error:
                raise BagError(f'{self.path}: line {section.data_line + rows.line_num - 1}: '
                               f'a cell longer than {csv.field_size_limit()} characters, or '
                               'a broken quote') from None

    def _rows(self, rows: Any, section: CsvSection, wanted: list[int], width: int,
              block: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Blocks of the parsed rows of one section (see `blocks`)."""
        texts: list[list[str]] = []
        for row in rows:
            if not any(cell.strip() for cell in row):
                break
            line = section.data_line + rows.line_num - 1
            if line == self.cut_line:
                self.truncated = True
                break
            if len(row) < width:
                row = row + [''] * (width - len(row))
            texts.append([row[index] for index in wanted])
            if len(texts) == block:
                yield self._parse(texts)
                texts = []
        if texts:
            yield self._parse(texts)

    def _parse(self, texts: list[list[str]]) -> tuple[np.ndarray, np.ndarray]:
        cells = np.char.strip(np.array(texts, dtype=str))
        cells[cells == ''] = 'nan'
        try:
            values = cells.astype(np.float64)
        except ValueError:
            values = np.array([[_number(cell) for cell in row] for row in cells])
            bad = np.array([any(not _is_number(cell) for cell in row) for row in cells])
            self.unreadable += int(bad.sum())
            values = values[~bad]
        frame = values[:, 0]
        numbered = np.isfinite(frame) & (frame == np.round(frame))
        self.unreadable += int((~numbered).sum())
        on_frame = numbered
        if self._first_value == 2:
            on_frame = numbered & ((values[:, 1] == 0) | np.isnan(values[:, 1]))
            self.sub_frames += int((numbered & ~on_frame).sum())
        kept = values[on_frame]
        return kept[:, 0].astype(np.int64), kept[:, self._first_value:]

    def notes(self, where: str, what: str) -> list[str]:
        """Say in plain words which rows were skipped and which frames dropped."""
        notes = []
        if self.untracked:
            notes.append(f'{where}: {self.untracked} frame(s) with empty cells {what} '
                         '(not tracked) dropped'.replace('  ', ' '))
        if self.unreadable:
            notes.append(f'{where}: {self.unreadable} unreadable row(s) skipped')
        if self.sub_frames:
            notes.append(f'{where}: {self.sub_frames} row(s) with a non-zero sub frame skipped')
        if self.truncated:
            notes.append(f'{where}: the last row is cut (no line break at the end of the '
                         'file): skipped')
        return notes


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan
