"""
Pose streams of ROS 2 and ROS 1 bags: which streams are the robot, and their samples.

Which streams of a bag are the robot: `choose_streams`, the one place that decides, for every
program. In order:

1. `topic` names the topic (a topic of single poses; a list of poses, then the element by
   `frame` or `subject`, else the only one that moves);
2. `frame` names a child frame on /tf (a frame attached to a moving one only through
   /tf_static is followed through that static chain);
3. otherwise ``/vicon/<subject>/<subject>`` when `subject` names one, else
   ``/vicon/octoroach/octoroach`` if the bag has it;
4. otherwise the candidates are every topic of single poses (TransformStamped, PoseStamped,
   Odometry, a bag's own type with a Pose or Transform inside; see `pose_messages`) and every
   body that moves in an array of named bodies (MOCAP4ROS2 RigidBodies, NamedPoseArray, any
   type of that shape, read from the bag's own definition), narrowed to `subject` where it
   names one. One candidate is the robot. Several are several robots only when every one is
   a VICON subject topic ``/vicon/S/S`` (a recording of many robots); else the choice is the
   user's, and the error lists every candidate with its type and rate;
5. with no candidate, the transform lists on /tf: the only child frame that moves.

Sample time: the message's header stamp when non-zero, else the log (receive) time; then
`streams` keeps the steadier of the two clocks. Position: the pose's x, y, z turned into the
z-up world; heading: the yaw of the forward axis (`axes`). An orientation that is not a
rotation (an all-zero quaternion of an occluded body) is a dropped frame, counted in the notes.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
import math
from pathlib import Path
from typing import Any

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.recordings.bagio.bag_files import PathLike, Storage
from octoroach_model.recordings.bagio.pose_blocks import PoseBlock
from octoroach_model.recordings.bagio.pose_messages import (
    frame_getter,
    full_pose_getter,
    list_layout,
    ListKind,
    ListLayout,
    pose_getter,
    pose_layout,
    PoseLayout,
    stamp_getter,
)
from octoroach_model.recordings.bagio.reader import (
    BagMessage,
    BagReader,
    describe_topics,
    TopicInfo,
)
from octoroach_model.recordings.conventions import quaternions
from octoroach_model.recordings.conventions.axes import axes_words, Orientations, to_z_up
from octoroach_model.recordings.conventions.chunks import DEFAULT_CHUNK_SIZE, PoseChunk
from octoroach_model.recordings.conventions.quaternions import FullPose
from octoroach_model.recordings.conventions.topics import (
    DEFAULT_POSE_TOPIC,
    marker_topic,
    MARKER_TYPE,
    POSE_STAMPED,
    pose_topic,
    subject_of,
    TRANSFORM_STAMPED,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import listed_items, listed_names

__all__ = ['BagPoseReader', 'PoseStream', 'choose_streams', 'iter_bag_pose_chunks']

# Whether pose topics of MCAP bags are decoded in blocks (`pose_blocks`); False reads every
# message through rosbags' deserializer, as before, to the same chunks
# (benchmarks/bench_reading.py compares the two)
BLOCK_DECODING = True
# A pose in a list "moves" when its position spans more than this, or it turns (about any
# axis: a spinning wheel moves) by more than MOVING_RAD
MOVING_M = 1e-3
MOVING_RAD = 1e-3
# Intervals per stream kept to state its rate (the median interval: pauses between runs do
# not lower it)
RATE_INTERVALS = 4096
_PLAIN_TYPES = (TRANSFORM_STAMPED, POSE_STAMPED)
# The most candidates an error lists
_LISTED = 12


@dataclass(frozen=True)
class BagPoseReader:
    """A bag's pose streams (`iter_bag_pose_chunks`), for `POSE_READERS`."""

    path: Path
    options: ReadOptions
    notes: list[str]

    def pose_chunks(self, chunk_size: int) -> Iterator[PoseChunk]:
        """Yield the bag's pose streams, chunk by chunk."""
        return iter_bag_pose_chunks(self.path, self.options, self.notes, chunk_size)


# --------------------------------------------------------------------------------------------
# Which streams a bag holds


