"""
Message conversion for the nodes: planar poses <-> VICON transforms, markers, statistics.

VICON convention (vicon_bridge): a geometry_msgs/msg/TransformStamped per sample, metres, the
child frame's yaw is the heading, unit quaternion (0, 0, sin(h/2), cos(h/2)). The quaternion
arithmetic is the recordings layer's (`heading_to_quaternion`, `quaternion_to_heading`), so
poses written to bags and poses published live cannot differ.

Publishers get real message objects; rclpy serializes them.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, TYPE_CHECKING

import numpy as np

from octoroach_model.recordings import heading_to_quaternion, quaternion_to_heading

if TYPE_CHECKING:
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import TransformStamped
    from std_msgs.msg import UInt32

    from octoroach_model.guidance import GuidanceAnswer

__all__ = ['STATUS_KEYS', 'PlanarPose', 'fill_transform', 'planar_rows', 'pose_to_transform',
           'run_marker', 'set_stamp', 'status_fields', 'transform_message',
           'transform_to_pose', 'violation_array', 'validation_status', 'diagnosis_status',
           'diagnosis_fields', 'guidance_array']

NS_PER_S = 1_000_000_000
PlanarPose = tuple[float, float, float, float]  # x [m], y [m], qz, qw of one sample

# Fields of a validation result that go into the DiagnosticStatus key/value list.
STATUS_KEYS = ('n', 'k', 'sigma1', 'sigma2', 'violation', 'rho', 'epsilon', 'delta', 'gamma',
               'seed', 'paths_used', 'paths_available', 'accepted', 'mode', 'duration_s',
               'elapsed_s', 'started_at')


# -- poses ----------------------------------------------------------------------------------

def set_stamp(stamp: Time, stamp_ns: int) -> None:
    """Write `stamp_ns` (nanoseconds) into a builtin_interfaces/msg/Time."""
    stamp.sec, stamp.nanosec = divmod(int(stamp_ns), NS_PER_S)


def planar_rows(poses: np.ndarray) -> list[list[PlanarPose]]:
    """
    Turn (..., T, 3) poses into lists of (x, y, qz, qw) in plain floats, one per sample.

    Computed for a whole run at once, so that publishing a sample only copies four numbers.
    """
    poses = np.asarray(poses, dtype=float)
    _, _, qz, qw = heading_to_quaternion(poses[..., 2])
    rows = np.stack([poses[..., 0], poses[..., 1], qz, qw], axis=-1)
    return [[tuple(row) for row in run] for run in rows.reshape(-1, *rows.shape[-2:]).tolist()]


def transform_message(frame_id: str, child_frame_id: str) -> TransformStamped:
    """Make a TransformStamped with its frames set, to be filled by `fill_transform`."""
    from geometry_msgs.msg import TransformStamped

    message = TransformStamped()
    message.header.frame_id = frame_id
    message.child_frame_id = child_frame_id
    return message


def fill_transform(message: TransformStamped, pose: PlanarPose,
                   stamp_ns: int) -> TransformStamped:
    """Set the stamp and the planar pose (x, y, qz, qw) of `message`; z and qx, qy stay 0."""
    set_stamp(message.header.stamp, stamp_ns)
    translation, rotation = message.transform.translation, message.transform.rotation
    translation.x, translation.y, rotation.z, rotation.w = pose
    return message


def pose_to_transform(pose: Sequence[float], stamp_ns: int, frame_id: str,
                      child_frame_id: str) -> TransformStamped:
    """Make the TransformStamped of a planar pose (x [m], y [m], heading [rad]) at a time."""
    [[row]] = planar_rows(np.asarray(pose, dtype=float).reshape(1, 3))
    return fill_transform(transform_message(frame_id, child_frame_id), row, stamp_ns)


def transform_to_pose(message: Any) -> tuple[float, float, float]:
    """Return (x [m], y [m], heading [rad]) of a TransformStamped (or a PoseStamped)."""
    if hasattr(message, 'transform'):
        position, rotation = message.transform.translation, message.transform.rotation
    else:
        position, rotation = message.pose.position, message.pose.orientation
    heading = quaternion_to_heading(rotation.x, rotation.y, rotation.z, rotation.w)
    return float(position.x), float(position.y), float(heading)


def run_marker(run_index: int) -> UInt32:
    """Make the run marker of run `run_index` (std_msgs/msg/UInt32; wraps at 2**32)."""
    from std_msgs.msg import UInt32

    return UInt32(data=int(run_index) % 2**32)


# -- validation statistics ------------------------------------------------------------------

def status_fields(result: Mapping[str, Any]) -> tuple[bool, str, list[tuple[str, str]]]:
    """Return (accepted, verdict in words, key/value pairs) of a validation result (JSON)."""
    accepted = bool(result['accepted'])
    where = (f"sigma1 = {result['sigma1']:.3f} rad, sigma2 = {result['sigma2']:.3f} rad "
             f"(n = {result['n']}, k = {result['k']})")
    if accepted:
        message = (f"accepted: estimated violation {result['violation']:.3f} <= rho = "
                   f"{result['rho']} at {where}")
    elif result.get('mode') == 'search':
        message = ('rejected: no spread on the grid keeps the violation below rho = '
                   f"{result['rho']}; at {where} it is {result['violation']:.3f}")
    else:
        message = (f"rejected: estimated violation {result['violation']:.3f} > rho = "
                   f"{result['rho']} at {where}")
    values = [(key, _text(result[key])) for key in STATUS_KEYS if key in result]
    return accepted, message, values


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return repr(value)
    return str(value)


def validation_status(result: Mapping[str, Any], name: str,
                      hardware_id: str) -> DiagnosticStatus:
    """Make the status of a validation result (JSON): OK if accepted, else WARN."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    accepted, message, values = status_fields(result)
    return DiagnosticStatus(
        level=DiagnosticStatus.OK if accepted else DiagnosticStatus.WARN, name=name,
        message=message, hardware_id=hardware_id,
        values=[KeyValue(key=key, value=value) for key, value in values])


