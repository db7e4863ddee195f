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

A pose list is a message with a sequence of such poses, each telling which pose it is:

- a transform list, whose elements carry a header and a child frame: `tf2_msgs/TFMessage` on
  /tf and /tf_static (and ROS 1's `tf/tfMessage`);
- an array of named bodies, whose elements carry a name (a string field, preferably one whose
  name says "name") and a pose: MOCAP4ROS2's `mocap4r2_msgs/RigidBodies` (``rigidbodies[]``
  with ``rigid_body_name`` and ``pose``), motion_capture_tracking's `NamedPoseArray`
  (``poses[]`` with ``name`` and ``pose``), or any type of that shape; the time is the
  element's own stamp if it has one, else the message's ``header.stamp``.
"""
from __future__ import annotations

from collections.abc import Mapping
from enum import Enum
from operator import attrgetter
from typing import Any, Callable, NamedTuple

from rosbags.interfaces import Nodetype

from octoroach_model.recordings.conventions.quaternions import FullPose

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


class ListKind(Enum):
    """What the elements of a pose list are."""

    TRANSFORMS = 'transforms'  # TFMessage: child frames, each with its own header
    NAMED = 'named bodies'  # RigidBodies, NamedPoseArray: a name and a pose


class ListLayout(NamedTuple):
    """A pose-list message: its sequence, one element's layout, what names an element."""

    msgtype: str
    field: str
    element: PoseLayout
    name: str  # attribute of an element that names it ('child_frame_id', 'rigid_body_name')
    stamp: str  # the message's own stamp, for elements without one ('' when absent)
    kind: ListKind

    @property
    def option(self) -> str:
        """Name the command-line option that chooses an element."""
        return '--frame' if self.kind is ListKind.TRANSFORMS else '--subject'

    @property
    def what(self) -> str:
        """Say what an element is, for messages ('child frame', 'body')."""
        return 'child frame' if self.kind is ListKind.TRANSFORMS else 'body'


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


def _stamp_path(fielddefs: FieldDefs, msgtype: str) -> tuple[str, str]:
    """(stamp path, header name) of a type's own time: header.stamp or a Time field."""
    named = _named(_fields(fielddefs, msgtype))
    header = next((name for name, typ in named if typ == HEADER_TYPE), '')
    time = next((name for name, typ in named if typ == TIME_TYPE), '')
    return (f'{header}.stamp' if header else time), header


def _strings(fielddefs: FieldDefs, msgtype: str) -> list[str]:
    """Names of a type's string fields, in declaration order."""
    return [name for name, kind in _fields(fielddefs, msgtype)
            if kind[0] == Nodetype.BASE and kind[1][0] == 'string']


def pose_layout(msgtype: str, fielddefs: FieldDefs) -> PoseLayout | None:
    """Find where a single-pose message type keeps its pose; None when it holds none."""
    found = _find_pose(fielddefs, msgtype, '', 0)
    if found is None:
        return None
    stamp, header = _stamp_path(fielddefs, msgtype)
    strings = _strings(fielddefs, msgtype)
    return PoseLayout(msgtype, stamp, found[0], found[1],
                      f'{header}.frame_id' if header else '',
                      'child_frame_id' if 'child_frame_id' in strings else '')


def list_layout(msgtype: str, fielddefs: FieldDefs) -> ListLayout | None:
    """Find the layout of a pose-list type (transforms or named bodies); None for others."""
    for name, kind in _fields(fielddefs, msgtype):
        if kind[0] not in (Nodetype.SEQUENCE, Nodetype.ARRAY):
            continue
        element = kind[1][0]
        if element[0] != Nodetype.NAME:
            continue
        layout = pose_layout(element[1], fielddefs)
        if layout is None:
            continue
        if layout.stamp and layout.child_frame and layout.parent_frame:
            return ListLayout(msgtype, name, layout, layout.child_frame, '',
                              ListKind.TRANSFORMS)
        strings = _strings(fielddefs, element[1])
        if strings:
            label = next((field for field in strings if 'name' in field.lower()), strings[0])
            return ListLayout(msgtype, name, layout, label, _stamp_path(fielddefs, msgtype)[0],
                              ListKind.NAMED)
    return None


# stamp ns, x, y, z, qx, qy, qz, qw
Sample = tuple[int, float, float, float, float, float, float, float]


def stamp_getter(path: str) -> Callable[[Any], int]:
    """Make a getter of a stamp in int ns (0 when the type has none)."""
    if not path:
        return lambda message: 0
    get = attrgetter(path)

    def stamp(message: Any) -> int:
        t = get(message)
        return int(t.sec) * 1_000_000_000 + int(t.nanosec)

    return stamp


def pose_getter(layout: PoseLayout) -> Callable[[Any], Sample]:
    """Make a getter of (stamp ns, x, y, z, qx, qy, qz, qw); stamp 0 when there is no time."""
    position = attrgetter(layout.position)
    orientation = attrgetter(layout.orientation)
    stamp = stamp_getter(layout.stamp)

    def get(message: Any) -> Sample:
        p, q = position(message), orientation(message)
        return (stamp(message), float(p.x), float(p.y), float(p.z), float(q.x), float(q.y),
                float(q.z), float(q.w))

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
