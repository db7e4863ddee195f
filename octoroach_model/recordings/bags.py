"""Pose bags: rosbag2 MCAP bags of VICON poses, written with rosbags, read record by record.

Writing goes through rosbags' `Writer` (metadata.yaml, QoS profiles, type hashes and message
definitions exactly as rosbag2 expects them), so `ros2 bag play` and Foxglove open the result.

Reading walks the MCAP records in file order instead of using the summary index, because the
bags that matter most are the damaged ones: a recorder killed mid-write leaves a file without
summary or footer, cut at an arbitrary byte, and often without metadata.yaml. The walk keeps
every complete message up to the damage (including the readable part of a cut chunk) and
reports the loss as a note; it never holds more than one chunk and one buffer of samples.

Conventions (see the package README):

- pose topic of subject S: ``/vicon/S/S``, `geometry_msgs/msg/TransformStamped` (PoseStamped
  is read too), header frame ``vicon/world``, child frame ``vicon/S/S``; the child frame's yaw
  is the heading, z = 0.
- run marker of subject S: ``/S/run_start``, `std_msgs/msg/UInt32`, data = run index, written
  at the start time of each run just before its first pose.
- sample time: header.stamp when non-zero, else the log (receive) time.
"""
from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import lru_cache
from io import BytesIO
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, Union

import numpy as np
import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Schema
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys import Stores, get_typestore

from octoroach_model.errors import BagError, DataError
from octoroach_model.paths import HEADING, X, Y, Paths

if TYPE_CHECKING:
    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

PathLike = Union[str, 'os.PathLike[str]']
Sources = Union[PathLike, Iterable[PathLike]]

DEFAULT_POSE_TOPIC = '/vicon/octoroach/octoroach'
DEFAULT_WORLD_FRAME = 'vicon/world'
DEFAULT_CHILD_FRAME = 'vicon/octoroach/octoroach'
DEFAULT_MARKER_TOPIC = '/octoroach/run_start'
DEFAULT_START_TIME_NS = 1_700_000_000 * 10**9

TRANSFORM_STAMPED = 'geometry_msgs/msg/TransformStamped'
POSE_STAMPED = 'geometry_msgs/msg/PoseStamped'
POSE_TYPES = (TRANSFORM_STAMPED, POSE_STAMPED)
MARKER_TYPE = 'std_msgs/msg/UInt32'

# vicon_bridge publishes with the rclpy default profile: reliable, volatile, keep last 10.
_POSE_QOS = Qos(
    QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE,
    QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False,
)
_MCAP_MAGIC = b'\x89MCAP0\r\n'
_RECORD_HEAD = struct.Struct('<BQ')  # opcode, record length
_MESSAGE_HEAD = struct.Struct('<HIQQ')  # channel id, sequence, log time, publish time
_PARSE_ERRORS = (McapError, EOFError, struct.error, UnicodeDecodeError, ValueError, IndexError)


def pose_topic(subject: str) -> str:
    """The VICON pose topic of `subject` (vicon_bridge naming)."""
    return f'/vicon/{subject}/{subject}'


def marker_topic(subject: str) -> str:
    """The run-marker topic of `subject`."""
    return f'/{subject}/run_start'


def subject_of(topic: str) -> str | None:
    """The subject S of a ``/vicon/S/S`` topic, else None."""
    parts = topic.strip('/').split('/')
    if len(parts) == 3 and parts[0] == 'vicon' and parts[1] == parts[2] and parts[1]:
        return parts[1]
    return None


