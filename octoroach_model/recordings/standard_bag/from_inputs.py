"""
Any pose input rewritten as the package's standard bag (`convert_to_bag`).

The standard bag is what `simulate` writes: `TransformStamped` on ``/vicon/S/S`` (frame
``vicon/world`` -> ``vicon/S/S``, metres, the heading as the yaw of a unit quaternion) with a
`UInt32` run marker on ``/S/run_start`` before each run. Every sample of the input's pose
stream is copied as it is (stamps, log times, arrival order; non-finite poses are dropped); the
input's own run markers are kept, and where it has none a marker is put wherever a run starts
by the reader's rule (the first sample, and every jump in the stamps longer than `gap_s`).
Which streams an input holds is decided as for every other program (`bag_streams.choose_streams`);
a bag of several robots (VICON subjects ``/vicon/S/S``) is written as several subjects, each
on its own topic. Poses come in the z-up world, so the bag is z up (REP 103). Conversion
streams: one chunk of samples at a time is in memory.
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from octoroach_model.errors import BagError, DataError, OutputError
from octoroach_model.fileio import atomic_directory
from octoroach_model.recordings.bagio.bag_files import PathLike
from octoroach_model.recordings.conventions.chunks import DEFAULT_CHUNK_SIZE, PoseChunk
from octoroach_model.recordings.conventions.topics import (
    child_frame,
    DEFAULT_SUBJECT,
    DEFAULT_WORLD_FRAME,
    marker_topic,
    pose_topic,
    subject_of,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.poses.readers import iter_source_pose_chunks
from octoroach_model.recordings.poses.streams import Progress, ReadProgress
from octoroach_model.recordings.sources import expand_sources
from octoroach_model.recordings.standard_bag.pose_writer import PoseBagWriter

DEFAULT_GAP_S = 0.5  # as the run splitter's default (run_set.DEFAULT_GAP_S)


class ConvertReport(NamedTuple):
    """What `convert_to_bag` wrote, and the notes on what it read and converted."""

    bag: Path
    subject: str
    inputs: tuple[str, ...]
    samples: int
    markers: int
    dropped: int
    notes: tuple[str, ...]


@dataclass
class _StreamState:
    """Where one input stream is: last stamp, markers still to place."""

    label: str
    has_markers: bool
    stream: int = 0  # the writer's stream (subject) it goes to
    last_stamp: int | None = None
    pending_markers: list[tuple[int, int]] = field(default_factory=list)  # sequence, log time


def convert_to_bag(inputs: Sequence[PathLike] | PathLike, out: PathLike, *,
                   options: ReadOptions | None = None, subject: str | None = None,
                   gap_s: float = DEFAULT_GAP_S, chunk_size: int = DEFAULT_CHUNK_SIZE,
                   progress: Progress | None = None) -> ConvertReport:
    """
    Write the pose streams of every input into one new standard bag at `out`.

    The streams of an input are chosen as every program chooses them (`options`: topic, /tf
    frame, subject, axes). The output subject is `subject`, else the input's (``/vicon/S/S``),
    else 'octoroach'; without `subject`, a stream of VICON subject S keeps S (so a bag of
    several robots stays several subjects). Inputs are written one after another. On any
    error the partial output is removed; the inputs are only read. `progress` hears how far
    the reading has got.
    """
    options = options or ReadOptions()
    if not (np.isfinite(gap_s) and gap_s > 0):
        raise DataError(f'gap_s must be a positive number of seconds, got {gap_s}')
    target = Path(out)
    if os.path.lexists(target):
        raise OutputError(f'{target}: exists already; choose a new path')
    paths = expand_sources([inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs))
    notes: list[str] = []
    # written under a temporary name beside it and renamed when complete: whole or absent
    with atomic_directory(target, what='the bag') as folder:
        report = _convert(paths, folder, options, subject, gap_s, notes,
                          max(1, int(chunk_size)), target, progress)
    return report


def _convert(paths: list[Path], folder: Path, options: ReadOptions, subject: str | None,
             gap_s: float, notes: list[str], chunk_size: int, target: Path,
             progress: Progress | None) -> ConvertReport:
    tracker = ReadProgress(progress, paths)
    chunks = (chunk for index, path in enumerate(paths)
              for chunk in tracker.follow(index, path, iter_source_pose_chunks(
                  path, options, notes, chunk_size, gap_s=gap_s)))
    first = next(chunks, None)
    if first is None:
        raise BagError(f'{", ".join(map(str, paths))}: no pose stream')
    chosen = subject or options.subject
    name = chosen or _stream_subject(first.topic) or DEFAULT_SUBJECT
    gap_ns = int(round(gap_s * 1e9))
    counts = {'samples': 0, 'markers': 0, 'dropped': 0}
    streams: dict[tuple[str, str], _StreamState] = {}
    outputs = {name: 0}
    custom = {'octoroach_model.converted_from': ', '.join(map(str, paths))}
    with PoseBagWriter(folder, topic=pose_topic(name), world_frame=DEFAULT_WORLD_FRAME,
                       child_frame=child_frame(name), marker_topic=marker_topic(name),
                       custom_data=custom, bag_name=target.name) as writer:
        for chunk in _with_first(first, chunks):
            key = (chunk.source, chunk.topic)
            state = streams.get(key)
            if state is None:
                own = None if chosen else _stream_subject(chunk.topic)
                out = own or name
                if out not in outputs:
                    outputs[out] = writer.add_stream(pose_topic(out), child_frame(out),
                                                     marker_topic(out))
                state = streams[key] = _StreamState(chunk.topic, bool(chunk.marker_topic),
                                                    outputs[out])
            _write_chunk(writer, chunk, state, gap_ns, counts)
    written = ', '.join(pose_topic(out) for out in outputs)
    notes.append(f'{target}: {counts["samples"]} poses written as TransformStamped on '
                 f'{written} ({DEFAULT_WORLD_FRAME} -> {child_frame(name)}, metres, z up, '
                 f'heading as the yaw of the child frame), {counts["markers"]} run markers on '
                 f'{", ".join(marker_topic(out) for out in outputs)}')
    if counts['dropped']:
        notes.append(f'{target}: {counts["dropped"]} non-finite pose(s) dropped')
    return ConvertReport(target, name, tuple(map(str, paths)), counts['samples'],
                         counts['markers'], counts['dropped'], tuple(notes))


def _stream_subject(label: str) -> str | None:
    """Return the VICON subject S of a stream label (/vicon/S/S, /tf:vicon/S/S), or None."""
    return subject_of(label.split(':')[-1])


def _with_first(first: PoseChunk, rest: Iterator[PoseChunk]) -> Iterator[PoseChunk]:
    yield first
    yield from rest


def _write_chunk(writer: PoseBagWriter, chunk: PoseChunk, state: _StreamState, gap_ns: int,
                 counts: dict[str, int]) -> None:
    """Write a chunk's finite samples with the run markers that go before them."""
    poses = chunk.poses
    finite = np.isfinite(poses).all(axis=1)
    counts['dropped'] += int((~finite).sum())
    sequence, stamps, logs = chunk.sequence[finite], chunk.stamp_ns[finite], \
        chunk.log_time_ns[finite]
    poses = poses[finite]
    if state.has_markers:
        state.pending_markers += list(zip(chunk.marker_sequence.tolist(),
                                          chunk.marker_log_time_ns.tolist()))
        starts: dict[int, list[int]] = {}
        kept: list[tuple[int, int]] = []
        for marker_sequence, log_time in state.pending_markers:
            position = int(np.searchsorted(sequence, marker_sequence, side='right'))
            if position < len(sequence):
                starts.setdefault(position, []).append(log_time)
            else:
                kept.append((marker_sequence, log_time))
        state.pending_markers = kept if not chunk.is_last else []
    else:
        starts = {}
        if len(stamps):
            before = np.empty_like(stamps)
            before[1:] = stamps[:-1]
            before[0] = stamps[0] if state.last_stamp is None else state.last_stamp
            new_run = np.abs(stamps - before) > gap_ns
            new_run[0] |= state.last_stamp is None
            starts = {int(i): [int(logs[i])] for i in np.flatnonzero(new_run)}
    if len(stamps):
        state.last_stamp = int(stamps[-1])
    edges = sorted(starts) + [len(stamps)]
    low = 0
    for edge in edges:
        if edge > low:
            writer.write_poses(stamps[low:edge], poses[low:edge], log_time_ns=logs[low:edge],
                               stream=state.stream)
            counts['samples'] += edge - low
        for log_time in starts.get(edge, []):
            writer.write_marker(counts['markers'], log_time, stream=state.stream)
            counts['markers'] += 1
        low = edge
