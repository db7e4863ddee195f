"""
Repair: a bag left by a killed recorder made complete, every surviving message kept.

A recorder killed with SIGKILL (or a full disk, a power cut) leaves MCAP files without
summary, index or footer, cut at some byte, and no metadata.yaml; ``ros2 bag info``, rosbags
and most tools refuse it. `repair_bag` reads each file up to its damage (`BagReader`'s walk),
writes its messages, schemas and channels (with their QoS and type-hash metadata) into a new,
complete MCAP file with `McapFileWriter`, and writes metadata.yaml, the way ``ros2 bag
reindex`` would.

Nothing is overwritten without being kept: in place, each damaged file is renamed to
``NAME.mcap.damaged`` (and an old metadata.yaml to ``metadata.yaml.damaged``) before the
repaired one takes its name; with `out`, the input is not touched at all and the new bag is
written into a temporary folder that takes the name `out` when it is complete. A repair that
is killed can be run again: in place, the ``NAME.mcap.partial`` files it left are removed
(never followed) and a renamed original gets its name back first.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import os
from pathlib import Path
from typing import NamedTuple

from mcap.records import Channel, Message, Schema

from octoroach_model.errors import BagError, OutputError
from octoroach_model.fileio import atomic_directory, PARTIAL_SUFFIX
from octoroach_model.recordings.bagio.bag_files import (
    bag_files,
    BagFiles,
    METADATA_FILE,
    PathLike,
    ROS1_SUFFIX,
    Storage,
)
from octoroach_model.recordings.bagio.qos import load_profiles
from octoroach_model.recordings.bagio.reader import FileDamage, iter_mcap_records, TRUNCATION_KEY
from octoroach_model.recordings.bagio.writer import (
    FileRecord,
    McapFileWriter,
    metadata_document,
    TopicRecord,
    write_metadata_yaml,
)
from octoroach_model.safe_yaml import load_yaml_file

DAMAGED_SUFFIX = '.damaged'


class RepairedFile(NamedTuple):
    """One storage file: its name in the bag, messages kept, what was wrong, the kept copy."""

    name: str
    messages: int
    damage: str
    kept: str  # path of the damaged original kept beside it ('' if untouched)


class RepairReport(NamedTuple):
    """What `repair_bag` did; `repaired` is False when the bag was complete already."""

    bag: Path
    files: tuple[RepairedFile, ...]
    messages: int
    repaired: bool
    notes: tuple[str, ...]


@dataclass
class _FileScan:
    """Channels, counts and times of one file, from a walk or from its copy."""

    record: FileRecord
    topics: dict[int, TopicRecord] = field(default_factory=dict)


def repair_bag(source: PathLike, out: PathLike | None = None) -> RepairReport:
    """
    Make the bag at `source` complete (in place) or write a complete copy to `out`.

    `source`: a rosbag2 MCAP bag directory or a bare .mcap file. A bare file without `out`
    is repaired into a new bag directory named after it (``x.mcap`` -> ``x/``).
    """
    path = Path(source)
    if path.is_file() and path.suffix == ROS1_SUFFIX:
        raise BagError(f'{path}: a ROS 1 bag; `rosbag reindex` repairs those')
    undone: list[str] = []
    if out is None and path.is_dir():
        _undo_killed_repair(path, undone)   # a repair killed here: start from the bag as it was
    bag = bag_files(path)
    if bag.storage is not Storage.MCAP:
        raise BagError(f'{path}: a {bag.storage} bag; `ros2 bag reindex` repairs those')
    notes = list(bag.notes) + undone
    in_place = out is None and bag.directory is not None
    target = Path(out) if out is not None else (
        bag.directory if bag.directory is not None else path.with_suffix(''))
    if not in_place and os.path.lexists(target):
        raise OutputError(f'{target}: exists already; choose a new output path')
    if not in_place:
        with atomic_directory(target, what='repaired bag') as folder:
            report = _repair(bag, folder, target.name, in_place, notes)
        return report._replace(bag=target)
    return _repair(bag, target, target.name, in_place, notes)


def _undo_killed_repair(directory: Path, notes: list[str]) -> bool:
    """
    Undo what a repair killed in place left: its NAME.mcap.partial files, a kept original.

    A partial copy is removed (a link or anything but a plain file there is refused, never
    followed); a damaged original already renamed to NAME.mcap.damaged while NAME.mcap is
    missing gets its name back. Then the repair starts over. True when anything was undone.
    """
    undone = False
    for partial in sorted(directory.glob('*.mcap' + PARTIAL_SUFFIX)):
        if partial.is_symlink() or not partial.is_file():
            raise OutputError(f'{partial}: not a file a repair left; move it away first')
        partial.unlink()
        original = partial.with_name(partial.name[:-len(PARTIAL_SUFFIX)])
        kept = original.with_name(original.name + DAMAGED_SUFFIX)
        if not os.path.lexists(original) and kept.is_file() and not kept.is_symlink():
            kept.replace(original)
        notes.append(f'{partial}: left by a repair that was stopped; removed, the repair '
                     'started over')
        undone = True
    return undone


def _repair(bag: BagFiles, target: Path, name_stem: str, in_place: bool,
            notes: list[str]) -> RepairReport:
    """Repair `bag`'s files into `target` (the bag itself in place); see `repair_bag`."""
    scans = [_scan(file) for file in bag.files]
    complete = all(scan[1].complete for scan in scans)
    if in_place and complete and (target / METADATA_FILE).is_file():
        total = sum(scan[1].messages for scan in scans)
        files = tuple(RepairedFile(file.name, report.messages, '', '')
                      for file, (_, report) in zip(bag.files, scans))
        return RepairReport(target, files, total, False, tuple(notes + [
            f'{target}: complete already (every file has its footer, metadata.yaml is there)']))
    custom_data = _custom_data(bag.directory)
    results: list[RepairedFile] = []
    file_records: list[FileRecord] = []
    topics: dict[str, TopicRecord] = {}
    for index, (file, (scan, report)) in enumerate(zip(bag.files, scans)):
        name = file.name if in_place else f'{name_stem}_{index}.mcap'
        damage = f'truncated MCAP, {report.damage}' if report.damage else ''
        if report.unreadable_chunks:
            damage = '; '.join(filter(None, [damage, f'{report.unreadable_chunks} unreadable '
                                                     'chunk(s) skipped']))
        if in_place and report.complete and not report.unreadable_chunks:
            copy, kept = scan, ''
        else:
            copy = _rewrite(file, target / (name + '.partial'))
            kept = _swap(file, target / name) if in_place else ''
            if not in_place:
                (target / (name + '.partial')).replace(target / name)
        results.append(RepairedFile(name, copy.record.message_count, damage, kept))
        file_records.append(replace(copy.record, path=name))
        for topic in copy.topics.values():
            _merge_topic(topics, topic)
    cuts = [f'{file.name}: {file.damage}' for file in results if file.damage]
    if cuts:
        custom_data = {**(custom_data or {}), TRUNCATION_KEY: '; '.join(cuts)}
    document = metadata_document(file_records, list(topics.values()), custom_data=custom_data)
    old_metadata = target / METADATA_FILE
    if in_place and old_metadata.exists():
        notes.append(f'{old_metadata}: replaced; the old one is kept as {_keep(old_metadata)}')
    write_metadata_yaml(target, document)
    total = sum(record.message_count for record in file_records)
    return RepairReport(target, tuple(results), total, True, tuple(notes))


