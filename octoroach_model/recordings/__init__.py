"""
Recordings: pose bags and motion-capture files, runs cut from them, multisample data sets.

Ground floor of the package: imports numpy, rosbags and mcap, never rclpy nor the model. By
concern, each floor importing only those below it:

- `conventions`: how a pose is stated (`PoseChunk`, axes, quaternions, VICON topic names);
- `bagio`: rosbag2 and ROS 1 bags read and written (`BagReader`, `BagWriter`, the recorder's
  `Recording`, `repair`), used by the CLI, the recorder, the replay and the validator alike;
- `mocap`: motion-capture files and trajectory tables;
- `sources`: which files a source is and what kind of input each one is; `options`: how to
  find the robot's pose in any of them (`ReadOptions`);
- `poses`: pose streams from any input, each kind read by its reader (`POSE_READERS`);
- `runs`: streams cut into runs, and multisample data sets;
- `standard_bag`: the package's pose bag, written from runs or from any input.
"""
from __future__ import annotations

from octoroach_model.recordings.bagio.bag_files import bag_files, BagFiles
from octoroach_model.recordings.bagio.qos import QosOverride, QosProfile, replay_profile
from octoroach_model.recordings.bagio.reader import BagMessage, BagReader, TopicInfo
from octoroach_model.recordings.bagio.writer import BagWriter
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.conventions.quaternions import (
    heading_to_quaternion,
    quaternion_to_heading,
)
from octoroach_model.recordings.conventions.topics import (
    DEFAULT_CHILD_FRAME,
    DEFAULT_MARKER_TOPIC,
    DEFAULT_POSE_TOPIC,
    DEFAULT_START_TIME_NS,
    DEFAULT_SUBJECT,
    DEFAULT_WORLD_FRAME,
    marker_topic,
    MARKER_TYPE,
    ODOMETRY,
    POSE_STAMPED,
    pose_topic,
    POSE_TYPES,
    subject_of,
    TF_MESSAGE,
    TRANSFORM_STAMPED,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.poses.readers import (
    bag_topics,
    iter_pose_samples,
    iter_source_pose_chunks,
    read_options,
)
from octoroach_model.recordings.runs.dataset import (
    FORMAT_VERSION,
    is_dataset_file,
    load_dataset,
    save_dataset,
)
from octoroach_model.recordings.runs.run_set import (
    DEFAULT_GAP_S,
    DEFAULT_RATE_HZ,
    load_measured,
    read_runs,
    Run,
    RunSet,
)
from octoroach_model.recordings.sources import (
    expand_sources,
    MEASURED_SUFFIXES,
    POSE_INPUT_SUFFIXES,
    source_files,
)
from octoroach_model.recordings.standard_bag.pose_writer import PoseBagWriter, write_paths_bag

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