@dataclass(frozen=True)
class PoseStream:
    """One pose stream a bag offers: its topic, type, name in a list, size and rate."""

    topic: str
    msgtype: str
    name: str = ''  # the child frame or body in a list of poses; '' for single poses
    count: int = -1
    rate_hz: float = math.nan

    @property
    def label(self) -> str:
        """Return the stream's name in notes and runs: the topic, or topic:name."""
        return f'{self.topic}:{self.name}' if self.name else self.topic

    @property
    def subject(self) -> str | None:
        """Return the subject a stream belongs to: S of /vicon/S/S, or a body's name."""
        return self.name or subject_of(self.topic)

    def describe(self) -> str:
        """Say '/topic [type, 100 Hz]' for messages."""
        rate = f'{self.rate_hz:.3g} Hz' if math.isfinite(self.rate_hz) else 'rate unknown'
        return f'{self.label} [{self.msgtype}, {rate}]'


@dataclass
class _ListChoice:
    """One followed element of a list of poses, and the static chain below it (if any)."""

    topic: str
    layout: ListLayout
    name: str  # the followed frame or body
    listed_name: str  # the name found in the list (== name unless a static chain follows)
    parent: str
    static: FullPose | None = None  # x, y, z, qx, qy, qz, qw of `name` in `listed_name`


@dataclass
class _Plan:
    """What to read from one bag."""

    pose_topics: dict[str, PoseLayout] = field(default_factory=dict)
    lists: list[_ListChoice] = field(default_factory=list)


def _layouts(reader: BagReader, topics: dict[str, TopicInfo]
             ) -> tuple[dict[str, PoseLayout], dict[str, ListLayout]]:
    """Topics holding single poses, and topics holding lists of poses."""
    fielddefs = reader.fielddefs
    poses: dict[str, PoseLayout] = {}
    lists: dict[str, ListLayout] = {}
    for name, info in topics.items():
        if info.serialization_format not in ('cdr', 'ros1') or info.msgtype == MARKER_TYPE:
            continue
        listed = list_layout(info.msgtype, fielddefs)
        if listed is not None:
            lists[name] = listed
            continue
        single = pose_layout(info.msgtype, fielddefs)
        if single is not None:
            poses[name] = single
    return poses, lists


class _Rate:
    """The median interval of a stream's times, from its first RATE_INTERVALS intervals."""

    def __init__(self) -> None:
        """Start with no time seen."""
        self.last: int | None = None
        self.intervals: list[int] = []

    def add(self, stamp_ns: int) -> None:
        if self.last is not None and stamp_ns > self.last \
                and len(self.intervals) < RATE_INTERVALS:
            self.intervals.append(stamp_ns - self.last)
        self.last = stamp_ns

    @property
    def hz(self) -> float:
        return 1e9 / float(np.median(self.intervals)) if self.intervals else math.nan


def _topic_rates(reader: BagReader, topics: list[str]) -> dict[str, float]:
    """Return each topic's rate from the log times of its messages (one pass, no decoding)."""
    rates = {topic: _Rate() for topic in topics}
    for message in reader.messages(topics):
        rates[message.topic].add(message.log_time_ns)
        if all(len(rate.intervals) >= RATE_INTERVALS for rate in rates.values()):
            break
    return {topic: rate.hz for topic, rate in rates.items()}