def _scan(file: Path) -> tuple[_FileScan, FileDamage]:
    """Walk one file: its topics, counts and time range, and what is damaged."""
    report = FileDamage(file)
    topics: dict[int, TopicRecord] = {}
    schemas: dict[int, Schema] = {}
    counts: dict[int, int] = {}
    start, end = None, 0
    channels: dict[int, Channel] = {}
    for record in iter_mcap_records(file, report):
        if isinstance(record, Message):
            counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
            start = record.log_time if start is None else min(start, record.log_time)
            end = max(end, record.log_time)
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Schema):
            schemas[record.id] = record

    for channel_id, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        try:
            offered = load_profiles(channel.metadata.get('offered_qos_profiles'))
        except BagError:
            offered = ()
        topics[channel_id] = TopicRecord(
            channel.topic, schema.name if schema is not None else '',
            channel.message_encoding, offered, channel.metadata.get('topic_type_hash', ''),
            counts.get(channel_id, 0))
    begin = start or 0
    record = FileRecord(file.name, begin, max(0, end - begin), sum(counts.values()))
    return _FileScan(record, topics), report


def _rewrite(source: Path, destination: Path) -> _FileScan:
    """Copy every readable message of `source` into a new complete MCAP file."""
    writer = McapFileWriter(destination)
    try:
        schemas: dict[int, Schema] = {}
        channels: dict[int, int] = {}  # source channel id -> new channel id
        report = FileDamage(source)
        for record in iter_mcap_records(source, report):
            if isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is not None:
                    writer.write(channel, record.log_time, record.data,
                                 publish_time_ns=record.publish_time, sequence=record.sequence)
            elif isinstance(record, Channel) and record.id not in channels:
                schema = schemas.get(record.schema_id)
                channels[record.id] = writer.add_channel(
                    record.topic, schema.name if schema is not None else '',
                    schema_encoding=schema.encoding if schema is not None else '',
                    schema_data=bytes(schema.data) if schema is not None else b'',
                    message_encoding=record.message_encoding, metadata=record.metadata)
            elif isinstance(record, Schema):
                schemas[record.id] = record
        scan = _FileScan(topics=dict(enumerate(writer.topic_records())),
                         record=writer.file_record(destination.name))
        writer.finish(sync=True)
    except BaseException:
        writer.abort()
        destination.unlink(missing_ok=True)
        raise
    return scan


def _keep(path: Path) -> str:
    """Rename `path` to a free ``PATH.damaged[.N]`` name; return the new name."""
    kept = path.with_name(path.name + DAMAGED_SUFFIX)
    number = 1
    while kept.exists():
        kept = path.with_name(f'{path.name}{DAMAGED_SUFFIX}.{number}')
        number += 1
    path.replace(kept)
    return str(kept)


def _swap(original: Path, final: Path) -> str:
    """Keep the damaged original, then give its name to the repaired copy."""
    kept = _keep(original)
    final.with_name(final.name + '.partial').replace(final)
    return kept


def _merge_topic(topics: dict[str, TopicRecord], topic: TopicRecord) -> None:
    old = topics.get(topic.name)
    if old is None:
        topics[topic.name] = topic
    else:
        topics[topic.name] = TopicRecord(old.name, old.msgtype, old.serialization_format,
                                         old.offered_qos or topic.offered_qos,
                                         old.type_hash or topic.type_hash,
                                         old.message_count + topic.message_count)


def _custom_data(directory: Path | None) -> dict[str, str] | None:
    """custom_data of an old metadata.yaml, kept through the repair."""
    if directory is None or not (directory / METADATA_FILE).is_file():
        return None
    try:
        info = load_yaml_file(directory / METADATA_FILE)
        data = info['rosbag2_bagfile_information'].get('custom_data')
    except (BagError, KeyError, TypeError, AttributeError):
        return None
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else None