def heading_to_quaternion(heading: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, z, w) of the unit quaternion that turns the world frame by `heading` about z."""
    half = 0.5 * np.asarray(heading, dtype=float)
    zeros = np.zeros_like(half)
    with np.errstate(invalid='ignore'):  # a non-finite heading gives a NaN quaternion
        return zeros, zeros.copy(), np.sin(half), np.cos(half)


def quaternion_to_heading(qx: np.ndarray, qy: np.ndarray, qz: np.ndarray,
                          qw: np.ndarray) -> np.ndarray:
    """Yaw in (-pi, pi] of any quaternion; non-unit ones are normalised first.

    A zero or non-finite quaternion gives NaN, so that sample is dropped downstream.
    """
    qx, qy, qz, qw = (np.asarray(q, dtype=float) for q in (qx, qy, qz, qw))
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        usable = np.isfinite(norm) & (norm > 0.0)
        norm = np.where(usable, norm, 1.0)
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
        yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return np.where(usable, yaw, np.nan)


@lru_cache(maxsize=1)
def _typestore() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


# --------------------------------------------------------------------------------------------
# Writing


class PoseBagWriter:
    """Streams pose samples and run markers into a new rosbag2 MCAP bag directory.

    Use as a context manager; samples are written in the order given (the arrival order a
    recorder would see). Markers are created lazily, so a bag without markers has no marker
    topic at all.
    """

    def __init__(self, out_path: PathLike, *, topic: str = DEFAULT_POSE_TOPIC,
                 world_frame: str = DEFAULT_WORLD_FRAME,
                 child_frame: str = DEFAULT_CHILD_FRAME,
                 marker_topic: str | None = DEFAULT_MARKER_TOPIC,
                 message_type: str = TRANSFORM_STAMPED) -> None:
        if message_type not in POSE_TYPES:
            raise BagError(f'{out_path}: cannot write {message_type}, only {POSE_TYPES}')
        self.path = Path(out_path)
        self.topic = topic
        self.marker_topic = marker_topic or None
        self.message_type = message_type
        try:
            self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        except WriterError as exc:
            raise BagError(f'{self.path}: cannot write the bag: {exc}') from None
        self._store = _typestore()
        self._pose_connection: Connection | None = None
        self._marker_connection: Connection | None = None
        self._message = self._template(world_frame, child_frame)
        self._marker = self._store.types[MARKER_TYPE](data=0)

    def _template(self, world_frame: str, child_frame: str) -> object:
        """One message object, mutated per sample: building five objects per pose is slow."""
        types = self._store.types
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=world_frame)
        if self.message_type == TRANSFORM_STAMPED:
            transform = types['geometry_msgs/msg/Transform'](
                translation=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                rotation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
            return types[TRANSFORM_STAMPED](
                header=header, child_frame_id=child_frame, transform=transform)
        pose = types['geometry_msgs/msg/Pose'](
            position=types['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
            orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
        return types[POSE_STAMPED](header=header, pose=pose)

    def __enter__(self) -> PoseBagWriter:
        try:
            self._writer.open()
            self._pose_connection = self._writer.add_connection(
                self.topic, self.message_type, typestore=self._store,
                offered_qos_profiles=[_POSE_QOS])
        except (WriterError, OSError) as exc:
            raise BagError(f'{self.path}: cannot write the bag: {exc}') from None
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Writes the MCAP summary and metadata.yaml."""
        if self._pose_connection is not None:
            self._writer.close()
            self._pose_connection = None

    def write_poses(self, stamp_ns: np.ndarray, poses: np.ndarray, *,
                    log_time_ns: np.ndarray | None = None) -> None:
        """Writes samples (k, 3) x, y, heading at header stamps `stamp_ns` (int ns).

        The log time defaults to the stamp, as for a recorder on the VICON machine.
        """
        if self._pose_connection is None:
            raise BagError(f'{self.path}: bag is not open for writing')
        stamps = np.asarray(stamp_ns, dtype=np.int64).ravel()
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        logs = stamps if log_time_ns is None else np.asarray(log_time_ns, np.int64).ravel()
        if not len(stamps) == len(poses) == len(logs):
            raise DataError(f'{self.path}: {len(stamps)} stamps for {len(poses)} poses')
        if len(stamps) and min(stamps.min(), logs.min()) < 0:
            raise DataError(f'{self.path}: negative time stamps cannot be written')
        qx, qy, qz, qw = heading_to_quaternion(poses[:, HEADING])
        columns = zip(stamps.tolist(), logs.tolist(), poses[:, X].tolist(),
                      poses[:, Y].tolist(), qz.tolist(), qw.tolist())
        message, serialize = self._message, self._store.serialize_cdr
        stamp = message.header.stamp
        if self.message_type == TRANSFORM_STAMPED:
            position, rotation = message.transform.translation, message.transform.rotation
        else:
            position, rotation = message.pose.position, message.pose.orientation
        write, connection = self._writer.write, self._pose_connection
        for stamp_int, log_int, x, y, z, w in columns:
            stamp.sec, stamp.nanosec = divmod(stamp_int, 1_000_000_000)
            position.x, position.y = x, y
            rotation.z, rotation.w = z, w
            write(connection, log_int, serialize(message, self.message_type))

    def write_marker(self, run_index: int, log_time_ns: int) -> None:
        """Writes one run-start marker (UInt32 run index) at `log_time_ns`."""
        if self.marker_topic is None:
            raise BagError(f'{self.path}: this writer has no marker topic')
        if self._pose_connection is None:
            raise BagError(f'{self.path}: bag is not open for writing')
        if self._marker_connection is None:
            self._marker_connection = self._writer.add_connection(
                self.marker_topic, MARKER_TYPE, typestore=self._store,
                offered_qos_profiles=[_POSE_QOS])
        self._marker.data = int(run_index)
        self._writer.write(self._marker_connection, int(log_time_ns),
                           self._store.serialize_cdr(self._marker, MARKER_TYPE))


