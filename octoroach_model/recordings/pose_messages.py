"""
Where a message type keeps a pose, found from its definition alone.

A pose is a position (`geometry_msgs/Point` or `Vector3`) beside an orientation
(`geometry_msgs/Quaternion`), searched depth-first in declaration order, sequences excluded:
`TransformStamped` gives ``transform.translation`` / ``transform.rotation``, `PoseStamped`
``pose.position`` / ``pose.orientation``, `nav_msgs/Odometry` ``pose.pose.position`` /
``pose.pose.orientation``, and a lab's own message that embeds any of these (or the two fields
side by side) works the same way, from the definition the bag carries. The time is
``header.stamp`` (or a top-level `builtin_interfaces/Time`); the frames are ``header.frame_id``
(parent) and ``child_frame_id``.

A transform list is a message with a sequence of such poses that each carry a header and a
child frame: `tf2_msgs/TFMessage` on /tf and /tf_static (and ROS 1's `tf/tfMessage`).
"""
from __future__ import annotations

from collections.abc import Mapping
from operator import attrgetter
from typing import Any, Callable, NamedTuple

from rosbags.interfaces import Nodetype

POSITION_TYPES = frozenset({'geometry_msgs/msg/Point', 'geometry_msgs/msg/Vector3',
                            'geometry_msgs/msg/Point32'})
ORIENTATION_TYPE = 'geometry_msgs/msg/Quaternion'
HEADER_TYPE = 'std_msgs/msg/Header'
TIME_TYPE = 'builtin_interfaces/msg/Time'
MAX_DEPTH = 4

FieldDefs = Mapping[str, Any]  # rosbags typestore.fielddefs


class PoseLayout(NamedTuple):
    """Attribute paths of a pose message's parts (dotted; '' when absent)."""

    msgtype: str
    stamp: str
    position: str
    orientation: str
    parent_frame: str
    child_frame: str

    @property
    def description(self) -> str:
        """'transform.translation / transform.rotation' for notes."""
        return f'{self.position} / {self.orientation}'


class TfLayout(NamedTuple):
    """A transform-list message: the name of its sequence and the layout of one element."""

    msgtype: str
    field: str
    element: PoseLayout


def _fields(fielddefs: FieldDefs, msgtype: str) -> list[tuple[str, Any]]:
    entry = fielddefs.get(msgtype)
    return list(entry[1]) if entry else []


def _named(fields: list[tuple[str, Any]]) -> list[tuple[str, str]]:
    """(name, type) of the fields that are single messages (no arrays, no base types)."""
    return [(name, kind[1]) for name, kind in fields if kind[0] == Nodetype.NAME]


def _find_pose(fielddefs: FieldDefs, msgtype: str, prefix: str,
               depth: int) -> tuple[str, str] | None:
    """(position path, orientation path) of the first pose inside `msgtype`."""
    named = _named(_fields(fielddefs, msgtype))
    position = next((name for name, typ in named if typ in POSITION_TYPES), None)
    orientation = next((name for name, typ in named if typ == ORIENTATION_TYPE), None)
    if position and orientation:
        return prefix + position, prefix + orientation
    if depth >= MAX_DEPTH:
        return None
    for name, typ in named:
        if typ in POSITION_TYPES or typ == ORIENTATION_TYPE or typ == HEADER_TYPE:
            continue
        found = _find_pose(fielddefs, typ, f'{prefix}{name}.', depth + 1)
        if found:
            return found
    return None


def pose_layout(msgtype: str, fielddefs: FieldDefs) -> PoseLayout | None:
    """Find where a single-pose message type keeps its pose; None when it holds none."""
    found = _find_pose(fielddefs, msgtype, '', 0)
    if found is None:
        return None
    fields = _fields(fielddefs, msgtype)
    named = _named(fields)
    header = next((name for name, typ in named if typ == HEADER_TYPE), '')
    time = next((name for name, typ in named if typ == TIME_TYPE), '')
    strings = {name for name, kind in fields if kind[0] == Nodetype.BASE
               and kind[1][0] == 'string'}
    return PoseLayout(msgtype, f'{header}.stamp' if header else time, found[0], found[1],
                      f'{header}.frame_id' if header else '',
                      'child_frame_id' if 'child_frame_id' in strings else '')


def tf_layout(msgtype: str, fielddefs: FieldDefs) -> TfLayout | None:
    """Find the layout of a transform-list type (TFMessage); None for any other type."""
    for name, kind in _fields(fielddefs, msgtype):
        if kind[0] not in (Nodetype.SEQUENCE, Nodetype.ARRAY):
            continue
        element = kind[1][0]
        if element[0] != Nodetype.NAME:
            continue
        layout = pose_layout(element[1], fielddefs)
        if layout and layout.stamp and layout.child_frame and layout.parent_frame:
            return TfLayout(msgtype, name, layout)
    return None


Sample = tuple[int, float, float, float, float, float, float]  # stamp ns, x, y, qx, qy, qz, qw
FullPose = tuple[float, float, float, float, float, float, float]  # x, y, z, qx, qy, qz, qw


def pose_getter(layout: PoseLayout) -> Callable[[Any], Sample]:
    """Make a getter of (stamp ns, x, y, qx, qy, qz, qw); stamp 0 when there is no time."""
    position = attrgetter(layout.position)
    orientation = attrgetter(layout.orientation)
    stamp = attrgetter(layout.stamp) if layout.stamp else None

    def get(message: Any) -> Sample:
        p, q = position(message), orientation(message)
        t = stamp(message) if stamp is not None else None
        ns = t.sec * 1_000_000_000 + t.nanosec if t is not None else 0
        return (ns, float(p.x), float(p.y), float(q.x), float(q.y), float(q.z), float(q.w))

    return get


def full_pose_getter(layout: PoseLayout) -> Callable[[Any], FullPose]:
    """Make a getter of (x, y, z, qx, qy, qz, qw), for composing transforms."""
    position = attrgetter(layout.position)
    orientation = attrgetter(layout.orientation)

    def get(message: Any) -> FullPose:
        p, q = position(message), orientation(message)
        return (float(p.x), float(p.y), float(p.z), float(q.x), float(q.y), float(q.z),
                float(q.w))

    return get


def frame_getter(path: str) -> Callable[[Any], str]:
    """Make a getter of a frame name without a leading '/' (ROS 1 wrote '/world')."""
    if not path:
        return lambda message: ''
    get = attrgetter(path)
    return lambda message: str(get(message)).lstrip('/')
