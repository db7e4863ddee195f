"""
Pose bags: VICON poses and run markers written as the package's standard bag.

The standard bag is what `simulate` and `convert` write and what the simulator and recorder
make live: `TransformStamped` on ``/vicon/S/S`` (header frame ``vicon/world``, child frame
``vicon/S/S``, unit quaternion of the heading, z = 0) and a `UInt32` run marker on
``/S/run_start`` just before each run's first pose, in a rosbag2 Jazzy bag (`writer`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from octoroach_model.errors import BagError, DataError
from octoroach_model.fileio import user_path
from octoroach_model.paths import check_paths, HEADING, Paths, X, Y
from octoroach_model.recordings.bagio.bag_files import PathLike
from octoroach_model.recordings.bagio.msgtypes import jazzy_types
from octoroach_model.recordings.bagio.qos import History, QosProfile
from octoroach_model.recordings.bagio.writer import BagWriter
from octoroach_model.recordings.conventions.quaternions import heading_to_quaternion
from octoroach_model.recordings.conventions.topics import (
    DEFAULT_CHILD_FRAME,
    DEFAULT_MARKER_TOPIC,
    DEFAULT_POSE_TOPIC,
    DEFAULT_START_TIME_NS,
    DEFAULT_WORLD_FRAME,
    MARKER_TYPE,
    POSE_TYPES,
    TRANSFORM_STAMPED,
)

# The simulator's publishers as a recorder sees them over DDS discovery (which does not carry
# history or depth): reliable, volatile, default (infinite) durations.
RECORDED_VICON_QOS = QosProfile(history=History.UNKNOWN, depth=0)


@dataclass
class _Stream:
    """One subject's pose topic in the bag: its message template and channels."""

    topic: str
    marker_topic: str | None
    message: Any
    pose_channel: int | None = None
    marker_channel: int | None = None