def write_paths_bag(out_path: PathLike, paths: Paths, *, topic: str = DEFAULT_POSE_TOPIC,
                    world_frame: str = DEFAULT_WORLD_FRAME,
                    child_frame: str = DEFAULT_CHILD_FRAME,
                    marker_topic: str | None = DEFAULT_MARKER_TOPIC, gap_s: float = 1.0,
                    start_time_ns: int = DEFAULT_START_TIME_NS,
                    message_type: str = TRANSFORM_STAMPED) -> Path:
    """Writes each run of `paths` at its sample times, one run after another.

    Runs are separated by `gap_s` (>= 1 s) of silence so that any reader can split them; one
    marker per run (data = run index) precedes its first pose unless `marker_topic` is None.
    Returns the bag directory.
    """
    if not gap_s >= 1.0:
        raise DataError(f'{out_path}: gap between runs must be at least 1 s, got {gap_s}')
    times = np.asarray(paths.t, dtype=float)
    if len(times) == 0 or not np.all(np.isfinite(times)):
        raise DataError(f'{out_path}: the paths have no finite sample times')
    offsets_ns = np.round((times - times[0]) * 1e9).astype(np.int64)
    if np.any(np.diff(offsets_ns) <= 0):
        raise DataError(f'{out_path}: sample times must increase strictly')
    period_ns = int(offsets_ns[-1]) + int(round(gap_s * 1e9))
    with PoseBagWriter(out_path, topic=topic, world_frame=world_frame, child_frame=child_frame,
                       marker_topic=marker_topic, message_type=message_type) as writer:
        for run_index in range(paths.n_paths):
            stamps = int(start_time_ns) + run_index * period_ns + offsets_ns
            if marker_topic:
                writer.write_marker(run_index, int(stamps[0]))
            writer.write_poses(stamps, paths.poses[run_index])
    return Path(out_path)


# --------------------------------------------------------------------------------------------
# Finding the files of a source


class BagFiles(NamedTuple):
    """The MCAP files of one source, in recording order, and what was odd about finding them."""

    name: str
    files: tuple[Path, ...]
    notes: tuple[str, ...]


def _is_bag_directory(path: Path) -> bool:
    """A rosbag2 directory: metadata.yaml, or .mcap files named after the directory."""
    if (path / 'metadata.yaml').is_file():
        return True
    files = [p for p in path.glob('*.mcap') if p.is_file()]
    return bool(files) and all(p.name.startswith(path.name) for p in files)


def expand_sources(sources: Sources, *, suffixes: tuple[str, ...] = ('.mcap',)) -> list[Path]:
    """Bag directories and files named by `sources`; a folder of bags expands to its bags.

    Files are taken as given (their content is checked when read); inside a plain folder only
    bag directories and files ending in `suffixes` count.
    """
    if isinstance(sources, (str, os.PathLike)):
        sources = [sources]
    found: list[Path] = []
    for source in sources:
        path = Path(source)
        if not path.exists():
            raise BagError(f'{path}: no such file or directory')
        if path.is_file() or _is_bag_directory(path):
            found.append(path)
            continue
        inside = _search_folder(path, suffixes)
        if not inside:
            wanted = ', '.join(suffixes)
            raise BagError(f'{path}: empty directory (no metadata.yaml, bag or {wanted} file)')
        found.extend(inside)
    if not found:
        raise BagError('no bag given')
    return found