def diagnosis_fields(report: Mapping[str, Any]) -> tuple[bool, str, list[tuple[str, str]]]:
    """
    Return (model sufficient, verdict in words, key/value pairs) of a diagnosis report.

    Each named cause gives `cause_<i>` (its name), `cause_<i>.<parameter>` (its size) and
    `cause_<i>.interval` (95 % interval of its main parameter), in the report's order.
    """
    causes = report.get('causes') or []
    values: list[tuple[str, str]] = [('causes', str(len(causes))),
                                     ('adequate', _text(bool(report.get('adequate'))))]
    words = []
    for number, cause in enumerate(causes, 1):
        values.append((f'cause_{number}', cause['cause']))
        values += [(f'cause_{number}.{key}', _text(value))
                   for key, value in cause['parameters'].items()]
        for key, (low, high) in cause.get('interval', {}).items():
            values.append((f'cause_{number}.interval', f'{key} [{low:.4g}, {high:.4g}]'))
            words.append(f"{cause['cause']} ({key} {cause['parameters'][key]:.3g}, 95 % "
                         f'{low:.3g} to {high:.3g})')
    unexplained = [row['statistic'] for row in report.get('unexplained') or []]
    if unexplained:
        values.append(('unexplained', '; '.join(unexplained)))
    message = ('causes: ' + ', '.join(words)) if words else "causes: none (the paper's model)"
    message += '; adequate' if report.get('adequate') else (
        '; still missed: ' + ', '.join(unexplained))
    return not causes and bool(report.get('adequate')), message, values


def diagnosis_status(report: Mapping[str, Any], name: str,
                     hardware_id: str) -> DiagnosticStatus:
    """
    Make the status of a diagnosis.

    OK when the paper's model explains the runs, WARN when it needed causes or still misses
    something.
    """
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    sufficient, message, values = diagnosis_fields(report)
    return DiagnosticStatus(
        level=DiagnosticStatus.OK if sufficient else DiagnosticStatus.WARN, name=name,
        message=message, hardware_id=hardware_id,
        values=[KeyValue(key=key, value=value) for key, value in values])


def guidance_array(answer: GuidanceAnswer, values: Sequence[tuple[str, str]],
                   stamp_ns: int, name: str = 'octoroach_model/guidance',
                   hardware_id: str = 'octoroach') -> DiagnosticArray:
    """
    Make the latched guidance (octoroach_model.guidance): one status, its values.

    OK once the question is settled (named, ruled out, enough runs), WARN while runs are
    still needed, STALE when the runs cannot be read or decided on yet.
    """
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    from octoroach_model.guidance import GuidanceStatus

    status = answer.status
    level = (DiagnosticStatus.OK if status in (GuidanceStatus.NAMED, GuidanceStatus.RULED_OUT,
                                               GuidanceStatus.ENOUGH_RUNS)
             else DiagnosticStatus.WARN if status == GuidanceStatus.COLLECTING
             else DiagnosticStatus.STALE)
    return violation_array([DiagnosticStatus(
        level=level, name=name, message=answer.statement,
        hardware_id=hardware_id, values=[KeyValue(key=key, value=value)
                                         for key, value in values])], stamp_ns)


def violation_array(statuses: list[DiagnosticStatus], stamp_ns: int) -> DiagnosticArray:
    """Make the DiagnosticArray of the latest validation and diagnosis statuses."""
    from diagnostic_msgs.msg import DiagnosticArray

    array = DiagnosticArray(status=list(statuses))
    set_stamp(array.header.stamp, stamp_ns)
    return array
