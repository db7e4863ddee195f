"""
Recordings: pose bags and motion-capture files, runs cut from them, multisample data sets.

Ground floor of the package: imports numpy, rosbags and mcap, never rclpy nor the model.

The bag layer (one reader, one writer, used by the CLI, the recorder, the replay and the
validator alike):

- `sources`: which files a source is, and what kind of input each one is;
- `reader.BagReader`: rosbag2 (MCAP, sqlite3) and ROS 1 bags, streamed, damage-tolerant;
- `writer.BagWriter`: rosbag2 Jazzy bags on mcap's Writer, with a crash-safe mode;
- `recording.Recording`: the recorder's bag (reception order, periodic flush);
- `repair`: a bag left by a killed recorder made complete;
- `bags`: pose streams (`PoseChunk`) from any input; `pose_writer`: the standard pose bag;
- `convert`: any input to the standard pose bag.
"""
from __future__ import annotations

from octoroach_model.recordings.bags import (
    bag_topics,
    iter_pose_samples,
    iter_source_pose_chunks,
    PoseChunk,
    read_options,
)
from octoroach_model.recordings.dataset import (
    FORMAT_VERSION,
    is_dataset_file,
    load_dataset,
    save_dataset,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.pose_writer import PoseBagWriter, write_paths_bag
from octoroach_model.recordings.qos import QosOverride, QosProfile, replay_profile
from octoroach_model.recordings.reader import BagMessage, BagReader, TopicInfo
from octoroach_model.recordings.runs import (
    DEFAULT_GAP_S,
    DEFAULT_RATE_HZ,
    load_measured,
    read_runs,
    Run,
    RunSet,
)
from octoroach_model.recordings.sources import (
    bag_files,
    BagFiles,
    expand_sources,
    MEASURED_SUFFIXES,
    POSE_INPUT_SUFFIXES,
    source_files,
)
from octoroach_model.recordings.vicon import (
    DEFAULT_CHILD_FRAME,
    DEFAULT_MARKER_TOPIC,
    DEFAULT_POSE_TOPIC,
    DEFAULT_START_TIME_NS,
    DEFAULT_SUBJECT,
    DEFAULT_WORLD_FRAME,
    heading_to_quaternion,
    marker_topic,
    MARKER_TYPE,
    ODOMETRY,
    POSE_STAMPED,
    pose_topic,
    POSE_TYPES,
    quaternion_to_heading,
    subject_of,
    TF_MESSAGE,
    TRANSFORM_STAMPED,
)
from octoroach_model.recordings.writer import BagWriter

__all__ = [
    'DEFAULT_CHILD_FRAME',
    'DEFAULT_GAP_S',
    'DEFAULT_MARKER_TOPIC',
    'DEFAULT_POSE_TOPIC',
    'DEFAULT_RATE_HZ',
    'DEFAULT_START_TIME_NS',
    'DEFAULT_SUBJECT',
    'DEFAULT_WORLD_FRAME',
    'FORMAT_VERSION',
    'MARKER_TYPE',
    'MEASURED_SUFFIXES',
    'ODOMETRY',
    'POSE_INPUT_SUFFIXES',
    'POSE_STAMPED',
    'POSE_TYPES',
    'TF_MESSAGE',
    'TRANSFORM_STAMPED',
    'BagFiles',
    'BagMessage',
    'BagReader',
    'BagWriter',
    'PoseBagWriter',
    'PoseChunk',
    'QosOverride',
    'QosProfile',
    'ReadOptions',
    'Run',
    'RunSet',
    'TopicInfo',
    'bag_files',
    'bag_topics',
    'expand_sources',
    'heading_to_quaternion',
    'is_dataset_file',
    'iter_pose_samples',
    'iter_source_pose_chunks',
    'load_dataset',
    'load_measured',
    'marker_topic',
    'pose_topic',
    'quaternion_to_heading',
    'read_options',
    'read_runs',
    'replay_profile',
    'save_dataset',
    'source_files',
    'subject_of',
    'write_paths_bag',
]
