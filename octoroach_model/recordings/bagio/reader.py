"""
The one bag reader: rosbag2 (MCAP or sqlite3) and ROS 1 bags, streamed message by message.

MCAP files are read record by record in file order (`mcap_records`: mcap's record parsers),
never through their summary index: the bags that matter most are the damaged ones. A recorder
killed mid-write leaves a file without summary or footer, often without metadata.yaml; the
reader keeps every message up to the damage, skips a chunk it cannot decode (bad checksum,
garbled record) and says in `notes` what was lost. File order is arrival order, which is what
cuts a stream at its run markers. One chunk at a time is in memory. `pose_messages` gives the
messages of pose topics decoded in blocks over whole chunks where their layout is fixed
(`pose_blocks`), the same values as message by message.

sqlite3 bags go through rosbags' `AnyReader` (time order, streamed from the database); ROS 1
bags through `ros1.Ros1Bag` (rosbags' record parsers, chunk by chunk in file order).

Message types come from the bag's own definitions where Jazzy does not know them
(`msgtypes.BagTypes`), so a lab's custom pose message decodes like a standard one.
"""
from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Mapping
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
import struct
from typing import Any, NamedTuple, TYPE_CHECKING
import zlib

from mcap.exceptions import EndOfFile, McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk, CRCValidationError

from octoroach_model.errors import BagError
from octoroach_model.limits import MAX_CHUNK_BYTES, size_words
from octoroach_model.recordings.bagio.bag_files import bag_files, PathLike, ROS1_SUFFIX, Storage
from octoroach_model.recordings.bagio.mcap_records import file_records
from octoroach_model.recordings.bagio.msgtypes import BagTypes
from octoroach_model.recordings.bagio.pose_blocks import BlockSplitter, PoseBlock, WantedChannel
from octoroach_model.recordings.bagio.pose_messages import PoseLayout
from octoroach_model.recordings.bagio.qos import load_profiles, QosProfile
from octoroach_model.recordings.bagio.ros1 import Ros1Bag
from octoroach_model.settings import listed_items, unknown_name

if TYPE_CHECKING:
    from rosbags.interfaces import Connection

MCAP_MAGIC = b'\x89MCAP0\r\n'
ROS1_MAGIC = b'#ROSBAG V2.0'
# metadata.yaml custom_data key by which `repair` marks a bag whose recording was cut short
TRUNCATION_KEY = 'octoroach_model.truncated'
# What a damaged MCAP can raise while its records are parsed
_PARSE_ERRORS = (McapError, EOFError, struct.error, UnicodeDecodeError, ValueError,
                 IndexError, KeyError, OverflowError, MemoryError, RuntimeError, OSError)


class TopicInfo(NamedTuple):
    """A topic of a bag: type, message count (-1: unknown), what the recording kept of it."""

    msgtype: str
    # A field may shadow tuple.count, which mypy reports; the record is read by field name
    # and `count` is public (recordings' API).
    count: int  # type: ignore[assignment]
    offered_qos: tuple[QosProfile, ...] = ()
    type_hash: str = ''
    serialization_format: str = 'cdr'


class ChannelInfo(NamedTuple):
    """One MCAP channel (or rosbags connection) as stored, so that it can be copied as is."""

    topic: str
    msgtype: str
    message_encoding: str
    schema_encoding: str
    schema_data: bytes
    metadata: dict[str, str]


class BagMessage(NamedTuple):
    """One stored message: where, when (int ns), the serialized bytes, and its channel."""

    topic: str
    msgtype: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    channel: int  # index into BagReader.channels
    sequence: int = 0


LATEST_LOG_TIME_NS = 1 << 63  # int64 nanoseconds end in 2262: a later log time is damage


