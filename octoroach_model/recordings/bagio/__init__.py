"""
Bag I/O: rosbag2 (MCAP, sqlite3) and ROS 1 bags read and written, message by message.

- `bag_files`: a bag's storage files and their `Storage`;
- `reader.BagReader`: every bag read streamed and damage-tolerant (`mcap_records`, `ros1`),
  with pose topics of MCAP bags decoded in blocks (`pose_messages`, `fixed_cdr`,
  `pose_blocks`);
- `writer.BagWriter`: rosbag2 Jazzy bags on mcap's Writer, with a crash-safe mode;
- `recording.Recording`: the recorder's bag (reception order, periodic flush);
- `repair`: a bag left by a killed recorder made complete;
- `qos`, `msgtypes`: QoS profiles and message types as bags keep them (their YAML is read
  by the package's `safe_yaml`).
"""