def choose_streams(reader: BagReader, topics: dict[str, TopicInfo],
                   options: ReadOptions) -> _Plan:
    """Decide which streams of a bag are the robot (module docstring); BagError if unclear."""
    name = reader.name
    poses, lists = _layouts(reader, topics)
    wanted = options.topic
    if wanted is None and options.frame is None:
        by_subject = pose_topic(options.subject) if options.subject else None
        if by_subject in poses:
            wanted = by_subject
        elif DEFAULT_POSE_TOPIC in topics:
            wanted = DEFAULT_POSE_TOPIC
    if wanted is not None:
        if wanted not in topics:
            raise BagError(f'{name}: no topic {wanted}; {describe_topics(topics)}')
        if wanted in poses:
            return _Plan({wanted: poses[wanted]})
        if wanted in lists:
            return _Plan(lists=[_choose_in_list(reader, {wanted: lists[wanted]}, lists,
                                                options)])
        unreadable = reader.types.unreadable.get(topics[wanted].msgtype)
        why = f' ({unreadable})' if unreadable else ''
        raise BagError(f'{name}: topic {wanted} has type {topics[wanted].msgtype}{why}, '
                       f'expected {TRANSFORM_STAMPED} or {POSE_STAMPED} (or Odometry, '
                       'TFMessage, an array of named bodies, a type with a Pose or Transform '
                       'inside)')
    transforms = {topic: layout for topic, layout in lists.items()
                  if layout.kind is ListKind.TRANSFORMS and not topic.endswith('_static')}
    if options.frame is not None:
        if not transforms:
            raise BagError(f'{name}: no /tf topic to find frame {options.frame} in; '
                           f'{describe_topics(topics)}')
        return _Plan(lists=[_choose_in_list(reader, transforms, lists, options)])
    named = {topic: layout for topic, layout in lists.items()
             if layout.kind is ListKind.NAMED}
    candidates = [PoseStream(topic, topics[topic].msgtype, '', topics[topic].count)
                  for topic in poses]
    if named:
        seen = _scan(reader, named, {})[0]
        moving = [key for key, entry in seen.items() if entry.moves] or list(seen)
        candidates += [PoseStream(topic, named[topic].msgtype, body, seen[(topic, body)].count,
                                  seen[(topic, body)].rate_hz) for topic, body in moving]
    if options.subject is not None:
        own = [stream for stream in candidates if stream.subject == options.subject]
        if own:
            candidates = own
        elif len(candidates) > 1 or any(stream.name for stream in candidates):
            _no_subject(name, options.subject, candidates)
    if not candidates:
        if transforms:
            return _Plan(lists=[_choose_in_list(reader, transforms, lists, options)])
        if lists:
            raise BagError(f'{name}: only static transforms ({listed_names(sorted(lists))}); '
                           'nothing moves')
        undecodable = sorted(reader.types.unreadable)
        why = f'; undecodable types: {listed_names(undecodable)}' if undecodable else ''
        raise BagError(f'{name}: no pose topic ({TRANSFORM_STAMPED} or {POSE_STAMPED}, '
                       f'Odometry, TFMessage, an array of named bodies); '
                       f'{describe_topics(topics)}{why}')
    robots = len(candidates) > 1 and all(not stream.name and subject_of(stream.topic)
                                         for stream in candidates)
    if len(candidates) > 1 and not robots:
        rates = _topic_rates(reader, [stream.topic for stream in candidates if not stream.name])
        candidates = [stream if stream.name else replace(stream, rate_hz=rates[stream.topic])
                      for stream in candidates]
        raise BagError(f'{name}: several pose streams: {_listed(candidates)}; choose one with '
                       '--topic' + (' (a body of an array with --topic and --subject)'
                                    if any(stream.name for stream in candidates) else ''))
    plan = _Plan()
    for stream in candidates:
        if stream.name:
            plan.lists.append(_ListChoice(stream.topic, named[stream.topic], stream.name,
                                          stream.name, ''))
        else:
            plan.pose_topics[stream.topic] = poses[stream.topic]
    return plan


def _listed(streams: list[PoseStream]) -> str:
    """Describe streams for an error: those whose names look like names (`listed_items`)."""
    return listed_items(streams, PoseStream.describe,
                        lambda stream: (stream.label, stream.msgtype), _LISTED, 'stream')


def _no_subject(name: str, subject: str, candidates: list[PoseStream]) -> None:
    """Refuse a subject that names none of several streams (with one, it names run markers)."""
    listed = listed_names(sorted({stream.subject or '' for stream in candidates} - {''}))
    raise BagError(f'{name}: no stream of subject {subject!r} among {_listed(candidates)} '
                   f'(subjects: {listed or "none"})')