@dataclass
class FileDamage:
    """What the walk over one MCAP file met."""

    path: Path
    messages: int = 0
    unreadable_chunks: int = 0
    damage: str = ''
    complete: bool = False  # reached the data end (or footer) record
    position: int = 0  # the byte the walk has reached
    oversized: list[str] = field(default_factory=list)  # chunks refused by their size
    impossible_times: int = 0  # messages logged after 2262 (past int64 ns): skipped

    def note(self) -> str | None:
        """Say in plain words what a cut file lost; None for a whole file."""
        if self.damage:
            return (f'{self.path}: truncated MCAP ({self.damage}): read {self.messages} '
                    'messages, the rest is lost')
        return None


def check_mcap_magic(path: Path) -> None:
    """Raise BagError unless `path` starts like an MCAP file."""
    try:
        with path.open('rb') as stream:
            magic = stream.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise BagError(f'{path}: cannot read: {exc.strerror or exc}') from None
    if magic != MCAP_MAGIC:
        what = 'an empty file' if not magic else 'it does not start with the MCAP magic bytes'
        hint = (' (a multisample data set: validate, diagnose and the validator read it; '
                'replay and repair take bags only)' if path.suffix == '.npz' else '')
        raise BagError(f'{path}: not an MCAP file ({what}){hint}')


class ChunkTooLarge(Exception):
    """An MCAP chunk that claims (or holds) more than `limits.MAX_CHUNK_BYTES` decompressed."""


def _decompressed(chunk: Chunk) -> Chunk:
    """
    Return `chunk` decompressed, never past `limits.MAX_CHUNK_BYTES` (or past its own claim).

    mcap's `breakup_chunk` allocates what the chunk claims (zstd) or whatever the data expand
    to (lz4) before looking; a 32 KB file could claim 1 GiB. The claim is checked first, then
    the data are decompressed by a bounded stream, and an uncompressed chunk goes on to
    `breakup_chunk`, which checks its CRC.
    """
    claimed = int(chunk.uncompressed_size)
    if not chunk.compression:
        return chunk
    if claimed > MAX_CHUNK_BYTES:
        raise ChunkTooLarge(f'a chunk claims {size_words(claimed)} decompressed, above the '
                            f'limit of {size_words(MAX_CHUNK_BYTES)}')
    if chunk.compression == 'zstd':
        import zstandard

        try:
            with zstandard.ZstdDecompressor().stream_reader(bytes(chunk.data)) as stream:
                data = stream.read(claimed + 1)
        except zstandard.ZstdError:
            raise ValueError('the chunk does not decompress') from None
    elif chunk.compression == 'lz4':
        import lz4.frame

        decompressor = lz4.frame.LZ4FrameDecompressor()
        data = decompressor.decompress(bytes(chunk.data), max_length=claimed + 1)
    else:
        raise ValueError('unknown compression, '
                         f'{unknown_name(chunk.compression, ("zstd", "lz4"))}')
    if len(data) != claimed:
        raise ValueError('the chunk does not decompress to the size it claims')
    return dataclasses.replace(chunk, compression='', data=data)


# What a chunk becomes: its records (or pose blocks) in file order, and how many messages
ChunkSplit = Callable[[Chunk], tuple[list[Any], int]]


def _check_crc(chunk: Chunk) -> Chunk:
    """Return a decompressed chunk whose checksum (where it has one) fits; raise otherwise."""
    if chunk.uncompressed_crc != 0:
        calculated = zlib.crc32(chunk.data)
        if calculated != chunk.uncompressed_crc:
            raise CRCValidationError(chunk.uncompressed_crc, calculated, chunk)
    return chunk


def split_records(chunk: Chunk) -> tuple[list[Any], int]:
    """Return a checked chunk's records as mcap's `breakup_chunk` reads them, one by one."""
    records = breakup_chunk(chunk, validate_crc=False)
    return records, sum(isinstance(record, Message) for record in records)


