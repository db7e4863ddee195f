"""
How every reader and writer states a pose; the floor the other recordings modules stand on.

- `chunks`: `PoseChunk`, the record every reader yields;
- `axes`: the z-up world, the body's forward axis and the heading;
- `quaternions`: all quaternion arithmetic (heading, rotation matrices, composing poses);
- `topics`: the VICON names of topics, frames and message types.
"""