@dataclass
class _Seen:
    """What the scan of a list of poses saw of one element (a child frame or a body)."""

    parent: str
    count: int = 0
    rate: _Rate = field(default_factory=_Rate)
    low: list[float] = field(default_factory=lambda: [math.inf] * 3)
    high: list[float] = field(default_factory=lambda: [-math.inf] * 3)
    first_q: quaternions.Quaternion | None = None
    turned_rad: float = 0.0

    def add(self, stamp_ns: int, position: tuple[float, float, float],
            q: quaternions.Quaternion) -> None:
        self.count += 1
        self.rate.add(stamp_ns)
        for axis, value in enumerate(position):
            if value < self.low[axis]:
                self.low[axis] = value
            if value > self.high[axis]:
                self.high[axis] = value
        norm = quaternions.norm(q)
        if not (math.isfinite(norm) and norm > 0):
            return
        if self.first_q is None:
            self.first_q = (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)
            return
        self.turned_rad = max(self.turned_rad,
                              quaternions.angle_between_rad(self.first_q, q, norm))

    @property
    def moves(self) -> bool:
        """Whether the element's position or orientation (about any axis) changed."""
        span = max(high - low for low, high in zip(self.low, self.high))
        return span > MOVING_M or self.turned_rad > MOVING_RAD

    @property
    def rate_hz(self) -> float:
        """Return its rate: one over its median interval."""
        return self.rate.hz


def _scan(reader: BagReader, dynamic: dict[str, ListLayout], statics: dict[str, ListLayout]
          ) -> tuple[dict[tuple[str, str], _Seen], dict[str, tuple[str, FullPose]]]:
    """Read the lists once: which elements there are, how often, whether they move."""
    seen: dict[tuple[str, str], _Seen] = {}
    static: dict[str, tuple[str, FullPose]] = {}  # child -> (parent, pose)
    getters = {topic: (attrgetter_list(layout.field), pose_getter(layout.element),
                       frame_getter(layout.name), frame_getter(layout.element.parent_frame),
                       full_pose_getter(layout.element), stamp_getter(layout.stamp))
               for topic, layout in {**dynamic, **statics}.items()}
    for message in reader.messages(list(getters)):
        try:
            decoded = reader.decode(message)
        except Exception:  # noqa: BLE001 - counted when the stream is read
            continue
        elements, pose, name_of, parent, full_pose, outer = getters[message.topic]
        for element in elements(decoded):
            name = name_of(element)
            if message.topic in dynamic:
                sample = pose(element)
                key = (message.topic, name)
                entry = seen.get(key)
                if entry is None:
                    entry = seen[key] = _Seen(parent(element))
                stamp = sample[0] or outer(decoded) or message.log_time_ns
                entry.add(stamp, sample[1:4], sample[4:])
            elif name not in static:
                static[name] = (parent(element), full_pose(element))
    return seen, static


def _choose_in_list(reader: BagReader, dynamic: dict[str, ListLayout],
                    lists: dict[str, ListLayout], options: ReadOptions) -> _ListChoice:
    """Choose the followed element of lists of poses: the one named, or the only moving one."""
    name = reader.name
    kinds = {layout.kind for layout in dynamic.values()}
    transforms = ListKind.TRANSFORMS in kinds
    statics = {topic: layout for topic, layout in lists.items()
               if topic.endswith('_static') and layout.kind is ListKind.TRANSFORMS} \
        if transforms else {}
    seen, static = _scan(reader, dynamic, statics)
    layout = next(iter(dynamic.values()))
    on = listed_names(sorted(dynamic))
    wanted = options.frame if transforms else options.subject
    wanted = wanted.lstrip('/') if wanted else None
    by_name = {element: topic for topic, element in seen}
    if wanted is not None:
        if wanted in by_name:
            topic = by_name[wanted]
            return _ListChoice(topic, dynamic[topic], wanted, wanted, seen[(topic, wanted)].parent)
        chain = _static_chain(wanted, static, by_name) if transforms else None
        if chain is None:
            listed = listed_names(sorted(by_name)) or 'none'
            raise BagError(f'{name}: no {layout.what} {wanted} on {on} '
                           f'({layout.what}s: {listed})')
        listed_name, frame_pose = chain
        topic = by_name[listed_name]
        return _ListChoice(topic, dynamic[topic], wanted, listed_name,
                           seen[(topic, listed_name)].parent, frame_pose)
    moving = sorted(key for key, entry in seen.items() if entry.moves)
    candidates = moving or sorted(seen)
    if not candidates:
        raise BagError(f'{name}: no {"transform" if transforms else "body"} on {on}')
    if len(candidates) > 1:
        what = 'moving frames' if transforms else 'moving bodies'
        rates = listed_items(candidates, lambda candidate: f'{candidate[1]} at '
                             f'{_rate_words(seen[candidate].rate_hz)}',
                             lambda candidate: (candidate[1],), _LISTED)
        raise BagError(f'{name}: several {what} on {on} [{layout.msgtype}] ({rates}); '
                       f'choose one with {layout.option}')
    topic, element = candidates[0]
    return _ListChoice(topic, dynamic[topic], element, element, seen[(topic, element)].parent)


