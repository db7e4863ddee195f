"""
Test helpers for the motion-capture readers: independent writers and the run splitter.

The writers follow the formats' own documentation, not the readers' code: Vicon CSV exports
as Vicon lays them out (section name, frame rate, names, ``Frame,Sub Frame,...``, units, one
row per frame, empty cells for an untracked frame), rotations from scipy; C3D files through
the `ezc3d` package (the reader uses the `c3d` package).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
import csv
from pathlib import Path

import ezc3d
import numpy as np
from scipy.spatial.transform import Rotation

from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.runs.run_set import _StreamSplitter, RunSet

# A marker plate on the robot, metres in the body frame (x forward, z up): not symmetric, so
# every pose is distinct, and not flat, like real markers on posts.
BODY_LAYOUT_M = {
    'front': (0.07, 0.004, 0.03),
    'left': (-0.04, 0.05, 0.025),
    'right': (-0.045, -0.05, 0.035),
    'top': (0.0, 0.01, 0.06),
}


def runs_from_chunks(chunks: Iterable[PoseChunk], gap_s: float = 0.5) -> RunSet:
    """Cuts pose chunks into runs the way `read_runs` does for bag chunks."""
    splitters: dict[tuple[str, str], _StreamSplitter] = {}
    notes: list[str] = []
    for chunk in chunks:
        key = (chunk.source, chunk.topic)
        if key not in splitters:
            splitters[key] = _StreamSplitter(chunk, bool(chunk.marker_topic), gap_s)
        splitters[key].feed(chunk)
        if chunk.is_last:
            notes.extend(splitters[key].notes)
    return RunSet([run for splitter in splitters.values() for run in splitter.runs], notes)


def body_rotations(heading: np.ndarray, roll: np.ndarray | None = None,
                   pitch: np.ndarray | None = None, forward_angle: float = 0.0) -> Rotation:
    """
    Orientations whose body axis at `forward_angle` has yaw `heading`, tilted by roll/pitch.

    Yaw first, then pitch about the new y, then roll about the new x (scipy 'ZYX'); the
    forward axis is turned back by `forward_angle` about the body z axis.
    """
    heading = np.asarray(heading, dtype=float)
    roll = np.zeros_like(heading) if roll is None else roll
    pitch = np.zeros_like(heading) if pitch is None else pitch
    yaw = Rotation.from_euler('ZYX', np.column_stack([heading, pitch, roll]))
    return yaw * Rotation.from_euler('z', -forward_angle)


def _format(value: float) -> str:
    return repr(float(value))


def write_vicon_csv(path: Path, frames: np.ndarray, rates: dict, objects: dict, *,
                    section: str = 'Objects', rotation: str = 'helical',
                    angle_unit: str = 'deg', length_unit: str = 'mm',
                    quaternion_first: bool = False, delimiter: str = ',',
                    end_with_newline: bool = True, extra_sections: Sequence[str] = ()) -> Path:
    """
    Write a Vicon CSV export of rigid objects, laid out as Vicon's documentation shows.

    `objects` maps the name cell (e.g. 'Global Angle octo:octo' or 'octo:octo') to
    (positions (F, 3) in metres, Rotation of F, tracked (F,) bool). `rotation` is 'helical'
    (RX RY RZ as an axis-angle vector), 'euler' (RX RY RZ Euler XYZ) or 'quaternion'
    (RX RY RZ RW). `rates` gives {'hz': rate}. Untracked frames are written as empty cells.
    """
    scale = {'mm': 1e3, 'm': 1.0, 'cm': 1e2}[length_unit]
    to_angle = np.degrees if angle_unit == 'deg' else (lambda value: value)
    rotation_names = ['RX', 'RY', 'RZ', 'RW'] if rotation == 'quaternion' else ['RX', 'RY', 'RZ']
    names_row, columns_row, units_row = ['', ''], ['Frame', 'Sub Frame'], ['', '']
    blocks = []
    for name, (positions, rotations, tracked) in objects.items():
        if rotation == 'quaternion':
            angles = rotations.as_quat()  # x, y, z, w
            angle_units = [''] * 4
        elif rotation == 'euler':
            angles = to_angle(rotations.as_euler('XYZ'))
            angle_units = [angle_unit] * 3
        else:
            angles = to_angle(rotations.as_rotvec())
            angle_units = [angle_unit] * 3
        translation = positions * scale
        if quaternion_first or rotation != 'quaternion':
            components = rotation_names + ['TX', 'TY', 'TZ']
            values = np.column_stack([angles, translation])
            units = angle_units + [length_unit] * 3
        else:
            components = ['TX', 'TY', 'TZ'] + rotation_names
            values = np.column_stack([translation, angles])
            units = [length_unit] * 3 + angle_units
        names_row += [name] + [''] * (len(components) - 1)
        columns_row += components
        units_row += units
        blocks.append((values, tracked))
    with path.open('w', newline='') as stream:
        writer = csv.writer(stream, delimiter=delimiter, lineterminator='\r\n')
        for title in extra_sections:
            writer.writerows([[title], ['1000'], ['', '', 'Plate 1 - Force', '', ''],
                              ['Frame', 'Sub Frame', 'Fx', 'Fy', 'Fz'], ['', '', 'N', 'N', 'N'],
                              [1, 0, 0.1, 0.2, 0.3], []])
        writer.writerows([[section], [str(rates['hz'])], names_row, columns_row, units_row])
        rows = []
        for index, frame in enumerate(frames):
            row = [int(frame), 0]
            for values, tracked in blocks:
                row += [_format(v) for v in values[index]] if tracked[index] \
                    else [''] * values.shape[1]
            rows.append(row)
        writer.writerows(rows)
    if not end_with_newline:
        text = path.read_bytes()
        path.write_bytes(text.rstrip(b'\r\n'))
    return path


def write_marker_csv(path: Path, frames: np.ndarray, rate_hz: float,
                     markers: dict[str, np.ndarray]) -> Path:
    """Write a Vicon CSV Trajectories section: per marker X Y Z in mm, NaN as empty cells."""
    names_row, columns_row, units_row = ['', ''], ['Frame', 'Sub Frame'], ['', '']
    for name in markers:
        names_row += [name, '', '']
        columns_row += ['X', 'Y', 'Z']
        units_row += ['mm'] * 3
    with path.open('w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\r\n')
        writer.writerows([['Trajectories'], [str(rate_hz)], names_row, columns_row, units_row])
        for index, frame in enumerate(frames):
            row = [int(frame), 0]
            for positions in markers.values():
                row += ['' if not np.isfinite(v) else _format(v * 1e3)
                        for v in positions[index]]
            writer.writerow(row)
    return path


def markers_on_body(poses: np.ndarray, layout_m: dict[str, Sequence[float]],
                    forward_angle: float = 0.0, height_m: float = 0.0) -> dict[str, np.ndarray]:
    """World positions (F, 3) of each layout marker on a body at planar `poses` (F, 3)."""
    rotations = body_rotations(poses[:, 2], forward_angle=forward_angle)
    origin = np.column_stack([poses[:, 0], poses[:, 1], np.full(len(poses), height_m)])
    return {name: rotations.apply(np.asarray(offset, dtype=float)) + origin
            for name, offset in layout_m.items()}


def write_c3d(path: Path, rate_hz: float, markers: dict[str, np.ndarray], *,
              units: str = 'mm', first_frame: int = 1, subjects: Sequence[str] = (),
              model_outputs: dict[str, np.ndarray] | None = None,
              modelled: Sequence[str] = (), uses_prefixes: bool = True) -> Path:
    """
    Write a C3D file with ezc3d: markers (F, 3) in metres, NaN where not seen.

    Not-seen points are written with residual -1 (how C3D marks them); `model_outputs`
    are extra points listed in POINT:ANGLES, as Nexus stores joint angles; `modelled` names
    points (among `markers`) listed in POINT:MODELED_MARKERS, as Nexus lists the virtual
    points its model computes (joint centres, segment origins).
    """
    scale = {'mm': 1e3, 'm': 1.0}[units]
    points = dict(markers)
    if model_outputs:
        points.update(model_outputs)
    names = list(points)
    n_frames = len(next(iter(points.values())))
    data = np.ones((4, len(names), n_frames))
    residuals = np.zeros((1, len(names), n_frames))
    for index, name in enumerate(names):
        values = np.asarray(points[name], dtype=float)
        seen = np.isfinite(values).all(axis=1)
        data[:3, index, :] = np.where(seen[:, None], values * scale, 0.0).T
        residuals[0, index, ~seen] = -1.0
    c3d = ezc3d.c3d()
    c3d['parameters']['POINT']['RATE']['value'] = [rate_hz]
    c3d['parameters']['POINT']['LABELS']['value'] = names
    c3d['parameters']['POINT']['UNITS']['value'] = [units]
    c3d['header']['points']['first_frame'] = first_frame - 1
    c3d['data']['points'] = data
    c3d['data']['meta_points']['residuals'] = residuals
    c3d['data']['meta_points']['camera_masks'] = np.zeros((7, len(names), n_frames), bool)
    if model_outputs:
        c3d.add_parameter('POINT', 'ANGLES', list(model_outputs))
    if modelled:
        c3d.add_parameter('POINT', 'MODELED_MARKERS', list(modelled))
        c3d.add_parameter('POINT', 'MODELED_MARKER_UNITS', [units])
    if subjects:
        c3d.add_parameter('SUBJECTS', 'NAMES', list(subjects))
        c3d.add_parameter('SUBJECTS', 'USES_PREFIXES', [1 if uses_prefixes else 0])
    c3d.write(str(path))
    return path