def iter_mcap_records(path: Path, report: FileDamage,
                      split: ChunkSplit = split_records) -> Iterator[Any]:
    """
    Schemas, channels, metadata and messages of one MCAP file in file order, up to damage.

    Each chunk is decompressed within the limit, its checksum checked, and `split` into the
    records it holds (message by message; `pose_blocks` gives runs of pose messages decoded
    at once).
    """
    check_mcap_magic(path)
    try:
        size = path.stat().st_size
        stream = path.open('rb')
    except OSError as exc:
        raise BagError(f'{path}: cannot read: {exc.strerror or exc}') from None
    with stream:
        records = file_records(stream, size)
        while True:
            position = report.position = stream.tell()
            try:
                record = next(records)
            except StopIteration:
                report.complete = True
                return
            except EndOfFile:
                report.damage = (f'ends at byte {position} without a footer'
                                 if position >= size else f'cut inside the record at byte '
                                 f'{max(position, len(MCAP_MAGIC))}')
                return
            except _PARSE_ERRORS as error:
                report.damage = f'unreadable record at byte {position} ({type(error).__name__})'
                return
            if isinstance(record, Chunk):
                try:
                    inner, messages = split(_check_crc(_decompressed(record)))
                except ChunkTooLarge as error:
                    report.unreadable_chunks += 1
                    report.oversized.append(f'byte {position}: {error}')
                    continue
                except _PARSE_ERRORS:
                    report.unreadable_chunks += 1
                    continue
                report.messages += messages
                yield from inner
            elif isinstance(record, (Schema, Channel, Metadata)):
                yield record
            elif isinstance(record, Message):
                report.messages += 1
                yield record
            elif isinstance(record, (DataEnd, Footer)):
                report.complete = True
                return  # the summary only repeats what the data section said


@dataclass
class _McapFileTopics:
    """Channels of one MCAP file and their message counts."""

    channels: dict[int, ChannelInfo] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)


class _FileChannels:
    """The schemas of one MCAP file met so far, and its channels that are passed on."""

    def __init__(self, reader: BagReader, file_index: int, topics: set[str] | None) -> None:
        """Start a file of `reader`; `topics` None passes every channel on."""
        self.reader = reader
        self.file_index = file_index
        self.topics = topics
        self.schemas: dict[int, Schema] = {}
        self.wanted: dict[int, WantedChannel] = {}

    def take(self, record: Any) -> None:
        """Take a schema or channel record (again, unchanged, when a chunk is read twice)."""
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            info = self.reader._channel_info(record, self.schemas.get(record.schema_id))
            if self.topics is None or info.topic in self.topics:
                index = self.reader._channel(self.file_index, record.id, info)
                self.wanted[record.id] = WantedChannel(index, info.topic, info.msgtype)


