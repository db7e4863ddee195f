"""
Pose streams from any input: ROS 2 and ROS 1 bags here, motion-capture files by dispatch.

`iter_pose_samples` turns each source into pose streams, delivered chunk by chunk
(`PoseChunk`), never holding a bag in memory. Inputs:

- rosbag2 bags (MCAP or sqlite3) and ROS 1 bags, read by `reader.BagReader`;
- Vicon CSV exports (.csv) and C3D files (.c3d), read by `vicon_csv` and `c3d_file`.

Which stream is the robot (`ReadOptions`): the topic named by `topic`; else
``/vicon/octoroach/octoroach``; else every topic whose type holds a pose (TransformStamped,
PoseStamped, Odometry, a bag's own type with a Pose or Transform inside; see
`pose_messages`), each its own stream; else the transform lists on /tf (and /tf_static):
the child frame named by `frame`, else the only moving one. A child frame that only
/tf_static attaches to a moving frame is followed through that static chain.

Sample time: the message's header stamp when non-zero, else the log (receive) time. Heading:
the yaw of the child frame plus the forward-axis offset (`ReadOptions.forward_axis`).
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from octoroach_model.errors import BagError, ParameterError
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.pose_messages import (
    frame_getter,
    full_pose_getter,
    FullPose,
    pose_getter,
    pose_layout,
    PoseLayout,
    tf_layout,
    TfLayout,
)
from octoroach_model.recordings.reader import BagMessage, BagReader, describe_topics, TopicInfo
from octoroach_model.recordings.sources import expand_sources, input_kind, PathLike, Sources
from octoroach_model.recordings.vicon import (
    DEFAULT_POSE_TOPIC,
    marker_topic,
    MARKER_TYPE,
    POSE_STAMPED,
    quaternion_to_heading,
    subject_of,
    TRANSFORM_STAMPED,
    wrap_angle,
)

DEFAULT_CHUNK_SIZE = 10_000
# A /tf frame "moves" when its position spans more than this, or its yaw more than MOVING_RAD
MOVING_M = 1e-3
MOVING_RAD = 1e-3
_PLAIN_TYPES = (TRANSFORM_STAMPED, POSE_STAMPED)
Quaternion = tuple[float, float, float, float]  # qx, qy, qz, qw


class PoseChunk(NamedTuple):
    """
    A block of consecutive samples of one pose stream, with the markers that came with them.

    `sequence` numbers every pose and marker message of a source in arrival (file) order, so
    a marker splits a stream exactly where the recorder received it. Times are int64 ns;
    x, y in metres, heading in radians in (-pi, pi].
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

    @property
    def stamp_s(self) -> np.ndarray:
        """Sample times in seconds (absolute; float64 keeps about 0.2 us)."""
        return self.stamp_ns / 1e9

    @property
    def poses(self) -> np.ndarray:
        """(k, 3) x, y, heading."""
        return np.column_stack([self.x, self.y, self.heading])


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
                      options: ReadOptions | None = None) -> Iterator[PoseChunk]:
    """
    Pose samples of every source, chunk by chunk, without holding an input in memory.

    `sources`: bags (rosbag2 directories, .mcap files, ROS 1 .bag files), motion-capture
    exports (.csv, .c3d), or folders of them. Which stream: see the module docstring. Every
    stream ends with one chunk whose `is_last` is True. What was converted, skipped or
    damaged is appended to `notes` in plain words.
    """
    notes = notes if notes is not None else []
    options = read_options(options, topic)
    for path in expand_sources(sources):
        yield from iter_source_pose_chunks(path, options, notes, max(1, int(chunk_size)))


def iter_source_pose_chunks(path: Path, options: ReadOptions, notes: list[str],
                            chunk_size: int = DEFAULT_CHUNK_SIZE) -> Iterator[PoseChunk]:
    """Yield the pose streams of one source, by its kind (bag, Vicon CSV, C3D)."""
    kind = input_kind(path)
    if kind == 'csv':
        reader = _mocap_reader('vicon_csv', 'iter_csv_pose_chunks', 'Vicon CSV exports')
        yield from reader(path, options, notes, chunk_size)
    elif kind == 'c3d':
        reader = _mocap_reader('c3d_file', 'iter_c3d_pose_chunks', 'C3D files')
        yield from reader(path, options, notes, chunk_size)
    elif kind == 'dataset':
        raise BagError(f'{path}: a multisample data set holds runs, not pose streams '
                       '(load_measured reads it)')
    else:
        yield from iter_bag_pose_chunks(path, options, notes, chunk_size)


