"""
Bags as ROS 2 drivers record them, written with rosbags' rosbag2 writer.

The drivers' message types are registered from their published .msg definitions
(MOCAP4ROS2-Project/mocap4r2_msgs, IMRCLab/motion_capture_tracking), so every bag carries the
definition of its types, as rosbag2 stores them; a reader must find the pose in it.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_types_from_msg, get_typestore, Stores

from octoroach_model.paths import Paths

START_NS = 1_700_000_000 * 10**9
PERIOD_NS = 4 * 10**9
# MOCAP4ROS2-Project/mocap4r2_msgs, msg/*.msg
MOCAP4R2 = {
    'mocap4r2_msgs/msg/Marker': 'int8 USE_NAME=0\nint8 USE_INDEX=1\nint8 USE_BOTH=2\n\n'
                                'int8 id_type\nint32 marker_index\nstring marker_name\n'
                                'geometry_msgs/Point translation\n',
    'mocap4r2_msgs/msg/RigidBody': 'string rigid_body_name\nMarker[] markers\n'
                                   'geometry_msgs/Pose pose\n',
    'mocap4r2_msgs/msg/RigidBodies': 'std_msgs/Header header\nuint32 frame_number\n'
                                     'mocap4r2_msgs/RigidBody[] rigidbodies\n',
}
# IMRCLab/motion_capture_tracking, motion_capture_tracking_interfaces/msg/*.msg
NAMED_POSES = {
    'motion_capture_tracking_interfaces/msg/NamedPose': 'string name\n'
                                                        'geometry_msgs/Pose pose\n',
    'motion_capture_tracking_interfaces/msg/NamedPoseArray': 'std_msgs/Header header\n'
                                                             'NamedPose[] poses\n',
}


def typestore(*definitions: dict[str, str]):
    """Jazzy's types and the drivers' own, registered from their .msg text."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for group in definitions:
        types: dict = {}
        for name, text in group.items():
            types.update(get_types_from_msg(text, name))
        store.register(types)
    return store


class Bag:
    """A rosbag2 MCAP bag written with rosbags, one connection per topic."""

    def __init__(self, path: Path, store) -> None:
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.store, self.types = store, store.types
        self.connections: dict[str, object] = {}

    def __enter__(self) -> Bag:
        self.writer.open()
        return self

    def __exit__(self, *exc) -> None:
        self.writer.close()

    def write(self, topic: str, msgtype: str, log_ns: int, message) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype,
                                                                 typestore=self.store)
        self.writer.write(self.connections[topic], log_ns,
                          self.store.serialize_cdr(message, msgtype))

    def header(self, stamp_ns: int, frame: str = 'world'):
        return self.types['std_msgs/msg/Header'](stamp=self.types['builtin_interfaces/msg/Time'](
            sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=frame)

    def pose(self, x: float, y: float, heading: float, z: float = 0.0, quaternion=None):
        q = quaternion if quaternion is not None else (0.0, 0.0, math.sin(heading / 2),
                                                       math.cos(heading / 2))
        return self.types['geometry_msgs/msg/Pose'](
            position=self.types['geometry_msgs/msg/Point'](x=x, y=y, z=z),
            orientation=self.types['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2],
                                                                   w=q[3]))

    def pose_stamped(self, stamp_ns: int, *pose, **more):
        return self.types['geometry_msgs/msg/PoseStamped'](header=self.header(stamp_ns),
                                                           pose=self.pose(*pose, **more))


def samples(paths: Paths, every: int = 1):
    """(stamp ns, x, y, heading) of each run's samples, runs PERIOD_NS apart."""
    offsets = np.round(paths.t * 1e9).astype(np.int64)
    for run in range(paths.n_paths):
        for k in range(0, len(offsets), every):
            yield (START_NS + run * PERIOD_NS + int(offsets[k]), *paths.poses[run, k])


def mocap4r2_bag(path: Path, paths: Paths, occluded: tuple[int, ...] = ()) -> Path:
    """Write MOCAP4ROS2's RigidBodies: a still wand and the robot (some frames occluded)."""
    with Bag(path, typestore(MOCAP4R2)) as bag:
        body = bag.types['mocap4r2_msgs/msg/RigidBody']
        for number, (stamp, x, y, heading) in enumerate(samples(paths)):
            robot = bag.pose(x, y, heading, 0.03,
                             quaternion=(0.0, 0.0, 0.0, 0.0) if number in occluded else None)
            message = bag.types['mocap4r2_msgs/msg/RigidBodies'](
                header=bag.header(stamp), frame_number=number, rigidbodies=[
                    body(rigid_body_name='wand', markers=[], pose=bag.pose(1.0, 2.0, 0.3)),
                    body(rigid_body_name='robot', markers=[], pose=robot)])
            bag.write('/rigid_bodies', 'mocap4r2_msgs/msg/RigidBodies', stamp, message)
    return path


def named_pose_bag(path: Path, paths: Paths) -> Path:
    """Write motion_capture_tracking's NamedPoseArray: two crazyflies that both move."""
    with Bag(path, typestore(NAMED_POSES)) as bag:
        named = bag.types['motion_capture_tracking_interfaces/msg/NamedPose']
        for stamp, x, y, heading in samples(paths):
            message = bag.types['motion_capture_tracking_interfaces/msg/NamedPoseArray'](
                header=bag.header(stamp), poses=[
                    named(name='cf1', pose=bag.pose(x, y, heading, 0.5)),
                    named(name='cf2', pose=bag.pose(x + 1.0, y, heading, 0.5))])
            bag.write('/poses', 'motion_capture_tracking_interfaces/msg/NamedPoseArray', stamp,
                      message)
    return path
