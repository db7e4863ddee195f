"""
Qualisys QTM TSV exports: 3D marker trajectories and 6DOF rigid bodies, streamed row by row.

QTM's TSV export (docs.qualisys.com, "Motion data (.tsv)"; the 6DOF columns as a QTM 6DOF
export writes them) is a tab-separated text file: a header of ``NAME<tab>value...`` lines,
then one row per frame.

- Header (when the export's "Include TSV header" is on, which this reader needs):
  FILE_VERSION (2.0.0, absent before), NO_OF_FRAMES, NO_OF_CAMERAS, NO_OF_MARKERS or
  NO_OF_BODIES, FREQUENCY (Hz; ``EXT`` with an edge-triggered external timebase), NO_OF_ANALOG,
  ANALOG_FREQUENCY, DESCRIPTION, TIME_STAMP, DATA_INCLUDED (``3D``, ``6D``; ``2D`` is refused),
  EVENT lines, and MARKER_NAMES with TRAJECTORY_TYPES (3D) or BODY_NAMES (6D). Other names
  are passed over.
- Data: with "write column headers" a names row (``Frame``, ``Time``, then ``<marker> X``,
  ``<marker> Y``, ``<marker> Z`` per marker, or per body ``<body> X``, ``Y``, ``Z``,
  ``Roll``, ``Pitch``, ``Yaw``, ``Residual``, ``Rot[0]`` ... ``Rot[8]``); without it the
  columns are in that order, with or without Frame and Time in front (told by the count).
- Units: positions in millimetres (QTM's unit), converted to metres; the 6DOF rotation is
  read from ``Rot[0..8]``, the rotation matrix R (body to world, Pglobal = R Plocal +
  Porigin) column by column (R[i][j] = Rot[i + 3 j]); the Euler angles are not used (their
  convention is a QTM setting).
- Missing data: an empty cell, ``NaN`` or ``NULL``, and a marker at exactly (0, 0, 0) (QTM
  can write null data as 0), is not seen; a 6DOF frame whose rotation is not a rotation
  (all zeros, not orthonormal) is a dropped frame (`axes.Orientations`).

3D: the body is `ReadOptions.markers` or every marker, trajectories of type ``Virtual``
(computed from a 6DOF body, not measured) left out unless named; its pose is the rigid fit of
`shared.MarkerBody`. 6D: the body is `ReadOptions.subject`, or the only one. Time: frame f at
FREQUENCY r is (f - first frame) / r; with ``EXT``, the Time column. The world is turned to z
up (`ReadOptions.up_axis`; QTM's default is z up). One file is one stream (``tsv:<name>``).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
import math
from pathlib import Path
import re

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.recordings.conventions.axes import Orientations, to_z_up
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.mocap.shared import (
    axis_words,
    check_rate,
    choose_subject,
    first_complete_frames,
    last_chunk,
    MarkerBody,
    pose_chunk,
    PoseInput,
    select_body_markers,
    stamps_ns,
    stream_fraction,
    text_lines,
)
from octoroach_model.recordings.options import ReadOptions

__all__ = ['QualisysTsvReader', 'TsvHeader', 'iter_tsv_pose_chunks', 'read_tsv_header']

MM = 1e-3
MAX_FRAME = 1 << 40  # frame numbers beyond this are damage (a year at 10 kHz is 2**38)
BODY_FIELDS = ('X', 'Y', 'Z', 'Roll', 'Pitch', 'Yaw', 'Residual',
               *(f'Rot[{index}]' for index in range(9)))
MISSING = ('', 'nan', 'null', '-')
_KEY = re.compile(r'^[A-Z][A-Z0-9_]*$')
WHAT = 'a Qualisys TSV export'


@dataclass
class TsvHeader:
    """A QTM TSV header: its named values, the column names (if written), where data start."""

    values: dict[str, list[str]] = field(default_factory=dict)
    events: int = 0
    columns: list[str] | None = None
    data_line: int = 0  # 1-based number of the first data row

    def first(self, key: str) -> str:
        """Return the first value of a header line ('' when absent)."""
        found = self.values.get(key) or ['']
        return found[0]


def _cells(line: str) -> list[str]:
    cells = [cell.strip() for cell in line.rstrip('\r\n').split('\t')]
    while cells and not cells[-1]:
        cells.pop()  # QTM ends rows with a tab
    return cells


def read_tsv_header(path: Path) -> TsvHeader:
    """Read the header lines of a QTM TSV export, up to its first data row."""
    where = str(path)
    header = TsvHeader()
    try:
        with path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
            for number, line in enumerate(text_lines(stream, where, WHAT), 1):
                cells = _cells(line)
                if not cells:
                    continue
                if cells[0] == 'Frame' or (cells[0] and cells[0][0].isdigit()):
                    header.columns = cells if cells[0] == 'Frame' else None
                    header.data_line = number + (1 if cells[0] == 'Frame' else 0)
                    return header
                if not _KEY.match(cells[0]):
                    raise BagError(f'{where}: line {number}: not a Qualisys TSV header line '
                                   '(a NAME in capitals, then tab-separated values)')
                if cells[0] == 'EVENT':
                    header.events += 1
                else:
                    header.values[cells[0]] = cells[1:]
    except OSError as exc:
        raise BagError(f'{where}: cannot read: {exc.strerror or exc}') from None
    raise BagError(f'{where}: a Qualisys TSV header without data rows')


def _rate(where: str, header: TsvHeader) -> float | None:
    """Return the frame rate, or None with an external (edge-triggered) timebase."""
    text = header.first('FREQUENCY')
    if text.upper() == 'EXT':
        return None
    try:
        return check_rate(float(text), f'{where}: FREQUENCY')
    except ValueError:
        raise BagError(f'{where}: FREQUENCY must be a number of Hz or EXT') from None


class QualisysTsvReader(PoseInput):
    """A Qualisys TSV export's pose streams (`iter_tsv_pose_chunks`), for `POSE_READERS`."""

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the file's pose streams, chunk by chunk."""
        return iter_tsv_pose_chunks(self.path, self.options, self.notes, chunk_size)