class BagReader:
    """
    One bag: its topics, and its messages as a stream. See the module docstring.

    `source`: a rosbag2 bag directory, a bare .mcap file or a ROS 1 .bag file. Anything odd
    met while reading (a missing metadata.yaml, a cut file, skipped chunks) is appended to
    `notes` in plain words.
    """

    def __init__(self, source: PathLike, notes: list[str] | None = None) -> None:
        self.path = Path(source)
        self.notes = notes if notes is not None else []
        self.name = str(self.path)
        self.truncated = False
        self.channels: list[ChannelInfo] = []
        self._channel_index: dict[tuple[int, int], int] = {}
        self._topics: dict[str, TopicInfo] | None = None
        if self.path.is_file() and is_ros1_bag(self.path):
            self.storage: Storage = Storage.ROS1
            self.files: tuple[Path, ...] = (self.path,)
            self.directory: Path | None = None
        else:
            bag = bag_files(self.path)
            self.storage, self.files, self.directory = bag.storage, bag.files, bag.directory
            self.notes.extend(bag.notes)
            cut = (bag.custom_data or {}).get(TRUNCATION_KEY)
            if cut:
                self.truncated = True
                self.notes.append(f'{self.name}: repaired after a truncation ({cut})')
            if self.storage is Storage.SQLITE3 and self.directory is None:
                raise BagError(f'{self.path}: a .db3 file is read through its bag directory '
                               '(the folder with metadata.yaml)')
        self.types = BagTypes()
        self._rosbags_types: Any = None  # the AnyReader typestore (sqlite3, ROS 1)
        self._progress: tuple[float, float] = (0.0, 1.0)  # done, total (bytes or messages)

    # ----------------------------------------------------------------------------- topics

    def topics(self) -> dict[str, TopicInfo]:
        """Topic name -> TopicInfo over all files (MCAP summary, or a walk when damaged)."""
        if self._topics is None:
            self._topics = (self._mcap_topics() if self.storage is Storage.MCAP
                            else self._rosbags_topics())
        return self._topics

    def _mcap_topics(self) -> dict[str, TopicInfo]:
        topics: dict[str, TopicInfo] = {}
        for file_index, path in enumerate(self.files):
            found = self._file_topics(path)
            for channel_id, channel in found.channels.items():
                self._channel(file_index, channel_id, channel)
                count = found.counts.get(channel_id, 0)
                _add_topic(topics, channel.topic, _topic_info(channel, count))
        return topics

    def _file_topics(self, path: Path) -> _McapFileTopics:
        """Channels and counts from the summary; a walk over the records if there is none."""
        check_mcap_magic(path)
        found = _McapFileTopics()
        try:
            with path.open('rb') as stream:
                summary = make_reader(stream).get_summary()
        except Exception:  # noqa: BLE001 - a damaged summary only means: walk the file instead
            summary = None
        if summary is not None and summary.channels:
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            for channel in summary.channels.values():
                schema = summary.schemas.get(channel.schema_id)
                found.channels[channel.id] = self._channel_info(channel, schema)
                found.counts[channel.id] = int(counts.get(channel.id, 0))
            return found
        report = FileDamage(path)
        schemas: dict[int, Schema] = {}
        for record in iter_mcap_records(path, report):
            if isinstance(record, Message):
                found.counts[record.channel_id] = found.counts.get(record.channel_id, 0) + 1
            elif isinstance(record, Channel):
                found.channels[record.id] = self._channel_info(
                    record, schemas.get(record.schema_id))
            elif isinstance(record, Schema):
                schemas[record.id] = record
        return found

    def _channel_info(self, channel: Channel, schema: Schema | None) -> ChannelInfo:
        """Record a channel as stored; register its type from the schema if Jazzy lacks it."""
        msgtype = schema.name if schema is not None else ''
        encoding = schema.encoding if schema is not None else ''
        data = bytes(schema.data) if schema is not None else b''
        if msgtype and channel.message_encoding == 'cdr':
            self.types.add_definition(msgtype, encoding, data.decode('utf-8', 'replace'))
        return ChannelInfo(channel.topic, msgtype, channel.message_encoding, encoding, data,
                           dict(channel.metadata))

    def _channel(self, file_index: int, channel_id: int, channel: ChannelInfo) -> int:
        key = (file_index, channel_id)
        if key not in self._channel_index:
            self._channel_index[key] = len(self.channels)
            self.channels.append(channel)
        return self._channel_index[key]

    # --------------------------------------------------------------------------- messages

    def messages(self, topics: Collection[str] | None = None) -> Iterator[BagMessage]:
        """Messages of `topics` (None: all), MCAP in file order, others in time order."""
        if self.storage is Storage.MCAP:
            for item in self._mcap_messages(topics, {}):
                assert isinstance(item, BagMessage)  # no blocks without layouts
                yield item
        else:
            yield from self._rosbags_messages(topics)

    def pose_messages(self, topics: Collection[str], layouts: Mapping[str, PoseLayout]
                      ) -> Iterator[BagMessage | PoseBlock]:
        """
        Messages of `topics` in order, those of `layouts`' topics decoded in blocks where fixed.

        MCAP only (`pose_blocks`): runs of messages of a pose topic whose CDR layout is fixed
        come as one `PoseBlock`, already decoded; every other message comes as from
        `messages`. Other storages give their messages one by one.
        """
        if self.storage is Storage.MCAP:
            yield from self._mcap_messages(topics, layouts)
        else:
            yield from self._rosbags_messages(topics)

    @property
    def read_fraction(self) -> float:
        """Return the share of the bag that `messages` has walked so far (0 to 1)."""
        done, total = self._progress
        return min(1.0, done / total) if total > 0 else 0.0

    def _mcap_messages(self, topics: Collection[str] | None, layouts: Mapping[str, PoseLayout]
                       ) -> Iterator[BagMessage | PoseBlock]:
        wanted = None if topics is None else set(topics)
        sizes = [_file_size(path) for path in self.files]
        total = float(sum(sizes)) or 1.0
        for file_index, path in enumerate(self.files):
            report = FileDamage(path)
            before = float(sum(sizes[:file_index]))
            channels = _FileChannels(self, file_index, wanted)
            split = split_records
            if layouts:
                split = BlockSplitter(channels.wanted, layouts, channels.take, self._decode_cdr,
                                      lambda: self.types.store.fielddefs, seed=file_index).split
            for record in iter_mcap_records(path, report, split):
                if isinstance(record, Message):
                    known = channels.wanted.get(record.channel_id)
                    if known is None:
                        continue
                    if not 0 <= record.log_time < LATEST_LOG_TIME_NS:
                        report.impossible_times += 1
                        continue
                    self._progress = (before + report.position, total)
                    yield BagMessage(known.topic, known.msgtype, record.log_time,
                                     record.publish_time, record.data, known.channel,
                                     record.sequence)
                elif isinstance(record, PoseBlock):
                    self._progress = (before + report.position, total)
                    yield record
                elif isinstance(record, (Channel, Schema)):
                    channels.take(record)
            self._report(report)

    def _decode_cdr(self, data: bytes, msgtype: str) -> Any:
        return self.types.deserialize_cdr(data, msgtype)

    def _report(self, report: FileDamage) -> None:
        for refused in report.oversized:
            self.notes.append(f'{report.path}: {refused}; skipped (docs/bags.md, "Limits")')
        if report.impossible_times:
            self.notes.append(f'{report.path}: {report.impossible_times} message(s) with a log '
                              'time past the year 2262 skipped (a damaged record)')
        if report.unreadable_chunks:
            self.notes.append(f'{report.path}: {report.unreadable_chunks} unreadable chunk(s) '
                              'skipped (bad checksum or garbled records); their messages are '
                              'lost')
        note = report.note()
        if note:
            self.notes.append(note)
            self.truncated = True

    def decode(self, message: BagMessage) -> Any:
        """Decode a message into a rosbags message object (raises on undecodable bytes)."""
        if self._rosbags_types is not None:
            store, ros1 = self._rosbags_types
            if ros1:
                return store.deserialize_ros1(message.data, message.msgtype)
            return store.deserialize_cdr(message.data, message.msgtype)
        return self.types.deserialize_cdr(message.data, message.msgtype)

    @property
    def fielddefs(self) -> Any:
        """Return the type definitions messages decode with (once topics() or messages() ran)."""
        if self._rosbags_types is not None:
            return self._rosbags_types[0].fielddefs
        return self.types.store.fielddefs

    # --------------------------------------------------------- sqlite3 and ROS 1 (rosbags)

    def _any_reader(self) -> Any:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import get_typestore, Stores

        default = get_typestore(Stores.ROS1_NOETIC if self.storage is Storage.ROS1
                                else Stores.ROS2_JAZZY)
        target = self.path if self.storage is Storage.ROS1 else self.directory
        assert target is not None  # __init__ refused a sqlite3 bag without its directory
        return AnyReader([Path(target)], default_typestore=default)

    def _rosbags_call(self, work: Any) -> Any:
        """Run `work(reader)` on an open AnyReader; rosbags' errors become one BagError line."""
        from rosbags.highlevel import AnyReaderError
        from rosbags.rosbag1 import ReaderError as Ros1Error
        from rosbags.rosbag2 import ReaderError as Ros2Error

        try:
            with self._any_reader() as reader:
                self._rosbags_types = (reader.typestore, self.storage is Storage.ROS1)
                return work(reader)
        except (AnyReaderError, Ros1Error, Ros2Error, OSError) as error:
            reason = str(error) or type(error).__name__
            hint = ('; `rosbag reindex` repairs an unindexed ROS 1 bag'
                    if 'index' in reason.lower() and self.storage is Storage.ROS1 else '')
            raise BagError(f'{self.name}: cannot read the bag: {reason}{hint}') from None

    def _ros1_types(self, connections: list[Any]) -> Any:
        """Build a type store of the bag's own definitions (Noetic's where it has none)."""
        from rosbags.typesys import get_types_from_msg, get_typestore, Stores, TypesysError

        types: dict = {}
        for connection in connections:
            if connection.msgdef.data:
                try:
                    types.update(get_types_from_msg(connection.msgdef.data, connection.msgtype))
                except TypesysError:         # its message quotes the file's definition text
                    self.types.unreadable[connection.msgtype] = 'unreadable definition'
        noetic = get_typestore(Stores.ROS1_NOETIC)
        store = get_typestore(Stores.EMPTY)
        store.register({**{name: noetic.fielddefs[name] for name in noetic.fielddefs},
                        **types})
        return store

    def _ros1_topics(self) -> dict[str, TopicInfo]:
        with Ros1Bag(self.path) as bag:
            self._rosbags_types = (self._ros1_types(bag.connections), True)
            topics: dict[str, TopicInfo] = {}
            for connection in bag.connections:
                self._connection_channel(connection)
                info = _connection_topic(connection)._replace(
                    count=bag.counts.get(connection.id, 0))
                _add_topic(topics, connection.topic, info)
        return topics

    def _ros1_messages(self, topics: Collection[str] | None) -> Iterator[BagMessage]:
        wanted = None if topics is None else set(topics)
        with Ros1Bag(self.path) as bag:
            if self._rosbags_types is None:
                self._rosbags_types = (self._ros1_types(bag.connections), True)
            selected = {c.id: self._connection_channel(c) for c in bag.connections
                        if wanted is None or c.topic in wanted}
            for connection, timestamp, data in bag.messages(selected):
                self._progress = bag.progress
                yield BagMessage(connection.topic, connection.msgtype, timestamp, timestamp,
                                 data, selected[connection.id])

    def _rosbags_topics(self) -> dict[str, TopicInfo]:
        if self.storage is Storage.ROS1:
            return self._ros1_topics()

        def listing(reader: Any) -> dict[str, TopicInfo]:
            topics: dict[str, TopicInfo] = {}
            for connection in reader.connections:
                self._connection_channel(connection)
                _add_topic(topics, connection.topic, _connection_topic(connection))
            return topics

        return self._rosbags_call(listing)

    def _connection_channel(self, connection: Connection) -> int:
        key = (-1, connection.id)
        if key not in self._channel_index:
            fmt = getattr(connection.msgdef.format, 'name', 'NONE')
            encoding = {'MSG': 'ros1msg' if self.storage is Storage.ROS1 else 'ros2msg',
                        'IDL': 'ros2idl'}.get(fmt, '')
            serialization = getattr(connection.ext, 'serialization_format', 'ros1')
            self._channel(-1, key[1], ChannelInfo(
                connection.topic, connection.msgtype, serialization, encoding,
                connection.msgdef.data.encode(), {}))
        return self._channel_index[key]

    def _rosbags_messages(self, topics: Collection[str] | None) -> Iterator[BagMessage]:
        from rosbags.highlevel import AnyReaderError
        from rosbags.rosbag1 import ReaderError as Ros1Error
        from rosbags.rosbag2 import ReaderError as Ros2Error

        if self.storage is Storage.ROS1:
            yield from self._ros1_messages(topics)
            return
        wanted = None if topics is None else set(topics)
        try:
            with self._any_reader() as reader:
                self._rosbags_types = (reader.typestore, self.storage is Storage.ROS1)
                selected = [c for c in reader.connections if wanted is None or c.topic in wanted]
                indexes = {id(c): self._connection_channel(c) for c in selected}
                if not selected:
                    return
                total = float(sum(int(c.msgcount) for c in selected)) or 1.0
                for number, (connection, timestamp, data) in enumerate(
                        reader.messages(connections=selected)):
                    self._progress = (float(number), total)
                    yield BagMessage(connection.topic, connection.msgtype, timestamp, timestamp,
                                     data, indexes[id(connection)])
        except (AnyReaderError, Ros1Error, Ros2Error, OSError) as error:
            raise BagError(f'{self.name}: cannot read the bag: {error}') from None