def _rate_words(rate_hz: float) -> str:
    return f'{rate_hz:.3g} Hz' if math.isfinite(rate_hz) else 'an unknown rate'


def attrgetter_list(path: str) -> Callable[[Any], list[Any]]:
    """Get a message's list of poses."""
    from operator import attrgetter

    get = attrgetter(path)
    return lambda message: list(get(message))


def _static_chain(frame: str, static: dict[str, tuple[str, FullPose]],
                  moving: dict[str, str]) -> tuple[str, FullPose] | None:
    """Follow /tf_static up to a frame on /tf: (that frame, pose of `frame` in it) or None."""
    pose: FullPose = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    current = frame
    for _ in range(32):
        if current not in static:
            return None
        parent, link = static[current]
        pose = quaternions.compose(link, pose)
        if parent in moving:
            return parent, pose
        current = parent
    return None


def _marker_topics(name: str, topics: dict[str, TopicInfo], subjects: dict[str, str | None],
                   options: ReadOptions, notes: list[str]) -> dict[str, str]:
    """
    Stream label -> its run-marker topic, for markers present with at least one message.

    `subjects` maps each label to the subject of its stream (None when it has none).
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
    for label, own in subjects.items():
        subject = options.subject if options.subject and len(subjects) == 1 else own
        if subject is not None and usable(marker_topic(subject)):
            found[label] = marker_topic(subject)
    if len(subjects) == 1 and not found:
        others = [t for t, info in topics.items()
                  if t.endswith('/run_start') and info.msgtype == MARKER_TYPE and info.count]
        if len(others) == 1:
            found[next(iter(subjects))] = others[0]
    return found


# --------------------------------------------------------------------------------------------
# Streaming the samples


@dataclass
class _Buffer:
    """
    Samples of one stream since the last chunk.

    Messages decoded one by one append to flat Python lists (cheap appends); a decoded block
    (`PoseBlock`) comes as arrays. `flush` hands them on in arrival order, at most `limit`.
    """

    source: str
    label: str
    options: ReadOptions
    marker: str = ''
    integers: list[int] = field(default_factory=list)  # sequence, stamp, log time per sample
    floats: list[float] = field(default_factory=list)  # x, y, z, qx, qy, qz, qw per sample
    markers: list[int] = field(default_factory=list)  # sequence, log time, value per marker
    orientations: Orientations = field(default_factory=Orientations)
    blocks: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # (k, 3), (k, 7)
    in_blocks: int = 0

    def __len__(self) -> int:
        return self.in_blocks + len(self.integers) // 3

    def _settle(self) -> None:
        """Turn the samples in the lists into a block, so that blocks keep arrival order."""
        if self.integers:
            integers = np.array(self.integers, dtype=np.int64).reshape(-1, 3)
            self.blocks.append((integers, np.array(self.floats, dtype=float).reshape(-1, 7)))
            self.in_blocks += len(integers)
            self.integers, self.floats = [], []

    def add_block(self, integers: np.ndarray, floats: np.ndarray) -> None:
        """Add (k, 3) sequence, stamp, log time and (k, 7) x, y, z, qx, qy, qz, qw."""
        self._settle()
        self.blocks.append((integers, floats))
        self.in_blocks += len(integers)

    def flush(self, read_fraction: float, is_last: bool = False, truncated: bool = False,
              limit: int | None = None) -> PoseChunk:
        self._settle()
        if self.blocks:
            integers = np.concatenate([block[0] for block in self.blocks])
            floats = np.concatenate([block[1] for block in self.blocks])
        else:
            integers = np.zeros((0, 3), dtype=np.int64)
            floats = np.zeros((0, 7), dtype=float)
        self.blocks, self.in_blocks = [], 0
        if limit is not None and len(integers) > limit:
            self.blocks = [(integers[limit:], floats[limit:])]
            self.in_blocks = len(integers) - limit
            integers, floats = integers[:limit], floats[:limit]
        markers = np.array(self.markers, dtype=np.int64).reshape(-1, 3)
        self.markers = []
        position = to_z_up(floats[:, :3], self.options.up_axis)
        heading = self.orientations.quaternion_headings(
            floats[:, 3:], self.options.up_axis, self.options.forward_axis)
        return PoseChunk(self.source, self.label, self.marker, integers[:, 0], integers[:, 1],
                         integers[:, 2], position[:, 0], position[:, 1], heading,
                         markers[:, 0], markers[:, 1], markers[:, 2], is_last, truncated,
                         position[:, 2], read_fraction)


def iter_bag_pose_chunks(path: PathLike, options: ReadOptions, notes: list[str],
                         chunk_size: int = DEFAULT_CHUNK_SIZE, *,
                         blocks: bool | None = None) -> Iterator[PoseChunk]:
    """
    Yield the pose streams of one bag (rosbag2 or ROS 1), chunk by chunk.

    `blocks`: single-pose topics of MCAP bags decoded in blocks where their layout is fixed
    (`pose_blocks`), the same chunks bit for bit; False decodes every message with rosbags;
    None: `BLOCK_DECODING`.
    """
    fast = BLOCK_DECODING if blocks is None else blocks
    reader = BagReader(path, notes)
    topics = reader.topics()
    name = reader.name
    if not topics:
        if reader.storage is Storage.MCAP:
            raise BagError(f'{name}: truncated MCAP, cut before any topic was recorded')
        raise BagError(f'{name}: the bag has no topics')
    plan = choose_streams(reader, topics, options)
    subjects: dict[str, str | None] = {}
    for choice in plan.lists:
        label = f'{choice.topic}:{choice.name}'
        subjects[label] = subject_of(choice.name) if choice.layout.kind is \
            ListKind.TRANSFORMS else choice.name
        kind = '' if choice.layout.kind is ListKind.TRANSFORMS \
            else f' [{choice.layout.msgtype}]'
        how = (f'{choice.topic}{kind}, {choice.layout.what} {choice.name}'
               + (f' relative to {choice.parent}' if choice.parent else '')
               + (f' (through /tf_static from {choice.listed_name})' if choice.static
                  else ''))
        notes.append(f'{name}: poses from {how}')
    for topic, layout in plan.pose_topics.items():
        subjects[topic] = subject_of(topic)
        if layout.msgtype not in _PLAIN_TYPES:
            notes.append(f'{name}: poses from {topic} [{layout.msgtype}], fields '
                         f'{layout.description}')
    if len(subjects) > 1:
        notes.append(f'{name}: {len(subjects)} pose streams, read as {len(subjects)} robots '
                     f'(VICON subjects): {", ".join(sorted(subjects))}')
    if reader.storage is Storage.ROS1:
        notes.append(f'{name}: ROS 1 bag (rosbag format 2.0), read with rosbags')
    if options.forward_axis != 'x' or options.up_axis != 'z':
        notes.append(f'{name}: forward axis {options.forward_axis}, up axis '
                     f'{options.up_axis}: {axes_words(options.up_axis, options.forward_axis)}')
    markers = _marker_topics(name, topics, subjects, options, notes)
    buffers = {label: _Buffer(name, label, options, markers.get(label, ''))
               for label in subjects}
    listeners: dict[str, list[_Buffer]] = {}
    for label, marker in markers.items():
        listeners.setdefault(marker, []).append(buffers[label])
    handlers = _handlers(plan, buffers)
    counter = _Counter()
    messages: Iterator[BagMessage | PoseBlock] = (
        reader.pose_messages([*handlers, *listeners], plan.pose_topics) if fast
        else reader.messages([*handlers, *listeners]))
    for message in messages:
        if isinstance(message, PoseBlock):
            full = _add_block(message, buffers[message.topic], counter)
            while len(full) >= chunk_size:
                yield full.flush(reader.read_fraction, limit=chunk_size)
            continue
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
        for full in handlers[message.topic](decoded, message, counter):
            if len(full) >= chunk_size:
                yield full.flush(reader.read_fraction)
    if counter.undecodable:
        notes.append(f'{name}: {counter.undecodable} undecodable message(s) skipped')
    if plan.lists and not counter.samples:
        notes.append(f'{name}: no pose of {", ".join(c.name for c in plan.lists)} could be '
                     'read')
    for buffer in buffers.values():
        last = buffer.flush(1.0, is_last=True, truncated=reader.truncated)
        notes.extend(buffer.orientations.notes(f'{name} {buffer.label}'))
        yield last


@dataclass
class _Counter:
    sequence: int = 0
    samples: int = 0
    undecodable: int = 0


def _add_block(block: PoseBlock, buffer: _Buffer, counter: _Counter) -> _Buffer:
    """Add a decoded block's samples as the message-by-message handler would, one by one."""
    count = len(block)
    integers = np.empty((count, 3), dtype=np.int64)
    integers[:, 0] = np.arange(counter.sequence + 1, counter.sequence + 1 + count)
    integers[:, 1] = np.where(block.stamp_ns != 0, block.stamp_ns, block.log_time_ns)
    integers[:, 2] = block.log_time_ns
    counter.sequence += count
    counter.samples += count
    buffer.add_block(integers, block.values)
    return buffer


