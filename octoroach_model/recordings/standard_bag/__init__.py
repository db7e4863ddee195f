"""
The package's standard pose bag: VICON poses and run markers in a rosbag2 Jazzy bag.

- `pose_writer`: `PoseBagWriter` and `write_paths_bag` (simulated or converted runs);
- `from_inputs`: `convert_to_bag`, any pose input rewritten as the standard bag.
"""
