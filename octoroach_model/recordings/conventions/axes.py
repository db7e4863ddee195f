"""
Axes: which way is up in an input's world, which body axis points forward, and the heading.

Inputs state poses in their own world frame: Vicon and ROS (REP 103) have z up, OptiTrack
Motive y up, a camera's optical frame y down. Every reader turns its poses into one z-up world
first (`ReadOptions.up_axis` names the input's up axis), then takes the heading as the yaw of
the body's forward axis (`ReadOptions.forward_axis`) in that world: the angle of its floor
projection from world +x towards +y. Everything the package writes (bags, ROS messages) is z
up, as REP 103 wants.

The turn from the input's world to the z-up world is a quarter or half turn about a
horizontal axis (`UP_ROTATIONS`), so the input's up axis becomes +z and the turn is proper
(never a mirror image).

Orientations are checked where they are read: a quaternion whose length is 0 (what some
receivers publish for an occluded body) or off 1 by more than `QUATERNION_NORM_TOLERANCE`,
and a rotation matrix that is not orthonormal within `ROTATION_TOLERANCE`, is a dropped frame,
counted (`Orientations`) and said in the notes.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from octoroach_model.recordings.conventions.quaternions import lengths, rotation_from_quaternion

# The axes an option may name, as unit vectors of the frame they belong to.
AXIS_VECTORS: dict[str, tuple[float, float, float]] = {
    'x': (1.0, 0.0, 0.0), '-x': (-1.0, 0.0, 0.0),
    'y': (0.0, 1.0, 0.0), '-y': (0.0, -1.0, 0.0),
    'z': (0.0, 0.0, 1.0), '-z': (0.0, 0.0, -1.0),
}
UP_AXES = ('z', 'y', '-y', 'x', '-x', '-z')
FORWARD_AXES = ('x', 'y', '-x', '-y', 'z', '-z')
# input world -> z-up world; each maps its key's axis onto +z
UP_ROTATIONS: dict[str, np.ndarray] = {
    'z': np.eye(3),
    'y': np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),   # +90 deg about x
    '-y': np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),  # -90 deg about x
    'x': np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),   # -90 deg about y
    '-x': np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),  # +90 deg about y
    '-z': np.diag([1.0, -1.0, -1.0]),                                      # 180 deg about x
}
# A quaternion whose length is off 1 by more than this is not a rotation: a dropped frame.
# Text exports round to 4-6 digits (a length off by 1e-4 at most); 1 % is far beyond rounding.
QUATERNION_NORM_TOLERANCE = 0.01
# A rotation matrix whose columns are off orthonormal by more than this is a dropped frame.
ROTATION_TOLERANCE = 0.01
# Below this length of the forward axis' floor projection the heading is undefined.
MIN_HORIZONTAL = 1e-9


def axis_vector(axis: str) -> np.ndarray:
    """Return the unit vector of an axis name ('x', '-y', ...)."""
    return np.asarray(AXIS_VECTORS[axis], dtype=float)


def to_z_up(points: np.ndarray, up_axis: str) -> np.ndarray:
    """Return (..., 3) points of the input's world in the z-up world."""
    if up_axis == 'z':
        return np.asarray(points, dtype=float)
    return np.asarray(points, dtype=float) @ UP_ROTATIONS[up_axis].T


def input_axis_of(z_up_axis: int, up_axis: str) -> str:
    """Name the input's axis that became z-up axis 0, 1 or 2 (x, y, z) under `up_axis`."""
    column = UP_ROTATIONS[up_axis][z_up_axis]  # row: which input axis feeds this z-up axis
    index = int(np.argmax(np.abs(column)))
    return ('x', 'y', 'z')[index]


def headings_from_rotations(rotations: np.ndarray, up_axis: str,
                            forward_axis: str) -> np.ndarray:
    """
    (F,) heading of (F, 3, 3) body-to-input-world rotations: yaw of the forward axis, z up.

    NaN where the rotation is NaN or the forward axis points (almost) straight up or down.
    """
    forward = rotations @ axis_vector(forward_axis)          # (F, 3) in the input's world
    forward = to_z_up(forward, up_axis)
    horizontal = np.hypot(forward[..., 0], forward[..., 1])
    with np.errstate(invalid='ignore'):
        level_enough = horizontal >= MIN_HORIZONTAL
    return np.where(level_enough, np.arctan2(forward[..., 1], forward[..., 0]), np.nan)


