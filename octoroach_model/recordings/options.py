"""
How to find the robot's pose in an input: which topic, frame, subject, markers and axis.

One record for every reader (ROS 2 and ROS 1 bags, /tf, Vicon CSV exports, C3D files), so a
choice made on the command line, in the Python API or in a node parameter means the same
everywhere. A reader uses the fields that apply to its format and ignores the others.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from octoroach_model.errors import ParameterError

# Body axis that points forward, as written in the option, and its angle from the body x axis.
FORWARD_AXES = {'x': 0.0, 'y': math.pi / 2, '-x': math.pi, '-y': -math.pi / 2}


@dataclass(frozen=True)
class ReadOptions:
    """
    Where the pose of the robot is in an input.

    topic : ROS bags: the pose topic (default: the VICON topic, or the only pose topic).
    frame : /tf and /tf_static: the child frame to follow (default: the only moving one).
    subject : Vicon CSV / C3D: the object or subject name (default: the only one).
    markers : C3D: names of the markers on the rigid body (default: all of the subject's).
    forward_axis : the body axis that points where the robot walks ('x', 'y', '-x', '-y');
        the heading is the yaw of that axis, so heading pi/2 means walking along world +y.
    """

    topic: str | None = None
    frame: str | None = None
    subject: str | None = None
    markers: tuple[str, ...] = ()
    forward_axis: str = 'x'

    def __post_init__(self) -> None:
        if self.forward_axis not in FORWARD_AXES:
            raise ParameterError(f'forward axis must be one of {", ".join(FORWARD_AXES)}, '
                                 f'got {self.forward_axis!r}')

    @property
    def heading_offset_rad(self) -> float:
        """Add to the yaw of the body x axis to get the heading of the forward axis."""
        return FORWARD_AXES[self.forward_axis]
