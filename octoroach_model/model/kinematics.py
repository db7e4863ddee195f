"""
The switching four-bar (eqs. 1-5; derived in docs/model.md), closed form and vectorised.

Body frame: x to the right, y forward, origin at G, hips A = (0, -d/2) and B = (0, d/2).
A stance pair has a rear foot and a front foot; `mirror` = +1 for the right pair (rear leg to
the left: O1 = A + l(-cos phi1, sin phi1), front leg to the right: O2 = B + l(cos phi2,
sin phi2)) and -1 for the left pair (its mirror image). The driven rear angle sweeps linearly
from touchdown to liftoff; the front angle solves closure (3), |O2 - O1| = a, which is
a cos(phi) + b sin(phi) = c and has the closed form phi = atan2(b, a) +- acos(c / hypot(a, b)).

World heading theta is the direction of the body's forward axis, so body vectors map to the
world through a rotation by theta - pi/2.
"""
from __future__ import annotations

from typing import TypeVar

import numpy as np
import numpy.typing as npt

from octoroach_model.arrays import FloatArray, Floats, IntArray
from octoroach_model.model.trig import cos_sin

# x and y of a point in the body frame, metres
Point = tuple[FloatArray, FloatArray]


def feet_in_body(rear_angle: Floats, front_angle: Floats, mirror: Floats,
                 leg_length: float, hip_distance: float) -> tuple[Point, Point]:
    """
    Rear and front foot positions (x, y) in the body frame; arrays broadcast.

    Parameters
    ----------
    rear_angle, front_angle : float or array, any shapes that broadcast
        Leg angles, rad.
    mirror : float or array
        +1 right pair, -1 left pair.
    leg_length, hip_distance : float
        l and d, m.

    Returns
    -------
    rear, front : (x, y) pairs of arrays, the broadcast shape, m.

    """
    half = 0.5 * hip_distance
    rear = (-mirror * leg_length * np.cos(rear_angle),
            -half + leg_length * np.sin(rear_angle))
    front = (mirror * leg_length * np.cos(front_angle),
             half + leg_length * np.sin(front_angle))
    return rear, front


def solve_front_angle(rear_angle: Floats, span: Floats, leg_length: float,
                      hip_distance: float, branch: Floats) -> FloatArray:
    """
    Front leg angle that keeps |front foot - rear foot| = span (closure, eq. 3).

    `branch` (+1 or -1) picks the root of a cos(phi) + b sin(phi) = c; it is fixed at
    touchdown so the angle is continuous through the stance. Where the stance leaves the
    reachable set (|c| > hypot(a, b)) the leg is held at the closest reachable angle and the
    front foot slides: at the Table III spreads this happens in about 0.3 % of right stances
    (about 3 % of 10-cycle runs touch it; docs/model.md, section 11), more at larger spreads.

    Parameters
    ----------
    rear_angle, span, branch : float or array, any shapes that broadcast
        Rear angle (rad), foot-to-foot distance a (m), root (+1 or -1).
    leg_length, hip_distance : float
        l and d, m.

    Returns
    -------
    array, the broadcast shape
        Front angle, rad.

    """
    # P = B - rear foot, seen in the pair's own (mirrored) frame: one equation for both.
    px = leg_length * np.cos(rear_angle)
    py = hip_distance - leg_length * np.sin(rear_angle)
    a = 2.0 * leg_length * px
    b = 2.0 * leg_length * py
    c = span ** 2 - px ** 2 - py ** 2 - leg_length ** 2
    ratio = np.clip(c / np.hypot(a, b), -1.0, 1.0)
    return np.arctan2(b, a) + branch * np.arccos(ratio)


def closure_branch(rear_angle: Floats, front_angle: Floats, leg_length: float,
                   hip_distance: float) -> FloatArray:
    """
    +1 or -1: which root of the closure the touchdown configuration lies on.

    The closure is the same equation for both pairs once the left pair is mirrored, so the
    mirror sign does not enter here.

    Parameters
    ----------
    rear_angle, front_angle : float or array, any shapes that broadcast
        Touchdown angles, rad.
    leg_length, hip_distance : float
        l and d, m.

    Returns
    -------
    array, the broadcast shape
        +1.0 or -1.0.

    """
    px = leg_length * np.cos(rear_angle)
    py = hip_distance - leg_length * np.sin(rear_angle)
    return np.where(front_angle >= np.arctan2(py, px), 1.0, -1.0)