@dataclass
class Orientations:
    """
    Counts of orientations that were not rotations, over one stream: its dropped frames.

    `zero`: all-zero quaternions (an occluded body, as some ROS 2 receivers publish it);
    `non_unit`: quaternions off unit length by more than QUATERNION_NORM_TOLERANCE, or rotation
    matrices off orthonormal by more than ROTATION_TOLERANCE; `non_finite`: NaN or infinite.
    """

    zero: int = 0
    non_unit: int = 0
    non_finite: int = 0

    def quaternion_headings(self, xyzw: np.ndarray, up_axis: str,
                            forward_axis: str) -> np.ndarray:
        """(n,) headings of (n, 4) quaternions x, y, z, w; NaN (counted) where not a rotation."""
        q = np.asarray(xyzw, dtype=float).reshape(-1, 4)
        norm = lengths(q)
        finite = np.isfinite(norm)
        zero = finite & (norm == 0.0)
        unit = finite & (np.abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE)
        self.non_finite += int((~finite).sum())
        self.zero += int(zero.sum())
        self.non_unit += int((finite & ~zero & ~unit).sum())
        headings = np.full(len(q), np.nan)
        if unit.any():
            rotations = rotation_from_quaternion(q[unit])
            headings[unit] = headings_from_rotations(rotations, up_axis, forward_axis)
        return headings

    def matrix_headings(self, rotations: np.ndarray, up_axis: str,
                        forward_axis: str) -> np.ndarray:
        """(n,) headings of (n, 3, 3) rotation matrices; NaN (counted) where not a rotation."""
        matrices = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
        finite = np.isfinite(matrices).all(axis=(1, 2))
        safe = np.where(finite[:, None, None], matrices, 0.0)
        zero = finite & (np.abs(safe).max(axis=(1, 2)) == 0.0)
        error = np.abs(np.einsum('fji,fjk->fik', safe, safe) - np.eye(3)).max(axis=(1, 2))
        proper = np.linalg.det(safe) > 0.0
        unit = finite & ~zero & (error <= ROTATION_TOLERANCE) & proper
        self.non_finite += int((~finite).sum())
        self.zero += int(zero.sum())
        self.non_unit += int((finite & ~zero & ~unit).sum())
        headings = np.full(len(matrices), np.nan)
        if unit.any():
            headings[unit] = headings_from_rotations(matrices[unit], up_axis, forward_axis)
        return headings

    def notes(self, where: str) -> list[str]:
        """Say how many frames were dropped for an orientation that is not a rotation."""
        said = []
        if self.zero:
            said.append(f'{where}: {self.zero} pose(s) with an all-zero orientation (an '
                        'occluded body) dropped')
        if self.non_unit:
            said.append(f'{where}: {self.non_unit} pose(s) whose orientation is not a rotation '
                        f'(a quaternion off unit length, or a matrix off orthonormal, by more '
                        f'than {QUATERNION_NORM_TOLERANCE:g}) dropped')
        if self.non_finite:
            said.append(f'{where}: {self.non_finite} pose(s) with a non-finite orientation '
                        'dropped')
        return said


def axes_words(up_axis: str, forward_axis: str) -> str:
    """Say the axis convention in the words of the notes."""
    up = '' if up_axis == 'z' else f"the input's {up_axis} axis turned to up (z); "
    return (f'{up}heading = yaw of the body {forward_axis} axis (pi/2: walking along '
            'world +y)')


def forward_angle_rad(forward_axis: str) -> float:
    """Return the angle of an in-plane forward axis from the body x axis (x, y, -x, -y)."""
    x, y, z = AXIS_VECTORS[forward_axis]
    if z:
        raise ValueError(f'forward axis {forward_axis} is not in the body x-y plane')
    return math.atan2(y, x)


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles folded into (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
