"""
Motion-capture files and trajectory tables, read into pose streams.

- `vicon_csv`, `c3d_file`, `qualisys`, `tables`: a reader per format (Vicon CSV, C3D,
  Qualisys TSV, TUM / EuRoC / headed CSV tables), each a `PoseReader`;
- `shared`: what they share (units, subject names, markers, chunks);
- `rigid`: rotations as Vicon writes them, and a body's pose from its markers.
"""
