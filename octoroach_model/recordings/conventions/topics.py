"""
The VICON convention of the package: topic and frame names, message types.

- pose topic of subject S: ``/vicon/S/S``, `geometry_msgs/msg/TransformStamped` (PoseStamped
  is read too), header frame ``vicon/world``, child frame ``vicon/S/S``; metres; the child
  frame's yaw is the heading, z = 0 (the vicon_bridge convention).
- run marker of subject S: ``/S/run_start``, `std_msgs/msg/UInt32`, data = run index, written
  at the start time of each run just before its first pose.
"""
from __future__ import annotations


DEFAULT_SUBJECT = 'octoroach'
DEFAULT_POSE_TOPIC = '/vicon/octoroach/octoroach'
DEFAULT_WORLD_FRAME = 'vicon/world'
DEFAULT_CHILD_FRAME = 'vicon/octoroach/octoroach'
DEFAULT_MARKER_TOPIC = '/octoroach/run_start'
DEFAULT_START_TIME_NS = 1_700_000_000 * 10**9

TRANSFORM_STAMPED = 'geometry_msgs/msg/TransformStamped'
POSE_STAMPED = 'geometry_msgs/msg/PoseStamped'
POSE_TYPES = (TRANSFORM_STAMPED, POSE_STAMPED)
MARKER_TYPE = 'std_msgs/msg/UInt32'
TF_MESSAGE = 'tf2_msgs/msg/TFMessage'
ODOMETRY = 'nav_msgs/msg/Odometry'


def pose_topic(subject: str, segment: str = '') -> str:
    """Name the VICON pose topic of a subject's segment (vicon_bridge; default: the subject)."""
    return f'/vicon/{subject}/{segment or subject}'


def child_frame(subject: str) -> str:
    """Name the VICON child frame of `subject`."""
    return f'vicon/{subject}/{subject}'


def marker_topic(subject: str) -> str:
    """Name the run-marker topic of `subject`."""
    return f'/{subject}/run_start'


def subject_of(name: str) -> str | None:
    """Find the subject S of a ``/vicon/S/S`` topic or ``vicon/S/S`` frame, else None."""
    parts = name.strip('/').split('/')
    if len(parts) == 3 and parts[0] == 'vicon' and parts[1] == parts[2] and parts[1]:
        return parts[1]
    return None