def _mocap_reader(module: str, function: str, what: str) -> Callable[..., Iterator[PoseChunk]]:
    """Import the reader of a motion-capture format when first needed."""
    import importlib

    try:
        return getattr(importlib.import_module(f'octoroach_model.recordings.{module}'),
                       function)
    except (ImportError, AttributeError):
        raise BagError(f'{what} cannot be read by this installation (module '
                       f'octoroach_model.recordings.{module} is missing)') from None


def bag_topics(source: PathLike) -> dict[str, TopicInfo]:
    """Topics of a bag (directory, .mcap or .bag file): type, count, recorded QoS."""
    return BagReader(source).topics()


# --------------------------------------------------------------------------------------------
# Which streams a bag holds


@dataclass
class _Buffer:
    """Samples of one stream since the last chunk, as flat Python lists (cheap appends)."""

    source: str
    label: str
    marker: str = ''
    integers: list[int] = field(default_factory=list)  # sequence, stamp, log time per sample
    floats: list[float] = field(default_factory=list)  # x, y, qx, qy, qz, qw per sample
    markers: list[int] = field(default_factory=list)  # sequence, log time, value per marker

    def __len__(self) -> int:
        return len(self.integers) // 3

    def flush(self, offset_rad: float, is_last: bool = False,
              truncated: bool = False) -> PoseChunk:
        integers = np.array(self.integers, dtype=np.int64).reshape(-1, 3)
        floats = np.array(self.floats, dtype=float).reshape(-1, 6)
        markers = np.array(self.markers, dtype=np.int64).reshape(-1, 3)
        self.integers, self.floats, self.markers = [], [], []
        heading = quaternion_to_heading(floats[:, 2], floats[:, 3], floats[:, 4], floats[:, 5])
        if offset_rad:
            heading = wrap_angle(heading + offset_rad)
        return PoseChunk(self.source, self.label, self.marker, integers[:, 0], integers[:, 1],
                         integers[:, 2], floats[:, 0], floats[:, 1], heading, markers[:, 0],
                         markers[:, 1], markers[:, 2], is_last, truncated)


@dataclass
class _TfChoice:
    """The /tf child frame to follow, and the static chain below it (if any)."""

    topics: list[str]  # transform-list topics holding `parent` (or the frame itself)
    layout: TfLayout
    frame: str  # the followed frame
    moving_frame: str  # the frame found on /tf (== frame unless a static chain follows)
    parent: str
    static: FullPose | None = None  # x, y, z, qx, qy, qz, qw of frame in moving_frame


@dataclass
class _Plan:
    """What to read from one bag."""

    pose_topics: dict[str, PoseLayout] = field(default_factory=dict)
    tf: _TfChoice | None = None


def _layouts(reader: BagReader, topics: dict[str, TopicInfo]
             ) -> tuple[dict[str, PoseLayout], dict[str, TfLayout]]:
    """Topics holding single poses, and topics holding transform lists."""
    fielddefs = reader.fielddefs
    poses: dict[str, PoseLayout] = {}
    lists: dict[str, TfLayout] = {}
    for name, info in topics.items():
        if info.serialization_format not in ('cdr', 'ros1') or info.msgtype == MARKER_TYPE:
            continue
        listed = tf_layout(info.msgtype, fielddefs)
        if listed is not None:
            lists[name] = listed
            continue
        single = pose_layout(info.msgtype, fielddefs)
        if single is not None:
            poses[name] = single
    return poses, lists