Handler = Callable[[Any, BagMessage, _Counter], list[_Buffer]]


def _handlers(plan: _Plan, buffers: dict[str, _Buffer]) -> dict[str, Handler]:
    """Topic -> function adding a decoded message's samples to its stream buffers."""
    handlers: dict[str, Handler] = {}
    for topic, layout in plan.pose_topics.items():
        handlers[topic] = _single_pose_handler(layout, buffers[topic])
    by_topic: dict[str, list[_ListChoice]] = {}
    for choice in plan.lists:
        by_topic.setdefault(choice.topic, []).append(choice)
    for topic, choices in by_topic.items():
        handlers[topic] = _list_handler(choices, buffers)
    return handlers


def _single_pose_handler(layout: PoseLayout, buffer: _Buffer) -> Handler:
    get = pose_getter(layout)

    def handle(decoded: Any, message: BagMessage, counter: _Counter) -> list[_Buffer]:
        sample = get(decoded)
        counter.sequence += 1
        counter.samples += 1
        buffer.integers += (counter.sequence, sample[0] or message.log_time_ns,
                            message.log_time_ns)
        buffer.floats += sample[1:]
        return [buffer]

    return handle


def _list_handler(choices: list[_ListChoice], buffers: dict[str, _Buffer]) -> Handler:
    """Handle one list topic: the samples of each followed element go to its buffer."""
    layout = choices[0].layout
    elements = attrgetter_list(layout.field)
    get = pose_getter(layout.element)
    name_of = frame_getter(layout.name)
    outer = stamp_getter(layout.stamp)
    wanted = {choice.listed_name: (choice, buffers[f'{choice.topic}:{choice.name}'])
              for choice in choices}

    def handle(decoded: Any, message: BagMessage, counter: _Counter) -> list[_Buffer]:
        added = []
        message_stamp: int | None = None
        for element in elements(decoded):
            found = wanted.get(name_of(element))
            if found is None:
                continue
            choice, buffer = found
            stamp, x, y, z, qx, qy, qz, qw = get(element)
            if not stamp:
                if message_stamp is None:
                    message_stamp = outer(decoded)
                stamp = message_stamp
            if choice.static is not None:
                x, y, z, qx, qy, qz, qw = quaternions.compose(
                    (x, y, z, qx, qy, qz, qw), choice.static)
            counter.sequence += 1
            counter.samples += 1
            buffer.integers += (counter.sequence, stamp or message.log_time_ns,
                                message.log_time_ns)
            buffer.floats += (x, y, z, qx, qy, qz, qw)
            added.append(buffer)
        return added

    return handle
