"""The switching four-bar (NOTES.md section 2, eqs. 1-5), closed form and vectorised.

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

import numpy as np


def feet_in_body(rear_angle, front_angle, mirror, leg_length, hip_distance):
    """Rear and front foot positions (x, y) in the body frame; arrays broadcast."""
    half = 0.5 * hip_distance
    rear = (-mirror * leg_length * np.cos(rear_angle),
            -half + leg_length * np.sin(rear_angle))
    front = (mirror * leg_length * np.cos(front_angle),
             half + leg_length * np.sin(front_angle))
    return rear, front


def solve_front_angle(rear_angle, span, leg_length, hip_distance, branch):
    """Front leg angle that keeps |front foot - rear foot| = span (closure, eq. 3).

    `branch` (+1 or -1) picks the root of a cos(phi) + b sin(phi) = c; it is fixed at
    touchdown so the angle is continuous through the stance. Where the stance leaves the
    reachable set (|c| > hypot(a, b), only for extreme random angles) the leg is held at the
    closest reachable angle.
    """
    # P = B - rear foot, seen in the pair's own (mirrored) frame: one equation for both.
    px = leg_length * np.cos(rear_angle)
    py = hip_distance - leg_length * np.sin(rear_angle)
    a = 2.0 * leg_length * px
    b = 2.0 * leg_length * py
    c = span ** 2 - px ** 2 - py ** 2 - leg_length ** 2
    ratio = np.clip(c / np.hypot(a, b), -1.0, 1.0)
    return np.arctan2(b, a) + branch * np.arccos(ratio)


def closure_branch(rear_angle, front_angle, leg_length, hip_distance):
    """+1 or -1: which root of the closure the touchdown configuration lies on.

    The closure is the same equation for both pairs once the left pair is mirrored, so the
    mirror sign does not enter here.
    """
    px = leg_length * np.cos(rear_angle)
    py = hip_distance - leg_length * np.sin(rear_angle)
    return np.where(front_angle >= np.arctan2(py, px), 1.0, -1.0)


def stance_motion(rear_touchdown, front_touchdown, rear_liftoff, phase, mirror,
                  leg_length, hip_distance):
    """Pose of G during a stance, relative to the body frame at touchdown.

    Parameters
    ----------
    rear_touchdown, front_touchdown, rear_liftoff : angles (rad) of the stance, any shape
        broadcastable with `phase`.
    phase : fraction of the stance elapsed, in [0, 1].
    mirror : +1 right pair, -1 left pair (broadcastable).

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


def stance_angles(nominal_angles, normals, sigma1, sigma2):
    """Random angles xi = eta + diag(sigma1 I4, sigma2 I2) Y (eq. 11).

    normals : (..., 6) standard normal draws Y. Returns (..., 6) angles in radians.
    """
    scale = np.array([sigma1] * 4 + [sigma2] * 2, dtype=float)
    return np.asarray(nominal_angles, dtype=float) + normals * scale


def integrate_stances(angles, phase, start_pose, leg_length, hip_distance):
    """Poses of runs made of alternating stances (right pair first).

    Parameters
    ----------
    angles : (n, S, 6) angles [phi1, phi2, phi3, phi4, phi_R^lo, phi_L^lo] per stance; a
        right stance (even index) uses phi1, phi2, phi_R^lo, a left one phi3, phi4, phi_L^lo.
    phase : (n, T) or (T,) elapsed stances at each sample (2 * stride frequency * t for a
        constant gait); values beyond S are held at the end of the last stance.
    start_pose : (n, 3) or (3,) x, y, heading at phase 0.

    Returns
    -------
    (n, T, 3) x [m], y [m], heading [rad].
    """
    angles = np.asarray(angles, dtype=float)
    n_runs, n_stances = angles.shape[:2]
    is_right = (np.arange(n_stances) % 2 == 0)
    mirror = np.where(is_right, 1.0, -1.0)
    rear_td = np.where(is_right, angles[..., 0], angles[..., 2])
    front_td = np.where(is_right, angles[..., 1], angles[..., 3])
    rear_lo = np.where(is_right, angles[..., 4], angles[..., 5])

    # Where each stance ends, relative to where it began; then chain them.
    end_dx, end_dy, end_dheading = stance_motion(rear_td, front_td, rear_lo, 1.0, mirror,
                                                 leg_length, hip_distance)
    start = np.broadcast_to(np.asarray(start_pose, dtype=float), (n_runs, 3))
    stance_heading = start[:, 2:3] + np.concatenate(
        [np.zeros((n_runs, 1)), np.cumsum(end_dheading, axis=1)[:, :-1]], axis=1)
    step_x, step_y = _body_to_world(end_dx, end_dy, stance_heading)
    stance_x = start[:, 0:1] + np.concatenate(
        [np.zeros((n_runs, 1)), np.cumsum(step_x, axis=1)[:, :-1]], axis=1)
    stance_y = start[:, 1:2] + np.concatenate(
        [np.zeros((n_runs, 1)), np.cumsum(step_y, axis=1)[:, :-1]], axis=1)

    phase = np.broadcast_to(np.asarray(phase, dtype=float), (n_runs, np.shape(phase)[-1]))
    index = np.clip(np.floor(phase).astype(np.intp), 0, n_stances - 1)
    within = np.clip(phase - index, 0.0, 1.0)

    def at_sample(per_stance):
        return np.take_along_axis(per_stance, index, axis=1)

    dx, dy, dheading = stance_motion(at_sample(rear_td), at_sample(front_td),
                                     at_sample(rear_lo), within, mirror[index],
                                     leg_length, hip_distance)
    heading0 = at_sample(stance_heading)
    world_dx, world_dy = _body_to_world(dx, dy, heading0)
    poses = np.empty(phase.shape + (3,))
    poses[..., 0] = at_sample(stance_x) + world_dx
    poses[..., 1] = at_sample(stance_y) + world_dy
    poses[..., 2] = heading0 + dheading
    return poses


def _body_to_world(dx, dy, heading):
    """Rotate body-frame vectors (x right, y forward) into the world for a given heading."""
    # R(heading - pi/2) = [[sin h, cos h], [-cos h, sin h]]
    sin_h, cos_h = np.sin(heading), np.cos(heading)
    return sin_h * dx + cos_h * dy, -cos_h * dx + sin_h * dy
