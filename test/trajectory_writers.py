"""
Independent writers of the trajectory and Qualisys formats, each from its published layout.

Written from the formats' own documentation, not from the readers' code:

- TUM trajectory (TUM RGB-D benchmark, "File Formats"): one pose per line,
  ``timestamp tx ty tz qx qy qz qw`` separated by spaces, seconds since the Unix epoch, metres,
  a unit quaternion; comment lines start with ``#``;
- EuRoC/ASL CSV (EuRoC MAV data set, ``mav0/state_groundtruth_estimate0/data.csv``): the
  header ``#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [],
  q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], ...`` (velocities and biases follow), integer
  nanoseconds, the quaternion w first;
- a CSV whose header names its columns (the package's documented names);
- Qualisys QTM TSV exports (docs.qualisys.com, "Motion data (.tsv)", "6DOF data"):
  ``NAME<tab>value`` header lines, then rows of Frame, Time and per marker X Y Z in mm, or per
  6DOF body X Y Z, Roll Pitch Yaw (deg), Residual and Rot[0..8], the rotation matrix column by
  column, as in a QTM 6DOF export (``Frame Time <body> X Y Z Roll ...``, rows ending with a
  tab).

Orientations come from scipy's Rotation.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

EPOCH_S = 1_305_031_102  # a TUM RGB-D recording's second
EUROC_EXTRA = ('v_RS_R_x [m s^-1]', 'v_RS_R_y [m s^-1]', 'v_RS_R_z [m s^-1]',
               'b_w_RS_S_x [rad s^-1]', 'b_w_RS_S_y [rad s^-1]', 'b_w_RS_S_z [rad s^-1]',
               'b_a_RS_S_x [m s^-2]', 'b_a_RS_S_y [m s^-2]', 'b_a_RS_S_z [m s^-2]')


def planar_pose(poses: np.ndarray, height_m: float = 0.03) -> tuple[np.ndarray, Rotation]:
    """Positions (F, 3) and orientations of planar poses (F, 3): x, y, heading, z = height."""
    positions = np.column_stack([poses[:, 0], poses[:, 1], np.full(len(poses), height_m)])
    return positions, Rotation.from_euler('z', poses[:, 2, None])


def _number(value: float, digits: int = 9) -> str:
    return f'{value:.{digits}f}'


def write_tum(path: Path, stamps_ns: np.ndarray, positions: np.ndarray, rotations: Rotation, *,
              comments: Sequence[str] = ('ground truth trajectory',
                                         'timestamp tx ty tz qx qy qz qw'),
              extra_comment_at: int | None = None) -> Path:
    """Write a TUM trajectory: seconds with 9 decimals (exact ns), metres, qx qy qz qw."""
    quaternions = rotations.as_quat()
    lines = [f'# {text}' for text in comments]
    for index, (stamp, position, q) in enumerate(zip(stamps_ns, positions, quaternions)):
        if index == extra_comment_at:
            lines.append('# a comment in the middle of the file')
        seconds, nanos = divmod(int(stamp), 1_000_000_000)
        lines.append(' '.join([f'{seconds}.{nanos:09d}', *map(_number, position),
                               *map(_number, q)]))
    path.write_text('\n'.join(lines) + '\n')
    return path


def write_euroc(path: Path, stamps_ns: np.ndarray, positions: np.ndarray,
                rotations: Rotation, *, units_on_time: bool = True) -> Path:
    """Write an EuRoC/ASL state CSV: ns, p_RS_R (m), q_RS w x y z, velocities and biases."""
    quaternions = rotations.as_quat()  # x, y, z, w
    time = '#timestamp [ns]' if units_on_time else '#timestamp'
    header = [time, 'p_RS_R_x [m]', 'p_RS_R_y [m]', 'p_RS_R_z [m]', 'q_RS_w []', 'q_RS_x []',
              'q_RS_y []', 'q_RS_z []', *EUROC_EXTRA]
    lines = [', '.join(header)]
    for stamp, position, q in zip(stamps_ns, positions, quaternions):
        values = [*position, q[3], q[0], q[1], q[2], *np.zeros(len(EUROC_EXTRA))]
        lines.append(','.join([str(int(stamp)), *(_number(v) for v in values)]))
    path.write_text('\n'.join(lines) + '\n')
    return path


def write_pose_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[str]], *,
                   delimiter: str = ',', preamble: Sequence[str] = ()) -> Path:
    """Write a CSV with a header line naming its columns (and comment lines before it)."""
    lines = [*preamble, delimiter.join(header)]
    lines += [delimiter.join(row) for row in rows]
    path.write_text('\n'.join(lines) + '\n')
    return path


def _qtm_header(kind: str, frames: int, rate_hz: float | str,
                lines: Sequence[str], file_version: bool, events: int) -> list[str]:
    header = ['FILE_VERSION\t2.0.0'] if file_version else []
    header += [f'NO_OF_FRAMES\t{frames}', 'NO_OF_CAMERAS\t8']
    header += lines[:1]
    header += [f'FREQUENCY\t{rate_hz}', 'NO_OF_ANALOG\t0', 'ANALOG_FREQUENCY\t0',
               'DESCRIPTION\t--', 'TIME_STAMP\t2024-05-14, 10:02:11.218\t8411.52004730',
               f'DATA_INCLUDED\t{kind}']
    header += [f'EVENT\tstart\t{1 + 10 * index}\t{0.1 * index:.3f}' for index in range(events)]
    return header + list(lines[1:])


def write_qtm_3d(path: Path, rate_hz: float, markers: dict[str, np.ndarray], *,
                 types: dict[str, str] | None = None, missing: str = '',
                 column_names: bool = True, file_version: bool = True,
                 first_frame: int = 1, events: int = 2) -> Path:
    """
    Write a QTM 3D TSV export: markers (F, 3) in metres written as mm, NaN as `missing`.

    `types` gives a marker's TRAJECTORY_TYPES entry (Measured by default; Virtual for one a
    6DOF body computed).
    """
    names = list(markers)
    count = len(next(iter(markers.values())))
    kinds = [(types or {}).get(name, 'Measured') for name in names]
    lines = [f'NO_OF_MARKERS\t{len(names)}', 'MARKER_NAMES\t' + '\t'.join(names),
             'TRAJECTORY_TYPES\t' + '\t'.join(kinds)]
    out = _qtm_header('3D', count, rate_hz, lines, file_version, events)
    if column_names:
        out.append('\t'.join(['Frame', 'Time', *(f'{name} {axis}' for name in names
                                                 for axis in 'XYZ')]))
    for index in range(count):
        cells = [str(first_frame + index), f'{index / rate_hz:.5f}']
        for name in names:
            point = markers[name][index]
            cells += [missing] * 3 if not np.isfinite(point).all() \
                else [f'{value * 1e3:.6f}' for value in point]
        out.append('\t'.join(cells) + '\t')
    path.write_text('\n'.join(out) + '\n')
    return path


def write_qtm_6d(path: Path, rate_hz: float | str,
                 bodies: dict[str, tuple[np.ndarray, Rotation, np.ndarray]], *,
                 missing: str = 'NaN', column_names: bool = True, file_version: bool = False,
                 times_s: np.ndarray | None = None) -> Path:
    """
    Write a QTM 6DOF TSV export: per body X Y Z (mm), Roll Pitch Yaw, Residual, Rot[0..8].

    `bodies` maps a name to (positions (F, 3) in metres, Rotation of F, tracked (F,) bool).
    Roll, pitch and yaw are the Qualisys standard angles (R = Rx(roll) Ry(pitch) Rz(yaw));
    Rot[0..8] is R column by column. An untracked frame has `missing` in every cell.
    """
    names = list(bodies)
    count = len(next(iter(bodies.values()))[0])
    lines = [f'NO_OF_BODIES\t{len(names)}', 'BODY_NAMES\t' + '\t'.join(names)]
    out = _qtm_header('6D', count, rate_hz, lines, file_version, 0)
    fields = ['Y', 'Z', 'Roll', 'Pitch', 'Yaw', 'Residual', *(f'Rot[{k}]' for k in range(9))]
    if column_names:
        columns = ['Frame', 'Time']
        for name in names:
            columns += [f'{name} X', *fields]
        out.append('\t'.join(columns) + '\t')
    step = 1.0 / float(rate_hz) if rate_hz != 'EXT' else 0.0
    for index in range(count):
        time = times_s[index] if times_s is not None else index * step
        cells = [str(index + 1), f'{time:.5f}']
        for name in names:
            positions, rotations, tracked = bodies[name]
            if not tracked[index]:
                cells += [missing] * 16
                continue
            matrix = rotations[index].as_matrix()
            angles = rotations[index].as_euler('XYZ', degrees=True)
            cells += [f'{value * 1e3:.6f}' for value in positions[index]]
            cells += [f'{value:.6f}' for value in angles] + ['0.84000']
            cells += [f'{value:.9f}' for value in matrix.flatten(order='F')]
        out.append('\t'.join(cells) + '\t')
    path.write_text('\n'.join(out) + '\n')
    return path