def _plan(reader: BagReader, topics: dict[str, TopicInfo], options: ReadOptions,
          notes: list[str]) -> _Plan:
    name = reader.name
    poses, lists = _layouts(reader, topics)
    wanted = options.topic
    if wanted is None and options.frame is None and DEFAULT_POSE_TOPIC in topics:
        wanted = DEFAULT_POSE_TOPIC
    if wanted is not None:
        if wanted not in topics:
            raise BagError(f'{name}: no topic {wanted}; {describe_topics(topics)}')
        if wanted in poses:
            return _Plan({wanted: poses[wanted]})
        if wanted in lists:
            return _Plan(tf=_choose_frame(reader, {wanted: lists[wanted]}, lists, options))
        unreadable = reader.types.unreadable.get(topics[wanted].msgtype)
        why = f' ({unreadable})' if unreadable else ''
        raise BagError(f'{name}: topic {wanted} has type {topics[wanted].msgtype}{why}, '
                       f'expected {TRANSFORM_STAMPED} or {POSE_STAMPED} (or Odometry, '
                       'TFMessage, a type with a Pose or Transform inside)')
    if options.frame is None and poses:
        return _Plan(poses)
    if lists:
        dynamic = {topic: layout for topic, layout in lists.items()
                   if not topic.endswith('_static')}
        if not dynamic:
            raise BagError(f'{name}: only static transforms ({", ".join(sorted(lists))}); '
                           'nothing moves')
        return _Plan(tf=_choose_frame(reader, dynamic, lists, options))
    if options.frame is not None:
        raise BagError(f'{name}: no /tf topic to find frame {options.frame} in; '
                       f'{describe_topics(topics)}')
    undecodable = sorted(reader.types.unreadable)
    why = f'; undecodable types: {", ".join(undecodable)}' if undecodable else ''
    raise BagError(f'{name}: no pose topic ({TRANSFORM_STAMPED} or {POSE_STAMPED}, Odometry, '
                   f'TFMessage); {describe_topics(topics)}{why}')


@dataclass
class _FrameSeen:
    """What the scan of /tf saw of one child frame."""

    parent: str
    topic: str
    count: int = 0
    low: list[float] = field(default_factory=lambda: [math.inf] * 3)
    high: list[float] = field(default_factory=lambda: [-math.inf] * 3)

    def add(self, x: float, y: float, yaw: float) -> None:
        for axis, value in enumerate((x, y, yaw)):
            if value < self.low[axis]:
                self.low[axis] = value
            if value > self.high[axis]:
                self.high[axis] = value

    @property
    def moves(self) -> bool:
        """Whether the frame's position or yaw changed over the bag."""
        span = [high - low for low, high in zip(self.low, self.high)]
        turned = min(span[2], 2 * math.pi - span[2])  # yaw near +-pi wraps
        return span[0] > MOVING_M or span[1] > MOVING_M or turned > MOVING_RAD


def _choose_frame(reader: BagReader, dynamic: dict[str, TfLayout],
                  lists: dict[str, TfLayout], options: ReadOptions) -> _TfChoice:
    """Scan the transform lists once: which child frames there are, and which move."""
    name = reader.name
    statics = [topic for topic in lists if topic.endswith('_static')]
    seen: dict[str, _FrameSeen] = {}
    static: dict[str, tuple[str, FullPose]] = {}  # child -> (parent, pose)
    getters = {topic: (attrgetter_list(layout.field), pose_getter(layout.element),
                       frame_getter(layout.element.child_frame),
                       frame_getter(layout.element.parent_frame),
                       full_pose_getter(layout.element))
               for topic, layout in lists.items()}
    for message in reader.messages(list(getters)):
        try:
            decoded = reader.decode(message)
        except Exception:  # noqa: BLE001 - counted when the stream is read
            continue
        transforms, pose, child, parent, full_pose = getters[message.topic]
        for transform in transforms(decoded):
            frame = child(transform)
            sample = pose(transform)
            if message.topic in dynamic:
                entry = seen.get(frame)
                if entry is None:
                    entry = seen[frame] = _FrameSeen(parent(transform), message.topic)
                entry.count += 1
                entry.add(sample[1], sample[2], float(quaternion_to_heading(*sample[3:])))
            elif message.topic in statics and frame not in static:
                static[frame] = (parent(transform), full_pose(transform))
    wanted = options.frame.lstrip('/') if options.frame else None
    if wanted is not None:
        if wanted in seen:
            frame = wanted
        else:
            chain = _static_chain(wanted, static, seen)
            if chain is None:
                listed = ', '.join(sorted(seen)) or 'none'
                raise BagError(f'{name}: no transform to child frame {wanted} on '
                               f'{", ".join(sorted(dynamic))} (child frames: {listed})')
            moving_frame, frame_pose = chain
            entry = seen[moving_frame]
            return _TfChoice([entry.topic], dynamic[entry.topic], wanted, moving_frame,
                             entry.parent, frame_pose)
    else:
        moving = sorted(frame for frame, entry in seen.items() if entry.moves)
        candidates = moving or sorted(seen)
        if not candidates:
            raise BagError(f'{name}: no transform on {", ".join(sorted(dynamic))}')
        if len(candidates) > 1:
            raise BagError(f'{name}: several moving frames on {", ".join(sorted(dynamic))} '
                           f'({", ".join(candidates)}); choose one with --frame')
        frame = candidates[0]
    entry = seen[frame]
    return _TfChoice([entry.topic], dynamic[entry.topic], frame, frame, entry.parent)