def stance_motion(rear_touchdown: Floats, front_touchdown: Floats, rear_liftoff: Floats,
                  phase: Floats, mirror: Floats, leg_length: float, hip_distance: float
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """
    Pose of G during a stance, relative to the body frame at touchdown.

    Parameters
    ----------
    rear_touchdown, front_touchdown, rear_liftoff : array_like
        Angles (rad) of the stance, any shape broadcastable with `phase`.
    phase : array_like
        Fraction of the stance elapsed, in [0, 1].
    mirror : array_like
        +1 right pair, -1 left pair (broadcastable).
    leg_length : float
        l, metres.
    hip_distance : float
        d, the distance between the hips A and B, metres.

    Returns
    -------
    dx, dy : displacement of G in the touchdown body frame (x right, y forward), metres.
    dheading : heading change since touchdown, radians (counter-clockwise positive).

    """
    rear0, front0 = feet_in_body(rear_touchdown, front_touchdown, mirror,
                                 leg_length, hip_distance)
    span = np.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
    branch = closure_branch(rear_touchdown, front_touchdown, leg_length, hip_distance)

    rear_angle = rear_touchdown + phase * (rear_liftoff - rear_touchdown)
    front_angle = solve_front_angle(rear_angle, span, leg_length, hip_distance, branch)
    rear, front = feet_in_body(rear_angle, front_angle, mirror, leg_length, hip_distance)

    # The foot-to-foot segment is fixed in the world: the body turns by the angle it turned.
    dheading = (np.arctan2(front0[1] - rear0[1], front0[0] - rear0[0])
                - np.arctan2(front[1] - rear[1], front[0] - rear[0]))
    dheading = (dheading + np.pi) % (2.0 * np.pi) - np.pi
    cos_h, sin_h = np.cos(dheading), np.sin(dheading)
    # The rear foot stays where it touched down: G = rear0 - R(dheading) rear.
    dx = rear0[0] - (cos_h * rear[0] - sin_h * rear[1])
    dy = rear0[1] - (sin_h * rear[0] + cos_h * rear[1])
    return dx, dy, dheading


def stance_angles(nominal_angles: npt.ArrayLike, normals: FloatArray, sigma1: float,
                  sigma2: float) -> FloatArray:
    """
    Random angles xi = eta + diag(sigma1 I4, sigma2 I2) Y (eq. 11).

    Parameters
    ----------
    nominal_angles : array_like, shape (6,)
        eta, rad.
    normals : array, shape (..., 6)
        Standard normal draws Y.
    sigma1, sigma2 : float
        Spreads of the touchdown and the liftoff angles, rad.

    Returns
    -------
    array, shape (..., 6)
        Angles, rad.

    """
    scale = np.array([sigma1] * 4 + [sigma2] * 2, dtype=float)
    angles: FloatArray = np.asarray(nominal_angles, dtype=float) + normals * scale
    return angles


def integrate_stances(angles: FloatArray, phase: FloatArray, start_pose: npt.ArrayLike,
                      leg_length: float, hip_distance: float) -> FloatArray:
    """
    Poses of runs made of alternating stances (right pair first).

    Parameters
    ----------
    angles : (n, S, 6) array
        Angles [phi1, phi2, phi3, phi4, phi_R^lo, phi_L^lo] per stance; a right stance (even
        index) uses phi1, phi2, phi_R^lo, a left one phi3, phi4, phi_L^lo.
    phase : (n, T) or (T,) array
        Elapsed stances at each sample (2 * stride frequency * t for a constant gait);
        values beyond S are held at the end of the last stance.
    start_pose : (n, 3) or (3,) array
        x, y, heading at phase 0.
    leg_length : float
        l, metres.
    hip_distance : float
        d, the distance between the hips A and B, metres.

    Returns
    -------
    (n, T, 3) x [m], y [m], heading [rad].

    Notes
    -----
    Same formulas as `stance_motion`, rearranged for speed (results agree to rounding):
    everything fixed during a stance (touchdown feet, span, closure branch, where the stance
    starts in the world) is computed once per stance; per sample only the rear angle's
    cos/sin, one square root for the closure and one arctan2 for the heading remain. The
    front foot comes from the closure's closed form without evaluating the front angle
    (cos and sin of atan2(b, a) +- acos(ratio) by the addition formulas), and G from the
    fixed rear foot seen along the fixed foot-to-foot segment.

    """
    angles = np.asarray(angles, dtype=float)
    n_runs, n_stances = angles.shape[:2]
    geometry = _Geometry(float(leg_length), float(hip_distance))
    start = np.broadcast_to(np.asarray(start_pose, dtype=float), (n_runs, 3))
    phase = np.asarray(phase, dtype=float)
    n_samples = phase.shape[-1]
    poses = np.empty((n_runs, n_samples, 3))
    if n_samples == 0:
        return poses
    # Each sample gathers its stance's values from the table of stances, in blocks of runs
    # small enough that the temporaries stay in the CPU cache. One call per block, not one per
    # stance: with a loop over stances (each broadcast along a shared grid's columns), small
    # per-stance slices made numpy's per-call cost dominate, most for few runs of many
    # stances (the nominal fit's single deterministic path); the results are bit-identical.
    phase = np.broadcast_to(phase, (n_runs, n_samples))
    stance_rows = max(1, _BLOCK * n_stances // n_samples)
    for rows in _row_blocks(n_runs, stance_rows):
        table = _stances(angles[rows], start[rows], geometry)
        flat_table = table.reshape(len(table), -1)
        for sub in _row_blocks(table.shape[2], max(1, _BLOCK // n_samples)):
            block = phase[rows][sub]
            index = np.floor(block).astype(np.intp)
            _clamp(index, 0, n_stances - 1)
            within = _clamp(block - index, 0.0, 1.0)
            # flat position of (stance, run) in the table: stance * runs + run
            flat = index * table.shape[2] + np.arange(sub.start, sub.stop)[:, None]
            geometry.poses(np.take(flat_table, flat, axis=1), within, out=poses[rows][sub])
    return poses


# Samples per block of work: small enough that the temporaries stay in the CPU cache.
_BLOCK = 1 << 13


class _Geometry:
    """The closure and the pose of G for given leg and hip geometry, on arrays of samples."""

    def __init__(self, leg_length: float, hip_distance: float) -> None:
        self.leg_length = leg_length
        self.hip_distance = hip_distance
        # |B - rear foot|^2 = l^2 + d^2 - 2 d l sin(rear) (P of solve_front_angle, squared).
        self.reach_sq = leg_length ** 2 + hip_distance ** 2
        # Heading changes within a stance stay inside (-pi, pi) when the foot-to-foot segment
        # always points forward (its y is at least d - 2 l): then no wrapping is needed.
        self.wrap = not 2.0 * leg_length < hip_distance

    def sweep(self, rear_angle: FloatArray, closure_offset: FloatArray, branch: FloatArray,
              mirror: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """
        Rear foot and foot-to-foot segment in the body frame at the given rear angles.

        closure_offset = (span^2 - 2 l^2 - d^2) / (2 l) per stance, so that the closure's
        ratio c / hypot(a, b) of `solve_front_angle` is (offset + d sin(rear)) / |P|.
        Returns rear_x, rear_y, segment_x, segment_y (segment = front foot - rear foot).
        """
        l, d = self.leg_length, self.hip_distance
        l_cos_r, l_sin_r = cos_sin(rear_angle, l)
        # P = B - rear foot in the pair's frame is (l cos r, d - l sin r)
        p_y = d - l_sin_r
        inv_p = 1.0 / np.sqrt(self.reach_sq - (2.0 * d) * l_sin_r)
        ratio = _clamp((closure_offset + (d / l) * l_sin_r) * inv_p, -1.0, 1.0)
        # front angle f = atan2(b, a) + branch acos(ratio), with (a, b) along P / |P|:
        # l cos f and l sin f by the addition formulas
        scale = l * inv_p
        l_cos_a = l_cos_r * scale
        l_sin_a = p_y * scale
        sin_b = np.sqrt((1.0 - ratio) * (1.0 + ratio))
        sin_b *= branch
        l_cos_f = l_cos_a * ratio - l_sin_a * sin_b
        l_sin_f = l_sin_a * ratio + l_cos_a * sin_b
        rear_x = -mirror * l_cos_r
        rear_y = l_sin_r - 0.5 * d
        segment_x = mirror * (l_cos_f + l_cos_r)
        segment_y = d + (l_sin_f - l_sin_r)
        return rear_x, rear_y, segment_x, segment_y

    def poses(self, stance: FloatArray, within: FloatArray, out: FloatArray) -> None:
        """
        World poses of G at fractions `within` of stances, written into `out` (..., 3).

        stance : the 11 per-stance fields of `_stances`, each broadcastable with `within`
        to out's shape without its last axis.
        """
        (rear_td, sweep, closure_offset, branch, mirror, heading0, segment_angle,
         axis_x, axis_y, foot_x, foot_y) = stance
        rear_x, rear_y, seg_x, seg_y = self.sweep(rear_td + within * sweep, closure_offset,
                                                  branch, mirror)
        dheading = segment_angle - np.arctan2(seg_y, seg_x)
        if self.wrap:
            dheading = (dheading + np.pi) % (2.0 * np.pi) - np.pi
        np.add(heading0, dheading, out=out[..., 2])
        # The rear foot, in coordinates along (u) and across (v) the foot-to-foot segment,
        # whose world direction (axis) is fixed for the stance: G = foot - u axis - v normal.
        inv_s = 1.0 / np.sqrt(seg_x * seg_x + seg_y * seg_y)
        u = (seg_x * rear_x + seg_y * rear_y) * inv_s
        v = (seg_x * rear_y - seg_y * rear_x) * inv_s
        np.subtract(foot_x, axis_x * u - axis_y * v, out=out[..., 0])
        np.subtract(foot_y, axis_y * u + axis_x * v, out=out[..., 1])


def _stances(angles: FloatArray, start: FloatArray, geometry: _Geometry) -> FloatArray:
    """
    Everything constant during each stance, as one (11, S, n) array.

    angles : (n, S, 6); start : (n, 3) pose at the first touchdown. The 11 fields, in order:
    rear touchdown angle, its sweep (liftoff - touchdown), closure offset (see
    `_Geometry.sweep`), closure branch, mirror sign, heading at touchdown, body-frame angle
    of the foot-to-foot segment at touchdown, that segment's world direction (x, y) and the
    rear foot's world position (x, y). Stances come before runs so that one stance's values
    for all runs are contiguous.
    """
    n_runs, n_stances = angles.shape[:2]
    l, d = geometry.leg_length, geometry.hip_distance
    # (S, n) touchdown and liftoff angles: right stances (even) use phi1, phi2, phi_R^lo,
    # left ones phi3, phi4, phi_L^lo.
    by_stance = angles.transpose(2, 1, 0)
    rear_td, front_td, rear_lo = np.empty((3, n_stances, n_runs))
    for field, right, left in ((rear_td, 0, 2), (front_td, 1, 3), (rear_lo, 4, 5)):
        field[0::2] = by_stance[right, 0::2]
        field[1::2] = by_stance[left, 1::2]
    mirror = np.where(np.arange(n_stances) % 2 == 0, 1.0, -1.0)[:, None]

    cos_r, sin_r = cos_sin(rear_td)
    cos_f, sin_f = cos_sin(front_td)
    rear0_x, rear0_y = -mirror * l * cos_r, l * sin_r - 0.5 * d
    seg0_x = mirror * l * (cos_f + cos_r)
    seg0_y = d + l * (sin_f - sin_r)
    span = np.sqrt(seg0_x * seg0_x + seg0_y * seg0_y)
    # closure_branch, with the same P = B - rear foot
    branch = np.where(front_td >= np.arctan2(d - l * sin_r, l * cos_r), 1.0, -1.0)
    # (span^2 - 2 l^2 - d^2) / (2 l), expanded so that nothing cancels
    closure_offset = l * (cos_f * cos_r - sin_f * sin_r) + d * (sin_f - sin_r)
    segment_angle = np.arctan2(seg0_y, seg0_x)
    sweep = rear_lo - rear_td

    # Where each stance ends, relative to where it began (stance_motion at phase 1).
    end_x, end_y, end_sx, end_sy = geometry.sweep(rear_td + 1.0 * sweep, closure_offset,
                                                  branch, mirror)
    end_dheading = segment_angle - np.arctan2(end_sy, end_sx)
    if geometry.wrap:
        end_dheading = (end_dheading + np.pi) % (2.0 * np.pi) - np.pi
    # R(dheading) turns the end segment onto the touchdown one.
    scale = 1.0 / (span * np.sqrt(end_sx * end_sx + end_sy * end_sy))
    cos_h = (seg0_x * end_sx + seg0_y * end_sy) * scale
    sin_h = (seg0_y * end_sx - seg0_x * end_sy) * scale
    end_dx = rear0_x - (cos_h * end_x - sin_h * end_y)
    end_dy = rear0_y - (sin_h * end_x + cos_h * end_y)

    # Chain the stances in the world.
    heading0 = _starts(start[:, 2], end_dheading)
    cos_0, sin_0 = cos_sin(heading0)
    step_x, step_y = sin_0 * end_dx + cos_0 * end_dy, -cos_0 * end_dx + sin_0 * end_dy
    start_x, start_y = _starts(start[:, 0], step_x), _starts(start[:, 1], step_y)
    # The rear foot in the world, and the world direction of the foot-to-foot segment
    # (angle heading0 - pi/2 + segment_angle), both fixed for the stance.
    foot_x = start_x + (sin_0 * rear0_x + cos_0 * rear0_y)
    foot_y = start_y + (-cos_0 * rear0_x + sin_0 * rear0_y)
    cos_s, sin_s = seg0_x / span, seg0_y / span
    axis_x = sin_0 * cos_s + cos_0 * sin_s
    axis_y = sin_0 * sin_s - cos_0 * cos_s
    fields = (rear_td, sweep, closure_offset, branch, mirror, heading0, segment_angle,
              axis_x, axis_y, foot_x, foot_y)
    table = np.empty((len(fields), n_stances, n_runs))
    for row, field in zip(table, fields):
        row[...] = field        # mirror is (S, 1): assignment broadcasts it over the runs
    return table


def _starts(first: FloatArray, increments: FloatArray) -> FloatArray:
    """(S, n) value at the start of each stance: first + cumulative sum of earlier stances."""
    out = np.empty(increments.shape)
    out[0] = first
    if len(increments) > 1:
        np.cumsum(increments[:-1], axis=0, out=out[1:])
        out[1:] += first
    return out


Clamped = TypeVar('Clamped', FloatArray, IntArray)


def _clamp(values: Clamped, low: float, high: float) -> Clamped:
    """
    Clip `values` into [low, high] in place and return them (np.clip's values).

    Two ufuncs instead of np.clip, whose Python wrapper costs more than the work on the
    model's blocks of a few thousand samples, tens of thousands of times a diagnosis (integer
    bounds look up np.iinfo at every call). NaN stays NaN; a -0.0 against a bound of 0 may
    stay -0.0, which equals 0.
    """
    np.maximum(values, low, out=values)
    np.minimum(values, high, out=values)
    return values


def _row_blocks(n_rows: int, size: int) -> list[slice]:
    """Consecutive slices of at most `size` rows covering range(n_rows)."""
    return [slice(start, min(start + size, n_rows)) for start in range(0, n_rows, size)]