def iter_tsv_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                         chunk_size: int = 10_000) -> Iterator[PoseChunk]:
    """
    Pose samples of a QTM TSV export (3D markers or 6DOF bodies), chunk by chunk.

    Mapping: module docstring. Raises BagError with a one-line reason for a header QTM does
    not write, 2D data, an ambiguous body or missing columns.
    """
    path = Path(path)
    where = str(path)
    header = read_tsv_header(path)
    included = header.first('DATA_INCLUDED').upper()
    if not included:
        included = '6D' if 'BODY_NAMES' in header.values else \
            '3D' if 'MARKER_NAMES' in header.values else ''
    if included == '2D':
        raise BagError(f'{where}: a Qualisys TSV export of 2D camera data; export 3D or 6DOF '
                       'data')
    if included not in ('3D', '6D'):
        raise BagError(f'{where}: a Qualisys TSV header without DATA_INCLUDED 3D or 6D (and '
                       'without MARKER_NAMES or BODY_NAMES)')
    rate = _rate(where, header)
    rows = _Rows(path, header, chunk_size)
    if included == '6D':
        yield from _body_chunks(where, header, rate, rows, options, notes)
    else:
        yield from _marker_chunks(where, header, rate, rows, options, notes)


class _Rows:
    """Data rows of a TSV export in blocks: frame numbers, times and the wanted cells."""

    def __init__(self, path: Path, header: TsvHeader, block: int) -> None:
        """Read rows of `path` from the header's first data row, `block` at a time."""
        self.path, self.header, self.block = path, header, max(1, block)
        self.unreadable = 0
        self.fraction = math.nan
        self.width = 0

    def blocks(self, wanted: list[int], frame_column: int | None, time_column: int | None
               ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Yield frame numbers (F,), times [s] (F,) and values (F, len(wanted))."""
        where = str(self.path)
        size = max(1, self.path.stat().st_size)
        with self.path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
            texts: list[list[str]] = []
            row_number = 0
            for number, line in enumerate(text_lines(stream, where, WHAT), 1):
                if number < self.header.data_line:
                    continue
                cells = _cells(line)
                if not cells:
                    continue
                row_number += 1
                self.width = max(self.width, len(cells))
                picked = [str(row_number) if frame_column is None else _cell(cells, frame_column),
                          '' if time_column is None else _cell(cells, time_column)]
                texts.append(picked + [_cell(cells, index) for index in wanted])
                if len(texts) == self.block:
                    self.fraction = stream_fraction(stream, size)
                    yield self._parse(texts)
                    texts = []
            if texts:
                self.fraction = 1.0
                yield self._parse(texts)

    def _parse(self, texts: list[list[str]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        values = np.full((len(texts), len(texts[0])), np.nan)
        good = np.ones(len(texts), dtype=bool)
        for index, row in enumerate(texts):
            try:
                values[index] = [math.nan if cell.lower() in MISSING else float(cell)
                                 for cell in row]
            except ValueError:
                good[index] = False
        frames = values[:, 0]
        with np.errstate(invalid='ignore'):
            good &= np.isfinite(frames) & (frames == np.round(frames)) & \
                (np.abs(frames) < MAX_FRAME)
        self.unreadable += int((~good).sum())
        kept = values[good]
        return kept[:, 0].astype(np.int64), kept[:, 1], kept[:, 2:]


def _cell(cells: list[str], index: int) -> str:
    return cells[index] if index < len(cells) else ''


def _leading(where: str, header: TsvHeader, rows: _Rows, per_item: int, items: int
             ) -> tuple[int | None, int | None, int]:
    """Return the Frame and Time columns (None if absent) and the first item's column."""
    if header.columns is not None:
        frame = 0 if header.columns[0] == 'Frame' else None
        time = header.columns.index('Time') if 'Time' in header.columns else None
        return frame, time, 0  # items are found by name
    width = _data_width(rows)
    extra = width - per_item * items
    if extra == 2:
        return 0, 1, 2
    if extra == 1:
        return 0, None, 1
    if extra == 0:
        return None, None, 0
    raise BagError(f'{where}: the data rows have {width} columns, which fits neither '
                   f'{per_item} per item for {items} item(s) nor Frame and Time before them')


def _times_ns(where: str, frames: np.ndarray, times_s: np.ndarray, rate: float | None,
              first_frame: int) -> np.ndarray:
    if rate is not None:
        return stamps_ns(frames, first_frame, rate)
    if not np.isfinite(times_s).all():
        raise BagError(f'{where}: FREQUENCY is EXT (an external timebase) and the rows have no '
                       'Time column to stamp them by; export with time data')
    return np.round(times_s * 1e9).astype(np.int64)


def _body_chunks(where: str, header: TsvHeader, rate: float | None, rows: _Rows,
                 options: ReadOptions, notes: list[str]) -> Iterator[PoseChunk]:
    """Yield the chunks of one 6DOF body: X Y Z (mm) and the rotation matrix Rot[0..8]."""
    bodies = header.values.get('BODY_NAMES') or []
    if not bodies:
        raise BagError(f'{where}: a 6DOF export without BODY_NAMES')
    body = choose_subject(where, bodies, options.subject, 'body')
    index = bodies.index(body)
    if header.columns is not None:
        start = _named_column(where, header.columns, f'{body} X', body)
        found = header.columns[start + 1:start + len(BODY_FIELDS)]
        expected = list(BODY_FIELDS[1:])
        if found != expected:
            raise BagError(f'{where}: the columns after "{body} X" are not Y Z Roll Pitch Yaw '
                           'Residual Rot[0]..Rot[8]')
        frame, time, _ = _leading(where, header, rows, len(BODY_FIELDS), len(bodies))
    else:
        frame, time, first = _leading(where, header, rows, len(BODY_FIELDS), len(bodies))
        start = first + index * len(BODY_FIELDS)
    wanted = [start, start + 1, start + 2, *range(start + 7, start + 16)]
    topic = f'tsv:{body}'
    notes.append(f'{where}: Qualisys TSV 6DOF export, body {body} '
                 f'{"at " + format(rate, "g") + " Hz" if rate else "(external timebase)"}: '
                 f'positions in mm converted to m, orientation from the rotation matrix '
                 f'Rot[0..8]; {axis_words(options)}; stamps from the first frame at 0 s')
    orientations = Orientations()
    sequence = 1
    first_frame: int | None = None
    for frames, times, values in rows.blocks(wanted, frame, time):
        if not len(frames):
            continue
        if first_frame is None:
            first_frame = int(frames[0])
        position = to_z_up(values[:, :3] * MM, options.up_axis)
        matrices = values[:, 3:].reshape(-1, 3, 3).transpose(0, 2, 1)  # column by column
        heading = orientations.matrix_headings(matrices, options.up_axis, options.forward_axis)
        seen = np.isfinite(position).all(axis=1) & np.isfinite(heading)
        if not seen.any():
            continue
        stamps = _times_ns(where, frames[seen], times[seen], rate, first_frame)
        yield pose_chunk(where, topic, sequence, stamps, position[seen, 0], position[seen, 1],
                         heading[seen], z=position[seen, 2], read_fraction=rows.fraction)
        sequence += int(seen.sum())
    if rows.unreadable:
        notes.append(f'{where}: {rows.unreadable} unreadable row(s) skipped')
    notes.extend(orientations.notes(where))
    yield last_chunk(where, topic, sequence)


def _named_column(where: str, columns: list[str], name: str, item: str) -> int:
    if name not in columns:
        raise BagError(f'{where}: no column "{name}" for {item} in the column names row')
    return columns.index(name)


def _data_width(rows: _Rows) -> int:
    """Return the number of cells of the first data row."""
    where = str(rows.path)
    with rows.path.open(encoding='utf-8-sig', errors='replace', newline='') as stream:
        for number, line in enumerate(text_lines(stream, where, WHAT), 1):
            if number >= rows.header.data_line and _cells(line):
                return len(_cells(line))
    return 0


def _marker_chunks(where: str, header: TsvHeader, rate: float | None, rows: _Rows,
                   options: ReadOptions, notes: list[str]) -> Iterator[PoseChunk]:
    """Yield the chunks of a rigid body fitted to marker trajectories (X Y Z in mm)."""
    names = header.values.get('MARKER_NAMES') or []
    if not names:
        raise BagError(f'{where}: a 3D export without MARKER_NAMES')
    types = header.values.get('TRAJECTORY_TYPES') or []
    virtual = [name for name, kind in zip(names, types) if kind.lower() == 'virtual']
    labels = list(names) if options.markers else \
        ['' if name in virtual else name for name in names]
    chosen = select_body_markers(where, labels, options)
    body_names = [names[index] for index in chosen]
    if header.columns is not None:
        starts = [_named_column(where, header.columns, f'{names[index]} X', names[index])
                  for index in chosen]
        frame, time, _ = _leading(where, header, rows, 3, len(names))
    else:
        frame, time, first = _leading(where, header, rows, 3, len(names))
        starts = [first + 3 * index for index in chosen]
    wanted = [start + axis for start in starts for axis in range(3)]
    body = MarkerBody(where, body_names, options)
    blocks = ((frames, _markers_m(values)) for frames, _, values in
              _Rows(rows.path, header, 1000).blocks(wanted, frame, time))
    body.set_layout_from_frames(*first_complete_frames(blocks, len(body_names)))
    topic = f'tsv:{path_subject(where)}'
    if virtual and not options.markers:
        notes.append(f'{where}: {len(virtual)} virtual trajectory(ies) left out of the body: '
                     f'{", ".join(virtual[:12])}')
    notes.append(f'{where}: Qualisys TSV 3D export, {len(body_names)} body markers '
                 f'({", ".join(body_names)}) '
                 f'{"at " + format(rate, "g") + " Hz" if rate else "(external timebase)"}: '
                 f'positions in mm converted to m; pose by a least-squares rigid fit to '
                 f'{body.layout_origin}; {axis_words(options)}; stamps from the first frame '
                 'at 0 s')
    sequence = 1
    first_frame: int | None = None
    for frames, times, values in rows.blocks(wanted, frame, time):
        if not len(frames):
            continue
        if first_frame is None:
            first_frame = int(frames[0])
        x, y, z, heading, valid = body.poses(_markers_m(values))
        if not valid.any():
            continue
        stamps = _times_ns(where, frames[valid], times[valid], rate, first_frame)
        yield pose_chunk(where, topic, sequence, stamps, x[valid], y[valid], heading[valid],
                         z=z[valid], read_fraction=rows.fraction)
        sequence += int(valid.sum())
    if rows.unreadable:
        notes.append(f'{where}: {rows.unreadable} unreadable row(s) skipped')
    notes.extend(body.summary.notes(where, ', '.join(body_names)))
    yield last_chunk(where, topic, sequence)


def _markers_m(values: np.ndarray) -> np.ndarray:
    """(F, M, 3) marker positions in metres; a marker at exactly (0, 0, 0) is not seen."""
    markers = values.reshape(len(values), -1, 3) * MM
    markers[(markers == 0.0).all(axis=2)] = np.nan
    return markers


def path_subject(where: str) -> str:
    """Return the file name without its suffix, the stream's name."""
    return Path(where).stem