def _file_size(path: Path) -> int:
    try:
        return max(1, path.stat().st_size)
    except OSError:
        return 1


def is_ros1_bag(path: Path) -> bool:
    """Tell a ROS 1 bag: a .bag file, or a file that starts with rosbag's "#ROSBAG" line."""
    if path.suffix == ROS1_SUFFIX:
        return True
    try:
        with path.open('rb') as stream:
            return stream.read(len(ROS1_MAGIC)) == ROS1_MAGIC
    except OSError:
        return False


def _topic_info(channel: ChannelInfo, count: int) -> TopicInfo:
    try:
        offered = load_profiles(channel.metadata.get('offered_qos_profiles'))
    except BagError:
        offered = ()
    return TopicInfo(channel.msgtype, count, offered, channel.metadata.get('topic_type_hash', ''),
                     channel.message_encoding)


def _connection_topic(connection: Connection) -> TopicInfo:
    """Describe a rosbags connection (sqlite3 or ROS 1) as a TopicInfo."""
    offered: tuple[QosProfile, ...] = ()
    profiles = getattr(connection.ext, 'offered_qos_profiles', None) or []
    try:
        offered = tuple(QosProfile.from_rosbag2({
            'history': q.history.value, 'depth': q.depth, 'reliability': q.reliability.value,
            'durability': q.durability.value, 'liveliness': q.liveliness.value,
            'deadline': q.deadline._asdict(), 'lifespan': q.lifespan._asdict(),
            'liveliness_lease_duration': q.liveliness_lease_duration._asdict(),
            'avoid_ros_namespace_conventions': q.avoid_ros_namespace_conventions,
        }) for q in profiles)
    except BagError:
        offered = ()
    from rosbags.interfaces import ConnectionExtRosbag2

    if isinstance(connection.ext, ConnectionExtRosbag2):
        return TopicInfo(connection.msgtype, int(connection.msgcount), offered,
                         connection.digest, connection.ext.serialization_format)
    return TopicInfo(connection.msgtype, int(connection.msgcount), offered, '', 'ros1')


def _add_topic(topics: dict[str, TopicInfo], topic: str, info: TopicInfo) -> None:
    """Add a channel's topic; the same topic in several files or channels sums its count."""
    if topic in topics:
        old = topics[topic]
        count = -1 if min(old.count, info.count) < 0 else old.count + info.count
        info = old._replace(count=count, offered_qos=old.offered_qos or info.offered_qos)
    topics[topic] = info


# the most topics an error lists (a bag may hold thousands)
LISTED_TOPICS = 12


def describe_topics(topics: dict[str, TopicInfo]) -> str:
    """Say 'it has /a [type], /b [type]' for error messages."""
    if not topics:
        return 'it has no topics'
    return 'it has ' + listed_items(          # names from the file: those that look like names
        sorted(topics.items()), lambda topic: f'{topic[0]} [{topic[1].msgtype}]',
        lambda topic: (topic[0], topic[1].msgtype), LISTED_TOPICS, 'topic')