def attrgetter_list(path: str) -> Callable[[Any], list[Any]]:
    """Get a message's list of transforms."""
    from operator import attrgetter

    get = attrgetter(path)
    return lambda message: list(get(message))


def _static_chain(frame: str, static: dict[str, tuple[str, FullPose]],
                  seen: dict[str, _FrameSeen]) -> tuple[str, FullPose] | None:
    """Follow /tf_static up to a moving frame: (that frame, pose of `frame` in it) or None."""
    pose: FullPose = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    current = frame
    for _ in range(32):
        if current not in static:
            return None
        parent, link = static[current]
        pose = _compose(link, pose)
        if parent in seen:
            return parent, pose
        current = parent
    return None


def _quaternion_product(a: Quaternion, b: Quaternion) -> Quaternion:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _rotate(q: Quaternion, v: tuple[float, float, float]) -> tuple[float, float, float]:
    x, y, z, _ = _quaternion_product(_quaternion_product(q, (*v, 0.0)),
                                     (-q[0], -q[1], -q[2], q[3]))
    return x, y, z


def _compose(outer: FullPose, inner: FullPose) -> FullPose:
    """Pose `inner` (in the frame of `outer`) expressed in the parent of `outer`."""
    moved = _rotate(outer[3:], inner[:3])
    return (outer[0] + moved[0], outer[1] + moved[1], outer[2] + moved[2],
            *_quaternion_product(outer[3:], inner[3:]))


def _marker_topics(name: str, topics: dict[str, TopicInfo], streams: dict[str, str],
                   options: ReadOptions, notes: list[str]) -> dict[str, str]:
    """
    Stream label -> its run-marker topic, for markers present with at least one message.

    `streams` maps each label to the name its subject is read from (topic or frame).
    """
    def usable(candidate: str) -> bool:
        info = topics.get(candidate)
        if info is None or info.count == 0:
            return False
        if info.msgtype != MARKER_TYPE:
            notes.append(f'{name}: marker topic {candidate} has type {info.msgtype}, '
                         f'not {MARKER_TYPE}; ignored')
            return False
        return True

    found: dict[str, str] = {}
    for label, source_name in streams.items():
        subject = options.subject if options.subject and len(streams) == 1 \
            else subject_of(source_name)
        if subject is not None and usable(marker_topic(subject)):
            found[label] = marker_topic(subject)
    if len(streams) == 1 and not found:
        others = [t for t, info in topics.items()
                  if t.endswith('/run_start') and info.msgtype == MARKER_TYPE and info.count]
        if len(others) == 1:
            found[next(iter(streams))] = others[0]
    return found


# --------------------------------------------------------------------------------------------
# Streaming the samples


