"""
The record every reader yields: a block of consecutive samples of one pose stream.

Readers (bags, motion-capture files, trajectory tables) turn their input into `PoseChunk`s;
`streams.watch_streams` looks at each stream as it passes (clock, axes, rate), and the run
splitter and `from_inputs` consume them. Positions are already in the z-up world (`axes`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

DEFAULT_CHUNK_SIZE = 10_000  # samples per chunk


class PoseChunk(NamedTuple):
    """
    A block of consecutive samples of one pose stream, with the markers that came with them.

    `sequence` numbers every pose and marker message of a source in arrival (file) order, so
    a marker splits a stream exactly where the recorder received it. Times are int64 ns:
    `stamp_ns` the pose's own time (a header stamp, or the log time where there is none; for
    files the frame time), `log_time_ns` when it was recorded (= stamp_ns for files). x, y, z
    in metres in the z-up world, heading in radians in (-pi, pi]. `z` is None where a reader
    has no height; `read_fraction` is how much of the source had been read (NaN: unknown).
    """

    source: str
    topic: str
    marker_topic: str
    sequence: np.ndarray
    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    marker_sequence: np.ndarray
    marker_log_time_ns: np.ndarray
    marker_value: np.ndarray
    is_last: bool
    truncated: bool
    z: np.ndarray | None = None
    read_fraction: float = math.nan

    @property
    def stamp_s(self) -> np.ndarray:
        """Sample times in seconds (absolute; float64 keeps about 0.2 us)."""
        return self.stamp_ns / 1e9

    @property
    def poses(self) -> np.ndarray:
        """(k, 3) x, y, heading."""
        return np.column_stack([self.x, self.y, self.heading])
