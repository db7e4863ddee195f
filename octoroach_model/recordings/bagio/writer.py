"""
The one bag writer: rosbag2 bags as ROS 2 Jazzy writes them, on mcap's public Writer.

Layout (rosbag2 Jazzy, storage plugin mcap, metadata version 9):

- ``BAG/BAG_0.mcap``: MCAP profile ``ros2``; one schema per message type (encoding
  ``ros2msg``, the full definition text); one channel per topic (message encoding ``cdr``)
  whose metadata holds ``offered_qos_profiles`` (YAML) and ``topic_type_hash`` (RIHS01); a
  ``rosbag2`` metadata record holding the bag's metadata as ``serialized_metadata``.
- ``BAG/metadata.yaml``: ``rosbag2_bagfile_information`` with ``ros_distro: jazzy``, per-topic
  ``offered_qos_profiles`` (a list; infinite durations as ``{sec: 9223372036, nsec:
  854775807}``) and ``type_description_hash``.

Crash-safe mode (the recorder): `flush()` ends the open chunk, hands everything written so far
to the operating system and syncs it to disk. mcap's `Writer.flush()` is public API (in the
version pinned in requirements.txt; a test checks it) and does the first two; a process killed
with SIGKILL after a flush leaves a file that `BagReader` and `repair` read up to that flush.
Chunks are small (64 KiB): a file cut at an arbitrary byte loses at most the chunk being cut.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import os
from pathlib import Path
import time
from typing import Any, IO

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
import yaml

from octoroach_model.errors import BagError, DataError, OutputError
from octoroach_model.fileio import is_empty_directory, write_text_atomic
from octoroach_model.recordings.bagio.bag_files import METADATA_FILE, PathLike, Storage
from octoroach_model.recordings.bagio.msgtypes import standard_definition, TypeDefinition
from octoroach_model.recordings.bagio.qos import dump_profiles, load_profiles, QosProfile

ROS_DISTRO = 'jazzy'
METADATA_VERSION = 9
MCAP_PROFILE = 'ros2'
DEFAULT_CHUNK_SIZE = 64 * 1024
LIBRARY = 'octoroach_model'


@dataclass(frozen=True)
class TopicRecord:
    """One topic as metadata.yaml lists it."""

    name: str
    msgtype: str
    serialization_format: str
    offered_qos: tuple[QosProfile, ...]
    type_hash: str
    message_count: int


@dataclass(frozen=True)
class FileRecord:
    """One storage file as metadata.yaml lists it."""

    path: str  # relative to the bag directory
    start_ns: int
    duration_ns: int
    message_count: int


def metadata_document(files: Sequence[FileRecord], topics: Sequence[TopicRecord], *,
                      storage: Storage = Storage.MCAP,
                      custom_data: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Build metadata.yaml's content (inside ``rosbag2_bagfile_information``), Jazzy's form."""
    counted = [record for record in files if record.message_count]
    start = min((record.start_ns for record in counted), default=0)
    end = max((record.start_ns + record.duration_ns for record in counted), default=0)
    return {
        'version': METADATA_VERSION,
        'storage_identifier': storage.value,
        'duration': {'nanoseconds': max(0, end - start)},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(record.message_count for record in files),
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': topic.name,
                'type': topic.msgtype,
                'serialization_format': topic.serialization_format,
                'offered_qos_profiles': [q.to_rosbag2() for q in topic.offered_qos],
                'type_description_hash': topic.type_hash,
            },
            'message_count': topic.message_count,
        } for topic in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [record.path for record in files],
        'files': [{
            'path': record.path,
            'starting_time': {'nanoseconds_since_epoch': record.start_ns},
            'duration': {'nanoseconds': record.duration_ns},
            'message_count': record.message_count,
        } for record in files],
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ROS_DISTRO,
    }


def write_metadata_yaml(directory: Path, document: Mapping[str, Any]) -> Path:
    """Write ``metadata.yaml`` atomically (`fileio.write_text_atomic`; a link is replaced)."""
    target = directory / METADATA_FILE
    try:
        write_text_atomic(target, yaml.safe_dump({'rosbag2_bagfile_information': dict(document)},
                                                 sort_keys=False, default_flow_style=False),
                          replace=True, what='bag metadata')
    except OSError as exc:
        raise OutputError(f'{target}: cannot write: {exc.strerror or exc}') from None
    return target


@dataclass
class _ChannelCount:
    """Bookkeeping of one channel for metadata.yaml."""

    topic: str
    msgtype: str
    serialization_format: str
    metadata: dict[str, str]
    count: int = 0