class PoseBagWriter:
    """
    Streams pose samples and run markers into a new bag directory.

    Use as a context manager; samples are written in the order given (the arrival order a
    recorder would see). The marker topic is created at the first marker, so a bag without
    markers has no marker topic at all. The subject given here is stream 0; `add_stream`
    adds further subjects (several robots in one bag).
    """

    def __init__(self, out_path: PathLike, *, topic: str = DEFAULT_POSE_TOPIC,
                 world_frame: str = DEFAULT_WORLD_FRAME,
                 child_frame: str = DEFAULT_CHILD_FRAME,
                 marker_topic: str | None = DEFAULT_MARKER_TOPIC,
                 message_type: str = TRANSFORM_STAMPED,
                 offered_qos: tuple[QosProfile, ...] = (RECORDED_VICON_QOS,),
                 custom_data: Mapping[str, str] | None = None,
                 bag_name: str | None = None) -> None:
        if message_type not in POSE_TYPES:
            raise BagError(f'{out_path}: cannot write {message_type}, only {POSE_TYPES}')
        self.topic = topic
        self.marker_topic = marker_topic or None
        self.message_type = message_type
        self.offered_qos = offered_qos
        self.world_frame = world_frame
        self._bag = BagWriter(out_path, custom_data=custom_data, name=bag_name)
        self.path = self._bag.path
        self._store = jazzy_types()
        self._open = False
        self._streams = [_Stream(topic, self.marker_topic,
                                 self._template(world_frame, child_frame))]
        self._marker: Any = self._store.types[MARKER_TYPE](data=0)

    def _template(self, world_frame: str, child_frame: str) -> Any:
        """One message object, mutated per sample: building five objects per pose is slow."""
        types = self._store.types
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=world_frame)
        if self.message_type == TRANSFORM_STAMPED:
            transform = types['geometry_msgs/msg/Transform'](
                translation=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                rotation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
            return types[TRANSFORM_STAMPED](
                header=header, child_frame_id=child_frame, transform=transform)
        pose = types['geometry_msgs/msg/Pose'](
            position=types['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
            orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
        return types[self.message_type](header=header, pose=pose)

    def __enter__(self) -> PoseBagWriter:
        self._bag.create()
        self._open = True
        first = self._streams[0]
        first.pose_channel = self._bag.add_topic(first.topic, self.message_type,
                                                 offered_qos=self.offered_qos)
        return self

    def add_stream(self, topic: str, child_frame: str, marker_topic: str | None) -> int:
        """Add a further subject's pose topic (and marker topic); return its stream index."""
        if not self._open:
            raise BagError(f'{self.path}: bag is not open for writing')
        stream = _Stream(topic, marker_topic or None,
                         self._template(self.world_frame, child_frame))
        stream.pose_channel = self._bag.add_topic(topic, self.message_type,
                                                  offered_qos=self.offered_qos)
        self._streams.append(stream)
        return len(self._streams) - 1

    def __exit__(self, exc_type: object, *exc_info: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self._bag.abort()

    def close(self) -> None:
        """Write the MCAP summary and metadata.yaml."""
        if self._open:
            self._bag.close()
            self._open = False

    def write_poses(self, stamp_ns: np.ndarray, poses: np.ndarray, *,
                    log_time_ns: np.ndarray | None = None, stream: int = 0) -> None:
        """
        Write samples (k, 3) x, y, heading at header stamps `stamp_ns` (int ns).

        The log time defaults to the stamp, as for a recorder on the VICON machine. `stream`:
        the subject (0, or an index from `add_stream`).
        """
        if not self._open:
            raise BagError(f'{self.path}: bag is not open for writing')
        target = self._streams[stream]
        stamps = np.asarray(stamp_ns, dtype=np.int64).ravel()
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        logs = stamps if log_time_ns is None else np.asarray(log_time_ns, np.int64).ravel()
        if not len(stamps) == len(poses) == len(logs):
            raise DataError(f'{self.path}: {len(stamps)} stamps for {len(poses)} poses')
        if len(stamps) and min(stamps.min(), logs.min()) < 0:
            raise DataError(f'{self.path}: negative time stamps cannot be written')
        qx, qy, qz, qw = heading_to_quaternion(poses[:, HEADING])
        columns = zip(stamps.tolist(), logs.tolist(), poses[:, X].tolist(),
                      poses[:, Y].tolist(), qz.tolist(), qw.tolist())
        message, serialize = target.message, self._store.serialize_cdr
        stamp = message.header.stamp
        if self.message_type == TRANSFORM_STAMPED:
            position, rotation = message.transform.translation, message.transform.rotation
        else:
            position, rotation = message.pose.position, message.pose.orientation
        write, msgtype = self._bag.write, self.message_type
        channel = int(target.pose_channel or 0)
        for stamp_int, log_int, x, y, z, w in columns:
            stamp.sec, stamp.nanosec = divmod(stamp_int, 1_000_000_000)
            position.x, position.y = x, y
            rotation.z, rotation.w = z, w
            write(channel, log_int, bytes(serialize(message, msgtype)))

    def write_marker(self, run_index: int, log_time_ns: int, *, stream: int = 0) -> None:
        """Write one run-start marker (UInt32 run index) at `log_time_ns`."""
        target = self._streams[stream]
        if target.marker_topic is None:
            raise BagError(f'{self.path}: this writer has no marker topic')
        if not self._open:
            raise BagError(f'{self.path}: bag is not open for writing')
        if target.marker_channel is None:
            target.marker_channel = self._bag.add_topic(target.marker_topic, MARKER_TYPE,
                                                        offered_qos=self.offered_qos)
        self._marker.data = int(run_index)
        self._bag.write(target.marker_channel, int(log_time_ns),
                        bytes(self._store.serialize_cdr(self._marker, MARKER_TYPE)))


def write_paths_bag(out_path: PathLike, paths: Paths, *, topic: str = DEFAULT_POSE_TOPIC,
                    world_frame: str = DEFAULT_WORLD_FRAME,
                    child_frame: str = DEFAULT_CHILD_FRAME,
                    marker_topic: str | None = DEFAULT_MARKER_TOPIC, gap_s: float = 1.0,
                    start_time_ns: int = DEFAULT_START_TIME_NS,
                    message_type: str = TRANSFORM_STAMPED,
                    bag_name: str | None = None) -> PathLike:
    """
    Write each run of `paths` at its sample times, one run after another.

    Runs are separated by `gap_s` (>= 1 s) of silence so that any reader can split them; one
    marker per run (data = run index) precedes its first pose unless `marker_topic` is None.
    Returns the bag directory. `bag_name`: `out_path` is a new empty folder that becomes the
    bag of that name when complete (BagWriter).
    """
    out_path = user_path(out_path, 'the bag folder')
    check_paths(paths)
    if not gap_s >= 1.0:
        raise DataError(f'{out_path}: gap between runs must be at least 1 s, got {gap_s}')
    times = np.asarray(paths.t, dtype=float)
    if len(times) == 0 or not np.all(np.isfinite(times)):
        raise DataError(f'{out_path}: the paths have no finite sample times')
    offsets_ns = np.round((times - times[0]) * 1e9).astype(np.int64)
    if np.any(np.diff(offsets_ns) <= 0):
        raise DataError(f'{out_path}: sample times must increase strictly')
    period_ns = int(offsets_ns[-1]) + int(round(gap_s * 1e9))
    with PoseBagWriter(out_path, topic=topic, world_frame=world_frame, child_frame=child_frame,
                       marker_topic=marker_topic, message_type=message_type,
                       bag_name=bag_name) as writer:
        for run_index in range(paths.n_paths):
            stamps = int(start_time_ns) + run_index * period_ns + offsets_ns
            if marker_topic:
                writer.write_marker(run_index, int(stamps[0]))
            writer.write_poses(stamps, paths.poses[run_index])
    return writer.path
