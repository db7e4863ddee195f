"""
C3D files: the robot's pose from its markers, by a least-squares rigid fit per frame.

Read with the `c3d` package's public `Reader`, frame by frame, so a file of any length is
converted in bounded memory (one chunk of frames at a time). The mapping (docs/formats_mocap.md):

- Markers: POINT:LABELS (and LABELS2, ...), ``Subject:Marker`` as Vicon writes them; labels
  listed as model outputs (POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS, REACTIONS) and
  unlabelled trajectories (``*12``) are not markers. Modelled and virtual markers (labels in
  POINT:MODELED_MARKERS, as Nexus lists the points its model computes, or in
  POINT:VIRTUAL_MARKERS) are left out unless `ReadOptions.markers` names them. Unprefixed
  labels belong to the only name in SUBJECTS:NAMES, if there is one. The body is
  `ReadOptions.markers` if given (``Subject:Marker`` or bare names), else every marker of the
  subject (`ReadOptions.subject`, or the only subject); it needs 3, moving as one rigid body
  (`shared.MarkerBody`).
- Units: POINT:UNITS (mm, cm or m) converted to metres; no unit means mm, with a note.
- Gaps: a point with a negative residual (or NaN) was not seen. A frame is fitted on the
  body markers it has; with fewer than 3 (or all on one line) it is a dropped frame.
- Layout: the body's reference marker layout is given (`layout`, metres in the body frame),
  or made from the first complete frames (every body marker seen): body axes = world axes
  at the first of them, origin at the markers' centroid. Then the heading is relative to
  that frame's orientation; give the layout for headings in the robot's own frame.
- Pose: x, y of the body origin in the z-up world (`ReadOptions.up_axis`); heading = yaw of
  the body axis `ReadOptions.forward_axis`.
- Time: frame f at POINT:RATE r is stamped (f - first frame) / r; one file is one stream
  (`topic` ``c3d:<subject>``), cut into runs by the splitter at gaps longer than gap_s.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
import warnings

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.mocap.shared import (
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
    unit_scale,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import shown

try:
    import c3d
except ImportError:  # not in package.xml: a ROS install may lack it, and then only C3D fails
    c3d = None

__all__ = ['C3dReader', 'iter_c3d_pose_chunks']

MODEL_OUTPUT_PARAMETERS = ('ANGLES', 'FORCES', 'MOMENTS', 'POWERS', 'SCALARS', 'REACTIONS')
# Points a model computed from the markers (Nexus' Plug-in Gait joint centres, segment
# origins): not measured, left out of a body unless named
MODELLED_MARKER_PARAMETERS = ('MODELED_MARKERS', 'VIRTUAL_MARKERS')
# What the c3d package raises on a malformed file: besides the usual ValueError, struct.error
# and EOFError, a broken header can reach its own bugs (an UnboundLocalError, a
# ZeroDivisionError); any of them means "not a readable C3D file", never a traceback.
_C3D_ERRORS = (Exception,)


@contextmanager
def _quiet() -> Iterator[None]:
    """Silence the c3d package (absent analog data, cut files): notes say what matters."""
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        yield


def _strings(reader: c3d.Reader, name: str) -> list[str]:
    """Return a string parameter as a list of stripped strings ([] when absent)."""
    param = reader.get(name)
    if param is None:
        return []
    values = np.atleast_1d(param.string_array).ravel()
    return [str(value).strip() for value in values]


def _point_labels(reader: c3d.Reader) -> list[str]:
    """Return the points' labels in storage order (LABELS, then LABELS2, ...)."""
    labels = _strings(reader, 'POINT:LABELS')
    extra = 2
    while len(labels) < reader.point_used and reader.get(f'POINT:LABELS{extra}') is not None:
        labels += _strings(reader, f'POINT:LABELS{extra}')
        extra += 1
    labels = labels[:reader.point_used]
    return labels + [''] * (reader.point_used - len(labels))


def _marker_labels(reader: c3d.Reader, options: ReadOptions) -> tuple[list[str], list[str]]:
    """
    Return the point labels with what is not a marker blanked out, and the modelled ones left.

    Model outputs are never markers; modelled and virtual markers are blanked unless
    `options.markers` names markers (then they may be among them).
    """
    outputs = set()
    for name in MODEL_OUTPUT_PARAMETERS:
        outputs.update(_strings(reader, f'POINT:{name}'))
    modelled = set()
    for name in MODELLED_MARKER_PARAMETERS:
        modelled.update(_strings(reader, f'POINT:{name}'))
    labels = ['' if label in outputs else label for label in _point_labels(reader)]
    if options.markers:
        return labels, []
    left_out = [label for label in labels if label and label in modelled]
    return ['' if label in modelled else label for label in labels], left_out