class McapFileWriter:
    """One rosbag2 MCAP file, written through mcap's Writer; see the module docstring."""

    def __init__(self, path: Path, *, chunk_size: int = DEFAULT_CHUNK_SIZE) -> None:
        self.path = path
        try:
            self._stream: IO[bytes] = path.open('xb')
        except FileExistsError:
            raise OutputError(f'{path}: exists already; choose a new path') from None
        except OSError as exc:
            raise OutputError(f'{path}: cannot write: {exc.strerror or exc}') from None
        self._mcap = McapWriter(self._stream, chunk_size=chunk_size,
                                compression=CompressionType.NONE, enable_crcs=True)
        self._mcap.start(profile=MCAP_PROFILE, library=LIBRARY)
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._channels: dict[int, _ChannelCount] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.message_count = 0
        self.finished = False

    def add_channel(self, topic: str, msgtype: str, *, schema_encoding: str,
                    schema_data: bytes, message_encoding: str = 'cdr',
                    metadata: Mapping[str, str] | None = None) -> int:
        """Add a channel (one topic and type); its schema is shared with others of the type."""
        key = (msgtype, schema_encoding, bytes(schema_data))
        schema_id = self._schemas.get(key)
        if schema_id is None:
            schema_id = self._schemas[key] = self._mcap.register_schema(
                msgtype, schema_encoding, bytes(schema_data))
        metadata = dict(metadata or {})
        channel_id = self._mcap.register_channel(topic, message_encoding, schema_id, metadata)
        self._channels[channel_id] = _ChannelCount(topic, msgtype, message_encoding, metadata)
        return channel_id

    def write(self, channel_id: int, log_time_ns: int, data: bytes, *,
              publish_time_ns: int | None = None, sequence: int = 0) -> None:
        """Append one serialized message to the file."""
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            raise DataError(f'{self.path}: negative time stamps cannot be written')
        self._mcap.add_message(channel_id, log_time_ns, data,
                               log_time_ns if publish_time_ns is None else int(publish_time_ns),
                               sequence)
        self._channels[channel_id].count += 1
        self.message_count += 1
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Add an MCAP metadata record (rosbag2 keeps its metadata in one named 'rosbag2')."""
        self._mcap.add_metadata(name, dict(data))

    def flush(self, sync: bool = True) -> None:
        """End the open chunk and hand the file to the OS (and the disk, with `sync`)."""
        self._mcap.flush()
        if sync:
            os.fsync(self._stream.fileno())

    def finish(self, sync: bool = False) -> None:
        """Write the summary, index and footer and close the file (synced, with `sync`)."""
        if self.finished:
            return
        self._mcap.finish()
        if sync:
            self._stream.flush()
            os.fsync(self._stream.fileno())
        self._stream.close()
        self.finished = True

    def abort(self) -> None:
        """Close the file as it is (no summary): what was flushed stays readable."""
        if not self.finished:
            self.finished = True
            try:
                self._stream.close()
            except OSError:
                pass

    def file_record(self, relative: str) -> FileRecord:
        """Give this file's entry of metadata.yaml."""
        start = self.start_ns or 0
        return FileRecord(relative, start, max(0, self.end_ns - start), self.message_count)

    def topic_records(self) -> list[TopicRecord]:
        """One entry per channel, in the order channels were added."""
        records: list[TopicRecord] = []
        for channel in self._channels.values():
            try:
                offered = load_profiles(channel.metadata.get('offered_qos_profiles'))
            except BagError:
                offered = ()
            records.append(TopicRecord(channel.topic, channel.msgtype,
                                       channel.serialization_format, offered,
                                       channel.metadata.get('topic_type_hash', ''),
                                       channel.count))
        return records


def channel_metadata(offered_qos: Sequence[QosProfile], type_hash: str) -> dict[str, str]:
    """Build an MCAP channel's metadata as rosbag2 Jazzy writes it."""
    return {'offered_qos_profiles': dump_profiles(offered_qos), 'topic_type_hash': type_hash}