def _search_folder(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    found: list[Path] = []
    for child in sorted(folder.iterdir()):
        if child.is_dir():
            found.extend([child] if _is_bag_directory(child) else _search_folder(child, suffixes))
        elif child.suffix in suffixes:
            found.append(child)
    return found


def bag_files(source: PathLike) -> BagFiles:
    """The .mcap files of a bag directory (from metadata.yaml if present) or of a bare file."""
    path = Path(source)
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    if path.is_file():
        return BagFiles(str(path), (path,), ())
    notes: list[str] = []
    listed = _files_in_metadata(path, notes)
    if listed is None:
        listed = sorted(p for p in path.glob('*.mcap') if p.is_file())
        if not listed:
            raise BagError(f'{path}: empty directory (no metadata.yaml and no .mcap file)')
        if not (path / 'metadata.yaml').exists():
            notes.append(f'{path}: no metadata.yaml (recorder not closed?); '
                         f'read {len(listed)} .mcap file(s) directly')
    return BagFiles(str(path), tuple(listed), tuple(notes))


def _files_in_metadata(path: Path, notes: list[str]) -> list[Path] | None:
    """Files listed in metadata.yaml, or None when it is missing or useless."""
    metadata_path = path / 'metadata.yaml'
    if not metadata_path.is_file():
        return None
    try:
        info = yaml.safe_load(metadata_path.read_text())['rosbag2_bagfile_information']
        storage = str(info.get('storage_identifier', 'mcap'))
        relative = [str(name) for name in info.get('relative_file_paths', [])]
    except (yaml.YAMLError, KeyError, TypeError, AttributeError, UnicodeDecodeError) as exc:
        notes.append(f'{metadata_path}: unreadable ({type(exc).__name__}); '
                     'read the .mcap files directly')
        return None
    if storage != 'mcap':
        raise BagError(f'{path}: storage {storage!r} is not supported, only MCAP '
                       '(record with --storage mcap or convert the bag)')
    files = [path / name for name in relative]
    present = [p for p in files if p.is_file()]
    if len(present) < len(files):
        missing = ', '.join(p.name for p in files if not p.is_file())
        notes.append(f'{path}: files listed in metadata.yaml are missing: {missing}')
    if not present:
        return None
    compressed = [p.name for p in present if p.suffix != '.mcap']
    if compressed:
        raise BagError(f'{path}: file-compressed bags are not supported ({compressed[0]}); '
                       'decompress them with `ros2 bag convert` first')
    return present


# --------------------------------------------------------------------------------------------
# Walking MCAP records


@dataclass
class _FileReport:
    """What the walk over one file met: messages read and where the damage is."""

    path: Path
    messages: int = 0
    damage: str = ''
    unreadable_records: int = 0

    def cut(self, reason: str) -> None:
        self.damage = self.damage or reason

    def note(self) -> str | None:
        if self.damage:
            return (f'{self.path}: truncated MCAP ({self.damage}): read {self.messages} '
                    'messages, the rest is lost')
        return None


def _check_magic(path: Path) -> None:
    try:
        with path.open('rb') as stream:
            magic = stream.read(len(_MCAP_MAGIC))
    except OSError as exc:
        raise BagError(f'{path}: cannot read: {exc.strerror or exc}') from None
    if magic != _MCAP_MAGIC:
        what = 'an empty file' if not magic else f'it starts with {magic[:8]!r}'
        raise BagError(f'{path}: not an MCAP file ({what})')


class MessageRecord(NamedTuple):
    """One MCAP message: channel, log time (ns) and serialized data."""

    channel_id: int
    log_time: int
    data: bytes


McapRecord = Union[Schema, Channel, MessageRecord]


def _iter_mcap_records(path: Path, report: _FileReport) -> Iterator[McapRecord]:
    """Schemas, channels and messages of the data section in file order, up to any damage."""
    try:
        _check_magic(path)
        size = path.stat().st_size
        stream = path.open('rb')
    except OSError as exc:
        raise BagError(f'{path}: cannot read: {exc.strerror or exc}') from None
    with stream:
        stream.seek(len(_MCAP_MAGIC))
        while True:
            offset = stream.tell()
            head = stream.read(_RECORD_HEAD.size)
            if len(head) < _RECORD_HEAD.size:
                report.cut(f'ends at byte {offset + len(head)} without a footer')
                return
            opcode, length = _RECORD_HEAD.unpack(head)
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                return
            if offset + _RECORD_HEAD.size + length > size:
                if opcode == Opcode.CHUNK:
                    yield from _chunk_records(stream.read(), report, complete=False)
                report.cut(f'cut inside the record at byte {offset}')
                return
            if opcode == Opcode.CHUNK:
                yield from _chunk_records(stream.read(length), report, complete=True)
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
                record = _parse_record(opcode, stream.read(length), report)
                if record is not None:
                    yield record
            else:
                stream.seek(length, os.SEEK_CUR)


def _parse_record(opcode: int, body: bytes, report: _FileReport) -> McapRecord | None:
    """A schema or channel (parsed by mcap) or a message; None if the record is garbled."""
    try:
        if opcode == Opcode.MESSAGE:
            channel_id, _, log_time, _ = _MESSAGE_HEAD.unpack_from(body)
            report.messages += 1
            return MessageRecord(channel_id, log_time, body[_MESSAGE_HEAD.size:])
        data = ReadDataStream(BytesIO(body))
        return Channel.read(data) if opcode == Opcode.CHANNEL else Schema.read(data)
    except _PARSE_ERRORS:
        report.unreadable_records += 1
        return None


def _chunk_records(body: bytes, report: _FileReport, *, complete: bool) -> Iterator[McapRecord]:
    """The records of a chunk; of a chunk cut by the end of the file, the complete ones."""
    header = ReadDataStream(BytesIO(body))
    try:
        header.read8()  # message start time
        header.read8()  # message end time
        uncompressed_size = header.read8()
        header.read4()  # uncompressed crc
        compression = header.read_prefixed_string()
        header.read8()  # compressed size
    except _PARSE_ERRORS:
        report.unreadable_records += int(complete)
        return
    content = _decompress(body[header.count:], compression, uncompressed_size, complete)
    if content is None:
        report.unreadable_records += 1
        return
    position = 0
    while position + _RECORD_HEAD.size <= len(content):
        opcode, length = _RECORD_HEAD.unpack_from(content, position)
        start = position + _RECORD_HEAD.size
        if start + length > len(content):
            report.unreadable_records += int(complete)
            return
        if opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
            record = _parse_record(opcode, content[start:start + length], report)
            if record is not None:
                yield record
        position = start + length


def _decompress(data: bytes, compression: str, size: int, complete: bool) -> bytes | None:
    """A chunk's records; of a cut chunk, as much as its decoder gives back."""
    try:
        if compression == '':
            return data
        if compression == 'zstd':
            import zstandard

            if complete:
                return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
            return zstandard.ZstdDecompressor().decompressobj().decompress(data)
        if compression == 'lz4':
            import lz4.frame

            if complete:
                return lz4.frame.decompress(data)
            return lz4.frame.LZ4FrameDecompressor().decompress(data)
    except Exception:  # noqa: BLE001 - a failing decoder only means the chunk is lost
        return None if complete else b''
    return None


# --------------------------------------------------------------------------------------------
# Topics of a source


class TopicInfo(NamedTuple):
    """A topic's message type and message count (-1: unknown)."""

    msgtype: str
    count: int


def bag_topics(source: PathLike) -> dict[str, TopicInfo]:
    """Topics of a bag directory or .mcap file, from the MCAP summary or, if damaged, a walk."""
    return _source_topics(bag_files(source))[0]


def _source_topics(bag: BagFiles) -> tuple[dict[str, TopicInfo], list[str]]:
    """Topics over all files of a source, and the damage found while listing them."""
    topics: dict[str, TopicInfo] = {}
    damage: list[str] = []
    for path in bag.files:
        file_topics, report = _file_topics(path)
        if report.damage:
            damage.append(report.damage)
        for topic, info in file_topics.items():
            _add_topic(topics, topic, info.msgtype, info.count)
    return topics, damage


def _file_topics(path: Path) -> tuple[dict[str, TopicInfo], _FileReport]:
    _check_magic(path)
    report = _FileReport(path)
    try:
        with path.open('rb') as stream:
            summary = make_reader(stream).get_summary()
    except Exception:  # noqa: BLE001 - a damaged summary only means: walk the file instead
        summary = None
    topics: dict[str, TopicInfo] = {}
    if summary is not None and summary.channels:
        counts = summary.statistics.channel_message_counts if summary.statistics else None
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            count = -1 if counts is None else int(counts.get(channel.id, 0))
            _add_topic(topics, channel.topic, schema.name if schema else '', count)
        return topics, report
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    counts_by_channel: dict[int, int] = {}
    for record in _iter_mcap_records(path, report):
        if isinstance(record, MessageRecord):
            counts_by_channel[record.channel_id] = counts_by_channel.get(record.channel_id, 0) + 1
        elif isinstance(record, Channel):
            channels[record.id] = (record.topic, schemas.get(record.schema_id, ''))
        else:
            schemas[record.id] = record.name
    for channel_id, (topic, msgtype) in channels.items():
        _add_topic(topics, topic, msgtype, counts_by_channel.get(channel_id, 0))
    return topics, report


def _add_topic(topics: dict[str, TopicInfo], topic: str, msgtype: str, count: int) -> None:
    if topic in topics:
        old = topics[topic]
        count = -1 if min(old.count, count) < 0 else old.count + count
        msgtype = old.msgtype
    topics[topic] = TopicInfo(msgtype, count)


def _describe_topics(topics: dict[str, TopicInfo]) -> str:
    if not topics:
        return 'it has no topics'
    listed = (f'{name} [{info.msgtype}]' for name, info in sorted(topics.items()))
    return 'it has ' + ', '.join(listed)


def select_pose_topics(name: str, topics: dict[str, TopicInfo],
                       topic: str | None = None) -> list[str]:
    """The pose streams to read from one source (see `iter_pose_samples`)."""
    wanted = topic if topic is not None else DEFAULT_POSE_TOPIC
    if wanted in topics:
        msgtype = topics[wanted].msgtype
        if msgtype not in POSE_TYPES:
            raise BagError(f'{name}: topic {wanted} has type {msgtype}, expected '
                           f'{TRANSFORM_STAMPED} or {POSE_STAMPED}')
        return [wanted]
    if topic is not None:
        raise BagError(f'{name}: no topic {topic}; {_describe_topics(topics)}')
    pose_topics = sorted(name for name, info in topics.items() if info.msgtype in POSE_TYPES)
    if not pose_topics:
        raise BagError(f'{name}: no pose topic ({TRANSFORM_STAMPED} or {POSE_STAMPED}); '
                       f'{_describe_topics(topics)}')
    return pose_topics


def _marker_topics(name: str, topics: dict[str, TopicInfo], streams: list[str],
                   notes: list[str]) -> dict[str, str]:
    """Pose stream -> its run-marker topic, for markers present with at least one message."""
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
    for stream in streams:
        subject = subject_of(stream)
        if subject is not None and usable(marker_topic(subject)):
            found[stream] = marker_topic(subject)
    if len(streams) == 1 and not found:
        others = [t for t, info in topics.items()
                  if t.endswith('/run_start') and info.msgtype == MARKER_TYPE and info.count]
        if len(others) == 1:
            found[streams[0]] = others[0]
    return found


# --------------------------------------------------------------------------------------------
# Streaming pose samples


class PoseChunk(NamedTuple):
    """A block of consecutive samples of one pose stream, with the markers that came with them.

    `sequence` numbers every pose and marker message of a source in arrival (file) order, so
    a marker splits a stream exactly where the recorder received it. Times are int64 ns.
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
    def marker_stamp_s(self) -> np.ndarray:
        return self.marker_log_time_ns / 1e9

    @property
    def poses(self) -> np.ndarray:
        """(k, 3) x, y, heading."""
        return np.column_stack([self.x, self.y, self.heading])


class _StreamBuffer:
    """Samples of one stream since the last chunk, as flat Python lists (cheap appends)."""

    def __init__(self, source: str, topic: str, marker: str) -> None:
        self.source, self.topic, self.marker = source, topic, marker
        self.clear()

    def clear(self) -> None:
        self.integers: list[int] = []  # sequence, stamp, log time per sample
        self.floats: list[float] = []  # x, y, qx, qy, qz, qw per sample
        self.markers: list[int] = []  # sequence, log time, value per marker

    def __len__(self) -> int:
        return len(self.integers) // 3

    def flush(self, is_last: bool = False, truncated: bool = False) -> PoseChunk:
        integers = np.array(self.integers, dtype=np.int64).reshape(-1, 3)
        floats = np.array(self.floats, dtype=float).reshape(-1, 6)
        markers = np.array(self.markers, dtype=np.int64).reshape(-1, 3)
        self.clear()
        heading = quaternion_to_heading(floats[:, 2], floats[:, 3], floats[:, 4], floats[:, 5])
        return PoseChunk(
            self.source, self.topic, self.marker, integers[:, 0], integers[:, 1],
            integers[:, 2], floats[:, 0], floats[:, 1], heading, markers[:, 0], markers[:, 1],
            markers[:, 2], is_last, truncated)


def iter_pose_samples(sources: Sources, *, topic: str | None = None,
                      notes: list[str] | None = None,
                      chunk_size: int = 10_000) -> Iterator[PoseChunk]:
    """Pose samples of every source, chunk by chunk, without holding a bag in memory.

    `sources`: bag directories (metadata.yaml + .mcap, or only .mcap files when the recorder
    died), bare .mcap files, or folders of them. Topic choice per source: `topic` if given;
    else ``/vicon/octoroach/octoroach`` if present; else every pose-typed topic, each its own
    stream. Every stream ends with one chunk whose `is_last` is True. What was skipped or
    damaged is appended to `notes` in plain words.
    """
    notes = notes if notes is not None else []
    for path in expand_sources(sources):
        yield from _iter_source(path, topic, notes, max(1, int(chunk_size)))


def _iter_source(path: Path, topic: str | None, notes: list[str],
                 chunk_size: int) -> Iterator[PoseChunk]:
    bag = bag_files(path)
    notes.extend(bag.notes)
    topics, damage = _source_topics(bag)
    if not topics and damage:
        raise BagError(f'{bag.name}: truncated MCAP, cut before any topic was recorded '
                       f'({damage[0]})')
    streams = select_pose_topics(bag.name, topics, topic)
    markers = _marker_topics(bag.name, topics, streams, notes)
    buffers = {name: _StreamBuffer(bag.name, name, markers.get(name, '')) for name in streams}
    listeners: dict[str, list[_StreamBuffer]] = {}
    for stream, marker in markers.items():
        listeners.setdefault(marker, []).append(buffers[stream])
    deserialize = _typestore().deserialize_cdr
    sequence = 0
    undecodable = 0
    truncated = False
    for file_path in bag.files:
        report = _FileReport(file_path)
        schemas: dict[int, str] = {}
        # channel id -> (message type, buffers fed by it)
        handlers: dict[int, tuple[str, list[_StreamBuffer]]] = {}
        for record in _iter_mcap_records(file_path, report):
            if isinstance(record, MessageRecord):
                handler = handlers.get(record.channel_id)
                if handler is None:
                    continue
                msgtype, targets = handler
                try:
                    message = deserialize(record.data, msgtype)
                    if msgtype == MARKER_TYPE:
                        value = int(message.data)
                    else:
                        sample = _pose_fields(message, msgtype)
                except Exception:  # noqa: BLE001 - damaged CDR is data: count and skip it
                    undecodable += 1
                    continue
                sequence += 1
                if msgtype == MARKER_TYPE:
                    for target in targets:
                        target.markers += (sequence, record.log_time, value)
                    continue
                target = targets[0]
                stamp = sample[0] or record.log_time
                target.integers += (sequence, stamp, record.log_time)
                target.floats += sample[1:]
                if len(target) >= chunk_size:
                    yield target.flush()
            elif isinstance(record, Channel):
                msgtype = schemas.get(record.schema_id, '')
                if record.message_encoding != 'cdr':
                    continue
                if record.topic in buffers and msgtype in POSE_TYPES:
                    handlers[record.id] = (msgtype, [buffers[record.topic]])
                elif record.topic in listeners and msgtype == MARKER_TYPE:
                    handlers[record.id] = (msgtype, listeners[record.topic])
            else:
                schemas[record.id] = record.name
        if report.unreadable_records:
            notes.append(f'{file_path}: {report.unreadable_records} unreadable record(s) '
                         'skipped')
        damage = report.note()
        if damage:
            notes.append(damage)
            truncated = True
    if undecodable:
        notes.append(f'{bag.name}: {undecodable} undecodable message(s) skipped')
    for buffer in buffers.values():
        yield buffer.flush(is_last=True, truncated=truncated)


def _pose_fields(message: object, msgtype: str) -> tuple[int, float, float, float, float,
                                                          float, float]:
    """(header stamp ns, x, y, qx, qy, qz, qw) of a TransformStamped or PoseStamped."""
    stamp = message.header.stamp
    if msgtype == TRANSFORM_STAMPED:
        position, rotation = message.transform.translation, message.transform.rotation
    else:
        position, rotation = message.pose.position, message.pose.orientation
    return (stamp.sec * 1_000_000_000 + stamp.nanosec, float(position.x), float(position.y),
            float(rotation.x), float(rotation.y), float(rotation.z), float(rotation.w))
