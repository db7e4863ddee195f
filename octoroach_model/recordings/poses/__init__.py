"""
Pose streams from any input, chunk by chunk.

- `readers`: `iter_pose_samples`, each kind of input read by its reader (`POSE_READERS`);
- `bag_streams`: which streams of a bag are the robot, and their samples;
- `streams`: what every stream is checked for on its way (clock, axes, density, progress).
"""
