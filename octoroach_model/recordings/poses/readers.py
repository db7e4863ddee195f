"""
Pose streams from any input, each kind of input read by its reader.

`iter_pose_samples` turns each source into pose streams, delivered chunk by chunk
(`PoseChunk`), never holding an input in memory. What a source is (`sources.input_kind`)
chooses its reader in `POSE_READERS`, a mapping of classes that share the `PoseReader`
protocol (as rosbags' ``STORAGE_PLUGINS``):

- rosbag2 bags (MCAP or sqlite3) and ROS 1 bags: `bag_streams.BagPoseReader` (which streams
  of a bag are the robot: `bag_streams.choose_streams`);
- Vicon CSV exports, C3D files, Qualisys TSV exports and trajectory tables (TUM, EuRoC/ASL,
  CSV with a header): the readers of `mocap`.

Every source's chunks pass `streams.watch_streams` (the clock, the up axis, the density).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Protocol

from octoroach_model.errors import BagError, ParameterError
from octoroach_model.recordings.bagio.bag_files import PathLike
from octoroach_model.recordings.bagio.reader import BagReader, TopicInfo
from octoroach_model.recordings.conventions.chunks import DEFAULT_CHUNK_SIZE, PoseChunk
from octoroach_model.recordings.mocap.c3d_file import C3dReader
from octoroach_model.recordings.mocap.qualisys import QualisysTsvReader
from octoroach_model.recordings.mocap.tables import TableReader
from octoroach_model.recordings.mocap.vicon_csv import ViconCsvReader
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.poses.bag_streams import BagPoseReader
from octoroach_model.recordings.poses.streams import Progress, ReadProgress, watch_streams
from octoroach_model.recordings.sources import (
    expand_sources,
    input_kind,
    InputKind,
    Sources,
    unknown_input_message,
)

__all__ = ['POSE_READERS', 'PoseReader', 'bag_topics', 'iter_pose_samples',
           'iter_source_pose_chunks', 'read_options']


class PoseReader(Protocol):
    """A reader of one kind of input: made for one file or bag, it yields its pose streams."""

    def __init__(self, path: Path, options: ReadOptions, notes: list[str]) -> None:
        """Read `path` as `options` say; say what was converted or skipped in `notes`."""

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the input's pose streams in chunks of at most about `chunk_size` samples."""


# The reader of each kind of input that holds pose streams (a data set holds runs instead)
POSE_READERS: Mapping[InputKind, type[PoseReader]] = {
    InputKind.BAG: BagPoseReader,
    InputKind.VICON_CSV: ViconCsvReader,
    InputKind.C3D: C3dReader,
    InputKind.QUALISYS_TSV: QualisysTsvReader,
    InputKind.TABLE: TableReader,
}


def read_options(options: ReadOptions | None = None, topic: str | None = None) -> ReadOptions:
    """`options`, with `topic` (the older keyword) filled in; both naming topics must agree."""
    if options is None:
        return ReadOptions(topic=topic)
    if topic is not None and options.topic not in (None, topic):
        raise ParameterError(f'two pose topics given: {topic} and {options.topic}')
    if topic is not None and options.topic is None:
        return replace(options, topic=topic)
    return options


def iter_pose_samples(sources: Sources, *, topic: str | None = None,
                      notes: list[str] | None = None, chunk_size: int = DEFAULT_CHUNK_SIZE,
                      options: ReadOptions | None = None, gap_s: float | None = None,
                      progress: Progress | None = None) -> Iterator[PoseChunk]:
    """
    Pose samples of every source, chunk by chunk, without holding an input in memory.

    `sources`: bags, motion-capture files, trajectory tables, or folders of them. Which
    stream: see `bag_streams`. Every stream ends with one chunk whose `is_last` is True. What
    was converted, skipped or damaged is appended to `notes` in plain words. With `gap_s`, a
    stream too sparse to form runs is refused; `progress(fraction, message)` hears how far the
    reading has got.
    """
    notes = notes if notes is not None else []
    options = read_options(options, topic)
    paths = expand_sources(sources)
    tracker = ReadProgress(progress, paths)
    for index, path in enumerate(paths):
        yield from tracker.follow(index, path, iter_source_pose_chunks(
            path, options, notes, max(1, int(chunk_size)), gap_s=gap_s))


def iter_source_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                            chunk_size: int = DEFAULT_CHUNK_SIZE, *,
                            gap_s: float | None = None) -> Iterator[PoseChunk]:
    """Yield the pose streams of one source, by its reader, through `streams.watch_streams`."""
    kind = input_kind(path)
    if kind is InputKind.DATASET:
        raise BagError(f'{path}: a multisample data set holds runs, not pose streams '
                       '(load_measured reads it)')
    reader = POSE_READERS.get(kind)
    if reader is None:
        raise BagError(unknown_input_message(path))
    chunks = reader(path, options, notes).pose_chunks(chunk_size)
    yield from watch_streams(chunks, options, notes, from_files=kind is not InputKind.BAG,
                             gap_s=gap_s)


def bag_topics(source: PathLike) -> dict[str, TopicInfo]:
    """Topics of a bag (directory, .mcap or .bag file): type, count, recorded QoS."""
    return BagReader(source).topics()