def iter_bag_pose_chunks(path: PathLike, options: ReadOptions, notes: list[str],
                         chunk_size: int = DEFAULT_CHUNK_SIZE) -> Iterator[PoseChunk]:
    """Yield the pose streams of one bag (rosbag2 or ROS 1), chunk by chunk."""
    reader = BagReader(path, notes)
    topics = reader.topics()
    name = reader.name
    if not topics:
        if reader.storage == 'mcap':
            raise BagError(f'{name}: truncated MCAP, cut before any topic was recorded')
        raise BagError(f'{name}: the bag has no topics')
    plan = _plan(reader, topics, options, notes)
    offset = options.heading_offset_rad
    if plan.tf is not None:
        tf = plan.tf
        labels = {f'{tf.topics[0]}:{tf.frame}': tf.frame}
        how = (f'{tf.topics[0]}, child frame {tf.frame} relative to {tf.parent}'
               + (f' (through /tf_static from {tf.moving_frame})' if tf.static else ''))
        notes.append(f'{name}: poses from {how}')
    else:
        labels = {topic: topic for topic in plan.pose_topics}
        for topic, layout in plan.pose_topics.items():
            if layout.msgtype not in _PLAIN_TYPES:
                notes.append(f'{name}: poses from {topic} [{layout.msgtype}], fields '
                             f'{layout.description}')
    if reader.storage == 'ros1':
        notes.append(f'{name}: ROS 1 bag (rosbag format 2.0), read with rosbags')
    if offset:
        notes.append(f'{name}: heading = yaw of the body + {math.degrees(offset):g} deg '
                     f'(forward axis {options.forward_axis})')
    markers = _marker_topics(name, topics, labels, options, notes)
    buffers = {label: _Buffer(name, label, markers.get(label, '')) for label in labels}
    listeners: dict[str, list[_Buffer]] = {}
    for label, marker in markers.items():
        listeners.setdefault(marker, []).append(buffers[label])
    handlers = _handlers(plan, buffers)
    counter = _Counter()
    for message in reader.messages([*handlers, *listeners]):
        try:
            decoded = reader.decode(message)
        except Exception:  # noqa: BLE001 - damaged bytes are data: count and skip them
            counter.undecodable += 1
            continue
        if message.topic in listeners:
            counter.sequence += 1
            value = int(decoded.data)
            for target in listeners[message.topic]:
                target.markers += (counter.sequence, message.log_time_ns, value)
            if message.topic not in handlers:
                continue
        full = handlers[message.topic](decoded, message, counter)
        if full is not None and len(full) >= chunk_size:
            yield full.flush(offset)
    if counter.undecodable:
        notes.append(f'{name}: {counter.undecodable} undecodable message(s) skipped')
    if plan.tf is not None and not counter.samples:
        notes.append(f'{name}: no transform to {plan.tf.frame} could be read')
    for buffer in buffers.values():
        yield buffer.flush(offset, is_last=True, truncated=reader.truncated)


@dataclass
class _Counter:
    sequence: int = 0
    samples: int = 0
    undecodable: int = 0


Handler = Callable[[Any, BagMessage, _Counter], '_Buffer | None']


def _handlers(plan: _Plan, buffers: dict[str, _Buffer]) -> dict[str, Handler]:
    """Topic -> function adding a decoded message's samples to its stream buffer."""
    handlers: dict[str, Handler] = {}
    for topic, layout in plan.pose_topics.items():
        handlers[topic] = _single_pose_handler(layout, buffers[topic])
    if plan.tf is not None:
        buffer = next(iter(buffers.values()))
        for topic in plan.tf.topics:
            handlers[topic] = _tf_handler(plan.tf, buffer)
    return handlers


def _single_pose_handler(layout: PoseLayout, buffer: _Buffer) -> Handler:
    get = pose_getter(layout)

    def handle(decoded: Any, message: BagMessage, counter: _Counter) -> _Buffer:
        sample = get(decoded)
        counter.sequence += 1
        counter.samples += 1
        buffer.integers += (counter.sequence, sample[0] or message.log_time_ns,
                            message.log_time_ns)
        buffer.floats += sample[1:]
        return buffer

    return handle


def _tf_handler(choice: _TfChoice, buffer: _Buffer) -> Handler:
    transforms = attrgetter_list(choice.layout.field)
    get = pose_getter(choice.layout.element)
    child = frame_getter(choice.layout.element.child_frame)
    wanted, static = choice.moving_frame, choice.static

    def handle(decoded: Any, message: BagMessage, counter: _Counter) -> _Buffer | None:
        added = None
        for transform in transforms(decoded):
            if child(transform) != wanted:
                continue
            sample = get(transform)
            if static is not None:
                composed = _compose((sample[1], sample[2], 0.0, *sample[3:]), static)
                sample = (sample[0], composed[0], composed[1], *composed[3:])
            counter.sequence += 1
            counter.samples += 1
            buffer.integers += (counter.sequence, sample[0] or message.log_time_ns,
                                message.log_time_ns)
            buffer.floats += sample[1:]
            added = buffer
        return added

    return handle
