"""
How to find the robot's pose in an input: which topic, frame, subject, markers and axes.

One record for every reader (ROS 2 and ROS 1 bags, /tf, arrays of named bodies, Vicon CSV
exports, C3D files, Qualisys TSV exports, trajectory tables), so a choice made on the command
line, in the Python API or in a node parameter means the same everywhere. A reader uses the
fields that apply to its format and ignores the others.
"""
from __future__ import annotations

from dataclasses import dataclass

from octoroach_model.errors import ParameterError
from octoroach_model.recordings.conventions.axes import forward_angle_rad, FORWARD_AXES, UP_AXES
from octoroach_model.settings import check_kinds, Setting, setting, unknown_name

# Settings of reading that programs and nodes share (`settings`: one source for each)
TOPIC = Setting('pose topic; empty or not given: the VICON one, or the only pose topic')
FORWARD_AXIS = Setting("the body axis the robot walks along; heading = that axis's yaw",
                       choices=FORWARD_AXES)
UP_AXIS = Setting("the input world's up axis (y: OptiTrack Motive's default; -y: a camera "
                  'frame); poses are turned so that it is z', choices=UP_AXES)
GAP_S = Setting('a pause in the poses longer than this splits runs where there is no run '
                'marker', unit='s', low=0.0, high=60.0, open_low=True)


@dataclass(frozen=True)
class ReadOptions:
    """
    Where the pose of the robot is in an input.

    topic : ROS bags: the pose topic (default: the VICON topic, or the only pose stream).
    frame : /tf and /tf_static: the child frame to follow (default: the only moving one).
    subject : Vicon CSV / C3D / Qualisys TSV: the object or subject; arrays of named bodies
        (MOCAP4ROS2 RigidBodies, NamedPoseArray): the body's name; VICON topics /vicon/S/S:
        the subject S (default: the only one, or the only one that moves).
    markers : C3D, Vicon CSV and Qualisys TSV trajectories: the markers on the rigid body
        (default: all of the subject's, modelled and virtual markers left out).
    forward_axis : the body axis that points where the robot walks ('x', 'y', '-x', '-y',
        'z', '-z'); the heading is the yaw of that axis, so heading pi/2 means walking along
        world +y.
    up_axis : the input world's axis that points up ('z', the default, as Vicon and REP 103;
        'y' for OptiTrack Motive's default; '-y' for a camera's optical frame; 'x', '-x',
        '-z'); poses are turned so that it becomes z before anything else (`axes`).
    accept_loose_fit : fit a marker body even when its markers do not move as one rigid body
        (the fit's typical residual above `mocap.MAX_TYPICAL_RESIDUAL_M`); refused otherwise.
    """

    topic: str | None = setting(None, TOPIC)
    frame: str | None = None
    subject: str | None = None
    markers: tuple[str, ...] = ()
    forward_axis: str = setting('x', FORWARD_AXIS)
    up_axis: str = setting('z', UP_AXIS)
    accept_loose_fit: bool = False

    def __post_init__(self) -> None:
        check_kinds(self)        # accept_loose_fit='no' would read as true, topic=5 fail late
        if not isinstance(self.markers, (list, tuple)) or not all(isinstance(name, str)
                                                                  for name in self.markers):
            raise ParameterError('markers must be a list of marker names (not one text: '
                                 "['A', 'B'], not 'A,B')")
        object.__setattr__(self, 'markers', tuple(self.markers))
        if self.forward_axis not in FORWARD_AXES:
            raise ParameterError(f'forward axis must be one of {", ".join(FORWARD_AXES)}, '
                                 f'got {unknown_name(self.forward_axis, FORWARD_AXES)}')
        if self.up_axis not in UP_AXES:
            raise ParameterError(f'up axis must be one of {", ".join(UP_AXES)}, '
                                 f'got {unknown_name(self.up_axis, UP_AXES)}')

    @property
    def heading_offset_rad(self) -> float:
        """Add to the yaw of the body x axis to get the heading of an in-plane forward axis."""
        return forward_angle_rad(self.forward_axis)