class BagWriter:
    """
    A new rosbag2 bag directory ``PATH`` with ``PATH/PATH_0.mcap`` and metadata.yaml.

    Use as a context manager (or `create` and `close`). Topics are added with `add_topic`
    (standard Jazzy types are described from Jazzy's definitions) and written to with
    `write(channel, log_time_ns, cdr_bytes)`.

    Crash-safe mode (`flush_period_s` set): a write more than `flush_period_s` after the last
    flush flushes (and syncs) the file, so a killed writer loses at most that much of what it
    wrote; `flush()` does it at once. Leaving the context with an exception aborts: the file
    stays as last flushed, without summary, and `repair` completes it.
    """

    def __init__(self, path: PathLike, *, flush_period_s: float | None = None,
                 chunk_size: int = DEFAULT_CHUNK_SIZE,
                 custom_data: Mapping[str, str] | None = None,
                 name: str | None = None) -> None:
        self.path = Path(path)
        # `name`: the bag's name when `path` is a new empty folder that becomes the bag under
        # that name once complete (fileio.atomic_directory); its files are named after it
        self.name = name
        self.custom_data = dict(custom_data or {})
        self.chunk_size = int(chunk_size)
        if flush_period_s is not None and not flush_period_s > 0:
            raise BagError(f'flush period must be positive, got {flush_period_s}')
        self.flush_period_s = flush_period_s
        self._last_flush = time.monotonic()
        self._unflushed = False
        self._file: McapFileWriter | None = None
        self.closed = False

    @property
    def file_path(self) -> Path:
        """Return the MCAP file inside the bag directory, named as rosbag2 names it."""
        return self.path / f'{self.name or self.path.name}_0.mcap'

    def create(self) -> BagWriter:
        """Create the directory and the MCAP file; BagError if the bag exists already."""
        if self.name is not None and is_empty_directory(self.path):
            pass                        # the caller's new folder, renamed to the bag later
        elif os.path.lexists(self.path):
            raise OutputError(f'{self.path}: cannot write the bag: it exists already; '
                              'choose a new path')
        try:
            if self.name is None:
                self.path.mkdir(parents=True)
        except OSError as exc:
            raise OutputError(f'{self.path}: cannot write the bag: '
                              f'{exc.strerror or exc}') from None
        self._file = McapFileWriter(self.file_path, chunk_size=self.chunk_size)
        self._file.add_metadata('rosbag2', {'serialized_metadata': self._serialized()})
        return self

    def __enter__(self) -> BagWriter:
        return self.create()

    def __exit__(self, exc_type: object, *exc_info: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _require(self) -> McapFileWriter:
        if self._file is None or self.closed:
            raise BagError(f'{self.path}: bag is not open for writing')
        return self._file

    def add_topic(self, topic: str, msgtype: str, *,
                  offered_qos: Sequence[QosProfile] = (),
                  definition: TypeDefinition | None = None,
                  type_hash: str | None = None) -> int:
        """Add a channel for `topic`; `definition` defaults to Jazzy's (BagError if unknown)."""
        definition = definition or standard_definition(msgtype)
        if definition is None:
            raise BagError(f'{self.path}: no definition of message type {msgtype}')
        return self._require().add_channel(
            topic, msgtype, schema_encoding=definition.encoding,
            schema_data=definition.text.encode(),
            metadata=channel_metadata(offered_qos, type_hash or definition.type_hash))

    def add_channel(self, topic: str, msgtype: str, *, schema_encoding: str,
                    schema_data: bytes, message_encoding: str = 'cdr',
                    metadata: Mapping[str, str] | None = None) -> int:
        """Add a channel copied as stored elsewhere (repair, conversion of raw messages)."""
        return self._require().add_channel(topic, msgtype, schema_encoding=schema_encoding,
                                           schema_data=schema_data,
                                           message_encoding=message_encoding,
                                           metadata=metadata)

    def write(self, channel: int, log_time_ns: int, data: bytes, *,
              publish_time_ns: int | None = None, sequence: int = 0) -> None:
        """Append one serialized message (CDR) on `channel`."""
        self._require().write(channel, log_time_ns, data, publish_time_ns=publish_time_ns,
                              sequence=sequence)
        self._unflushed = True
        self.flush_if_due()

    def flush_if_due(self) -> bool:
        """Crash-safe mode: flush when unflushed writes are `flush_period_s` old or older."""
        if self.flush_period_s is None or not self._unflushed or self.closed:
            return False
        if time.monotonic() - self._last_flush < self.flush_period_s:
            return False
        self.flush()
        return True

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return self._file.message_count if self._file is not None else 0

    def flush(self) -> None:
        """Everything written so far survives a killed process (see the module docstring)."""
        self._require().flush(sync=True)
        self._last_flush = time.monotonic()
        self._unflushed = False

    def _document(self) -> dict[str, Any]:
        file = self._require()
        return metadata_document([file.file_record(self.file_path.name)],
                                 file.topic_records(), custom_data=self.custom_data)

    def _serialized(self) -> str:
        return yaml.safe_dump(self._document(), sort_keys=False, default_flow_style=False)

    def close(self) -> None:
        """Write the MCAP summary and footer, then metadata.yaml."""
        if self.closed or self._file is None:
            return
        file = self._file
        file.add_metadata('rosbag2', {'serialized_metadata': self._serialized()})
        document = self._document()
        file.finish()
        self.closed = True
        write_metadata_yaml(self.path, document)

    def abort(self) -> None:
        """Close the file without summary or metadata.yaml (`repair` completes it)."""
        if self._file is not None and not self.closed:
            self._file.abort()
        self.closed = True
