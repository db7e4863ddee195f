"""
Quaternions (x, y, z, w), the one place the package does their arithmetic.

- the heading of the standard bag: `heading_to_quaternion` and back, `quaternion_to_heading`
  (the yaw about z of any quaternion, normalised first);
- `rotation_from_quaternion`: (n, 3, 3) rotation matrices, for the heading of a body's forward
  axis (`axes`);
- the pose of a frame reached through /tf_static (`compose`, `product`, `rotate`) and how far
  a body has turned (`norm`, `angle_between_rad`), one message at a time in plain floats.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


Quaternion = tuple[float, float, float, float]  # qx, qy, qz, qw
FullPose = tuple[float, float, float, float, float, float, float]  # x, y, z, qx, qy, qz, qw


def heading_to_quaternion(heading: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, z, w) of the unit quaternion that turns the world frame by `heading` about z."""
    half = 0.5 * np.asarray(heading, dtype=float)
    zeros = np.zeros_like(half)
    with np.errstate(invalid='ignore'):  # a non-finite heading gives a NaN quaternion
        return zeros, zeros.copy(), np.sin(half), np.cos(half)


def quaternion_to_heading(qx: ArrayLike, qy: ArrayLike, qz: ArrayLike,
                          qw: ArrayLike) -> np.ndarray:
    """
    Yaw in (-pi, pi] of any quaternion; non-unit ones are normalised first.

    A zero or non-finite quaternion gives NaN, so that sample is dropped downstream.
    """
    x, y, z, w = (np.asarray(q, dtype=float) for q in (qx, qy, qz, qw))
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        norm = np.sqrt(x * x + y * y + z * z + w * w)
        usable = np.isfinite(norm) & (norm > 0.0)
        norm = np.where(usable, norm, 1.0)
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
        yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.where(usable, yaw, np.nan)


def lengths(xyzw: np.ndarray) -> np.ndarray:
    """(n,) lengths of (n, 4) quaternions; inf or NaN where a component is not finite."""
    q = np.asarray(xyzw, dtype=float)
    with np.errstate(invalid='ignore', over='ignore'):
        return np.sqrt((q * q).sum(axis=1))


def rotation_from_quaternion(xyzw: np.ndarray) -> np.ndarray:
    """Rotations of quaternions (x, y, z, w), normalised first; a zero one gives NaN."""
    q = np.asarray(xyzw, dtype=float).reshape(-1, 4)
    with np.errstate(invalid='ignore', divide='ignore'):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def product(a: Quaternion, b: Quaternion) -> Quaternion:
    """Hamilton product a b: the turn b, then a."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def rotate(q: Quaternion, v: tuple[float, float, float]) -> tuple[float, float, float]:
    """Vector `v` turned by the unit quaternion `q`."""
    x, y, z, _ = product(product(q, (*v, 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return x, y, z


def compose(outer: FullPose, inner: FullPose) -> FullPose:
    """Pose `inner` (in the frame of `outer`) expressed in the parent of `outer`."""
    moved = rotate(outer[3:], inner[:3])
    return (outer[0] + moved[0], outer[1] + moved[1], outer[2] + moved[2],
            *product(outer[3:], inner[3:]))


def norm(q: Quaternion) -> float:
    """Length of one quaternion."""
    return math.sqrt(sum(c * c for c in q))


def angle_between_rad(unit: Quaternion, q: Quaternion, q_norm: float) -> float:
    """Angle in [0, pi] of the turn from the unit quaternion `unit` to `q` of length `q_norm`."""
    dot = abs(sum(a * b for a, b in zip(unit, q))) / q_norm
    return 2.0 * math.acos(min(1.0, dot))
