"""
Rigid bodies in motion capture: rotations as Vicon writes them, and the pose from markers.

Pure numpy, vectorised over frames, for the Vicon CSV and C3D readers:

- `rotation_from_helical`, `rotation_from_euler_xyz` (and `quaternions.rotation_from_quaternion`):
  the three ways a Vicon export states an object's orientation, as (n, 3, 3) rotation matrices
  that turn body coordinates into world coordinates;
- `fit_rigid`: the least-squares rotation and translation that carry a body's reference
  marker layout onto the markers seen in each frame (Kabsch / Umeyama without scale), with
  missing markers left out frame by frame;
- `layout_from_frames`: a reference layout from frames in which every marker was seen.

The heading of a fitted pose is `axes.headings_from_rotations`: the yaw of the body's
forward axis in the z-up world.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


MIN_MARKERS = 3
# The markers seen in a frame must span a plane: the second singular value of their centred
# layout at least this fraction of the first, else the rotation about their line is unknown.
MIN_SPREAD_RATIO = 1e-3


class RigidFit(NamedTuple):
    """
    Pose of a rigid body per frame: world = rotation @ body + translation.

    rotation : (F, 3, 3); translation : (F, 3) in the markers' unit; valid : (F,) False where
    fewer than 3 markers were seen or they lie on one line (rotation and translation NaN);
    rms_residual : (F,) root-mean-square distance between seen and fitted markers.
    """

    rotation: np.ndarray
    translation: np.ndarray
    valid: np.ndarray
    rms_residual: np.ndarray


def _skew(vectors: np.ndarray) -> np.ndarray:
    """(n, 3, 3) cross-product matrices of (n, 3) vectors."""
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                     np.stack([-y, x, zero], -1)], -2)


def rotation_from_helical(vectors_rad: np.ndarray) -> np.ndarray:
    """
    Rotations of helical (axis-angle) vectors: unit axis times angle in radians.

    Rodrigues' formula R = I + a [r]x + b [r]x^2 with a = sin(t)/t, b = (1 - cos t)/t^2,
    t = |r|; series for small t keep it exact near the identity.
    """
    vectors = np.asarray(vectors_rad, dtype=float).reshape(-1, 3)
    angle = np.linalg.norm(vectors, axis=1)
    small = angle < 1e-6
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    skew = _skew(vectors)
    return np.eye(3) + a[:, None, None] * skew + b[:, None, None] * (skew @ skew)


def _axis_rotation(angle: np.ndarray, axis: int) -> np.ndarray:
    """(n, 3, 3) rotations by `angle` (rad) about world axis 0, 1 or 2."""
    cos, sin = np.cos(angle), np.sin(angle)
    matrix = np.zeros((len(angle), 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    matrix[:, axis, axis] = 1.0
    matrix[:, i, i] = cos
    matrix[:, j, j] = cos
    matrix[:, i, j] = -sin
    matrix[:, j, i] = sin
    return matrix


def rotation_from_euler_xyz(angles_rad: np.ndarray) -> np.ndarray:
    """
    Rotations of Euler XYZ angles (rad): about x, then the new y, then the new z.

    R = Rx(a) @ Ry(b) @ Rz(c) for angles (a, b, c); a level body (a = b = 0) has R = Rz(c).
    """
    angles = np.asarray(angles_rad, dtype=float).reshape(-1, 3)
    return (_axis_rotation(angles[:, 0], 0) @ _axis_rotation(angles[:, 1], 1)
            @ _axis_rotation(angles[:, 2], 2))


def fit_rigid(layout: np.ndarray, markers: np.ndarray) -> RigidFit:
    """
    Least-squares pose of a rigid body in every frame (Kabsch / Umeyama, no scale).

    layout : (M, 3) marker positions in the body frame.
    markers : (F, M, 3) marker positions in the world, same unit, NaN where not seen.
    The rotation comes from the SVD of the cross-covariance of the seen markers about their
    centroids, with the sign fixed so that it never reflects; frames with fewer than
    `MIN_MARKERS` seen markers, or seen markers on one line, are not valid.
    """
    layout = np.asarray(layout, dtype=float)
    markers = np.asarray(markers, dtype=float)
    seen = np.isfinite(markers).all(axis=2)
    weight = seen.astype(float)
    count = weight.sum(axis=1)
    enough = count >= MIN_MARKERS
    safe_count = np.where(enough, count, 1.0)[:, None]
    world = np.where(seen[..., None], markers, 0.0)
    world_centroid = np.einsum('fm,fmi->fi', weight, world) / safe_count
    body_centroid = weight @ layout / safe_count
    body = (layout[None] - body_centroid[:, None]) * weight[..., None]
    world_centred = (world - world_centroid[:, None]) * weight[..., None]
    cross = np.einsum('fmi,fmj->fij', body, world_centred)
    u, _, vt = np.linalg.svd(cross)
    v = np.swapaxes(vt, 1, 2)
    sign = np.sign(np.linalg.det(v @ np.swapaxes(u, 1, 2)))
    sign = np.where(sign == 0.0, 1.0, sign)
    v[:, :, 2] *= sign[:, None]
    rotation = v @ np.swapaxes(u, 1, 2)
    translation = world_centroid - np.einsum('fij,fj->fi', rotation, body_centroid)

    spread = np.linalg.svd(body, compute_uv=False)
    valid = enough & (spread[:, 1] > MIN_SPREAD_RATIO * spread[:, 0])
    fitted = np.einsum('fij,mj->fmi', rotation, layout) + translation[:, None]
    squared = (((fitted - world) ** 2).sum(axis=2) * weight).sum(axis=1)
    rms = np.sqrt(squared / safe_count[:, 0])
    rotation[~valid] = np.nan
    translation[~valid] = np.nan
    rms[~valid] = np.nan
    return RigidFit(rotation, translation, valid, rms)


def layout_from_frames(frames: np.ndarray) -> np.ndarray:
    """
    (M, 3) body-frame layout from (K, M, 3) frames in which every marker was seen.

    The body frame is the world frame moved to the markers' centroid in the first frame (as
    Vicon Tracker does when an object is created); the other frames are fitted to it and
    averaged in the body frame, which evens out measurement noise.
    """
    frames = np.asarray(frames, dtype=float)
    reference = frames[0] - frames[0].mean(axis=0)
    fit = fit_rigid(reference, frames)
    if not fit.valid.any():      # no frame spans a plane: no layout (the caller says why)
        return np.full(frames.shape[1:], np.nan)
    in_body = np.einsum('kji,kmj->kmi', fit.rotation, frames - fit.translation[:, None])
    return in_body[fit.valid].mean(axis=0)


def layout_spans_a_plane(layout: np.ndarray) -> bool:
    """Tell whether `layout` (M, 3) has at least 3 markers, not all on one line."""
    layout = np.asarray(layout, dtype=float)
    if len(layout) < MIN_MARKERS or not np.isfinite(layout).all():
        return False
    spread = np.linalg.svd(layout - layout.mean(axis=0), compute_uv=False)
    return bool(spread[1] > MIN_SPREAD_RATIO * spread[0])
