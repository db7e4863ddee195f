"""
ROS 2 nodes: thin adapters between VICON-style messages and the model / recordings layers.

Only this subpackage imports rclpy. Each module has `main(argv) -> int`, reached through
`ros2 run octoroach_model X` and `python -m octoroach_model X`:

- `simulator`: model runs published as VICON poses (TransformStamped, 50 Hz).
- `recorder`: VICON topics to a rosbag2 MCAP bag, and the bag to a multisample data set.
- `replay`: a recorded bag published again with its recorded timing.
- `validator`: probabilistic validation as services (`validator --call` is its client).

Beside them, `common` (parameters, command line, spin and shutdown, QoS) and `messages` (poses
<-> VICON transforms, run markers, validation statistics) hold what the nodes share.
"""
from __future__ import annotations

__all__ = ['recorder', 'replay', 'simulator', 'validator']