def _layout_rows(where: str, layout: Mapping[str, Sequence[float]]) -> np.ndarray:
    """
    Return the given layout as (M, 3) rows, in its own order: that of the chosen markers.

    `select_body_markers` finds one marker per name of the layout, in the layout's order. A
    refused row is named by the layout's name, not by the file's label it found.
    """
    rows = []
    for name, value in layout.items():
        try:
            row = np.asarray(value, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise BagError(f'{where}: the layout of marker {name.strip()} must be (x, y, z) in '
                           f'metres, got {shown(value)}') from None
        rows.append(row)
    return np.array(rows)


class C3dReader(PoseInput):
    """A C3D file's pose streams (`iter_c3d_pose_chunks`), for `POSE_READERS`."""

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the file's pose streams, chunk by chunk."""
        return iter_c3d_pose_chunks(self.path, self.options, self.notes, chunk_size)


def iter_c3d_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                         chunk_size: int = 10_000, *,
                         layout: Mapping[str, Sequence[float]] | None = None,
                         ) -> Iterator[PoseChunk]:
    """
    Pose samples of the rigid body in a C3D file, chunk by chunk (mapping: module doc).

    `layout` maps marker names (``Marker`` or ``Subject:Marker``) to their (x, y, z) position
    in metres in the body frame; it also names the body's markers. The stream ends with one
    chunk whose `is_last` is True. What was converted, dropped or assumed goes to `notes`.
    Raises BagError with a one-line reason for a file that cannot be read or is ambiguous.
    """
    if c3d is None:
        raise BagError('C3D files cannot be read by this installation (the c3d package is '
                       'missing: pip install c3d)')
    path = Path(path)
    where = str(path)
    chunk_size = max(1, int(chunk_size))
    try:
        handle = path.open('rb')
    except OSError as exc:
        raise BagError(f'{where}: cannot open: {exc.strerror or exc}') from None
    with handle:
        try:
            with _quiet():
                reader = c3d.Reader(handle)
                labels, modelled = _marker_labels(reader, options)
                subjects = _strings(reader, 'SUBJECTS:NAMES')
                units = _strings(reader, 'POINT:UNITS')
                rate_hz = float(reader.point_rate)
                first_frame, last_frame = int(reader.first_frame), int(reader.last_frame)
        except _C3D_ERRORS as exc:
            raise BagError(f'{where}: not a readable C3D file ({_reason(exc)})') from None
        rate_hz = check_rate(rate_hz, where)
        if reader.point_used == 0:
            raise BagError(f'{where}: the C3D file holds no 3D points (markers)')
        default_subject = subjects[0] if len(subjects) == 1 else ''
        chosen = select_body_markers(where, labels, options, default_subject,
                                     named=tuple(layout) if layout else ())
        names = [labels[index].strip() for index in chosen]
        unit = units[0] if units and units[0] else ''
        scale = unit_scale(unit, LENGTH_UNITS, 'length', f'{where} POINT:UNITS') if unit \
            else 1e-3
        body = MarkerBody(where, names, options,
                          _layout_rows(where, layout) if layout else None)
        if body.layout_m is None:
            body.set_layout_from_frames(*_first_complete(reader, chosen, scale, where))
        frame_count = last_frame - first_frame + 1
        if modelled:
            notes.append(f'{where}: {len(modelled)} modelled or virtual marker(s) left out of '
                         f'the body (POINT:MODELED_MARKERS): {", ".join(modelled[:12])}'
                         + (' ...' if len(modelled) > 12 else ''))
        notes.append(
            f'{where}: C3D, {len(names)} body markers ({", ".join(names)}) at {rate_hz:g} Hz, '
            f'frames {first_frame}..{last_frame}; '
            f'{length_words(unit) if unit else "positions in mm (no POINT:UNITS) converted to m"}'
            f'; pose by a least-squares rigid fit to {body.layout_origin}; '
            f'{axis_words(options)}; stamps from frame {first_frame} at 0 s')
        subject = split_label(names[0])[0] or default_subject or options.subject or path.stem
        topic = f'c3d:{subject}'
        read = 0
        sequence = 1
        for frames, markers_m in _frame_blocks(reader, chosen, scale, chunk_size, where):
            read += len(frames)
            x, y, z, heading, valid = body.poses(markers_m)
            if not valid.any():
                continue
            yield pose_chunk(where, topic, sequence, stamps_ns(frames[valid], first_frame,
                                                               rate_hz),
                             x[valid], y[valid], heading[valid], z=z[valid],
                             read_fraction=read / max(1, frame_count))
            sequence += int(valid.sum())
        truncated = read < frame_count
        if truncated:
            notes.append(f'{where}: the file ends after {read} of its {frame_count} frames '
                         '(truncated)')
        notes.extend(body.summary.notes(where, ', '.join(names)))
        yield last_chunk(where, topic, sequence, truncated=truncated)


def _reason(exc: BaseException) -> str:
    """
    Name what went wrong by the kind of error only.

    The c3d package's messages can quote names and values read from the file, and an error
    must never show a file's content.
    """
    known: dict[type[BaseException], str] = {EOFError: 'the file ends early',
                                             MemoryError: 'a size in it is too large'}
    return known.get(type(exc), f'{type(exc).__name__} while parsing it')


def _frame_blocks(reader: c3d.Reader, chosen: list[int], scale: float, block: int,
                  where: str) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield frame numbers (F,) and markers (F, M, 3) in metres, NaN where not seen."""
    # NaN coordinates are "not seen" downstream (fit_rigid): the package's own check per frame
    # costs a third of the reading time.
    frames_iter = reader.read_frames(copy=False, check_nan=False)
    index = np.asarray(chosen)
    while True:
        numbers = np.empty(block, dtype=np.int64)
        points = np.empty((block, len(index), 4), dtype=np.float32)
        count = 0
        try:
            with _quiet():
                for frame_no, frame_points, _ in frames_iter:
                    numbers[count] = frame_no
                    points[count] = frame_points[index, :4]
                    count += 1
                    if count == block:
                        break
        except _C3D_ERRORS as exc:
            raise BagError(f'{where}: unreadable C3D frame data ({_reason(exc)})') from None
        if count == 0:
            return
        with np.errstate(invalid='ignore', over='ignore'):   # garbage in a broken file: NaN
            markers = points[:count, :, :3].astype(np.float64) * scale
            markers[~(points[:count, :, 3] >= 0)] = np.nan
        yield numbers[:count], markers
        if count < block:
            return


def _first_complete(reader: c3d.Reader, chosen: list[int], scale: float,
                    where: str) -> tuple[np.ndarray, int]:
    """Return up to LAYOUT_FRAMES frames (metres) with every body marker seen, and the first."""
    return first_complete_frames(_frame_blocks(reader, chosen, scale, 1000, where), len(chosen))
