"""
Pose messages decoded in blocks over whole MCAP chunks read exactly as message by message.

Every bag here is read twice into pose streams: with the pose topics decoded in blocks
(`recordings.bagio.pose_blocks`, the default) and with every message through rosbags' CDR
deserializer. The chunks (every array bit for bit) and the notes must be the same, for the
package's own bag, bags of other writers and types, bags whose frames change, compressed,
cut and damaged bags, and the reference bag. Where the layout is not fixed (a sequence before
the pose, big-endian CDR) no block is made; where a block decodes wrongly, the check against
rosbags refuses it.
"""
from __future__ import annotations

from collections.abc import Callable
import math
from pathlib import Path
import random

from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import get_types_from_msg, get_typestore, Stores

import octoroach_model as om
from octoroach_model.errors import BagError, DataError
from octoroach_model.recordings import BagReader, ReadOptions, write_paths_bag
from octoroach_model.recordings.bagio.fixed_cdr import FixedLayout
from octoroach_model.recordings.bagio.mcap_records import file_records
from octoroach_model.recordings.bagio.pose_blocks import PoseBlock
from octoroach_model.recordings.poses.bag_streams import iter_bag_pose_chunks

REPO = Path(__file__).resolve().parents[1]
START_NS = 1_700_000_000 * 10**9
CHUNK_SAMPLES = 37  # pose chunks this long, so that blocks straddle their ends
OWN_TYPES = {
    # a lab's type: float32 position, float64 orientation and a fixed array after it
    'lab_msgs/msg/Tracked': 'std_msgs/Header header\nstring body\nuint8 quality\n'
                            'geometry_msgs/Point32 position\n'
                            'geometry_msgs/Quaternion orientation\nfloat64[4] residuals\n',
    # a sequence before the pose: its layout changes from message to message
    'lab_msgs/msg/Cloud': 'std_msgs/Header header\nfloat64[] extra\ngeometry_msgs/Pose pose\n',
}


# -- bags -------------------------------------------------------------------------------------

def _store():
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict = {}
    for name, text in OWN_TYPES.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


class _Builder:
    """Messages of Jazzy's and the lab's types for sample (stamp, x, y, heading)."""

    def __init__(self, store) -> None:
        self.types = store.types

    def header(self, stamp_ns: int, frame: str = 'world'):
        return self.types['std_msgs/msg/Header'](stamp=self.types['builtin_interfaces/msg/Time'](
            sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=frame)

    def quaternion(self, heading: float):
        return self.types['geometry_msgs/msg/Quaternion'](
            x=0.0, y=0.0, z=math.sin(heading / 2), w=math.cos(heading / 2))

    def pose(self, x: float, y: float, heading: float):
        return self.types['geometry_msgs/msg/Pose'](
            position=self.types['geometry_msgs/msg/Point'](x=x, y=y, z=0.01),
            orientation=self.quaternion(heading))

    def transform(self, stamp_ns: int, x: float, y: float, heading: float,
                  child: str = 'vicon/octoroach/octoroach'):
        return self.types['geometry_msgs/msg/TransformStamped'](
            header=self.header(stamp_ns, 'vicon/world'), child_frame_id=child,
            transform=self.types['geometry_msgs/msg/Transform'](
                translation=self.types['geometry_msgs/msg/Vector3'](x=x, y=y, z=0.0),
                rotation=self.quaternion(heading)))


def _samples(runs: int = 3, seed: int = 4):
    """(run, index, stamp ns, x, y, heading) of every sample, runs 4 s apart."""
    paths = om.simulate(runs, seed=seed, cycles=2)
    offsets = np.round(paths.t * 1e9).astype(np.int64)
    for run in range(paths.n_paths):
        for k, offset in enumerate(offsets.tolist()):
            x, y, heading = paths.poses[run, k].tolist()
            yield run, k, START_NS + run * 4 * 10**9 + offset, x, y, heading


def _rosbags_bag(path: Path, pose: Callable, little_endian: bool = True) -> Path:
    """Write a rosbag2 MCAP bag with rosbags: each sample through `pose`, run markers."""
    store = _store()
    build = _Builder(store)
    writer = Ros2Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    connections: dict[str, object] = {}

    def write(topic: str, msgtype: str, stamp: int, message) -> None:
        if topic not in connections:
            connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(connections[topic], stamp,
                     store.serialize_cdr(message, msgtype, little_endian=little_endian))

    with writer:
        for run, k, stamp, x, y, heading in _samples():
            if k == 0:
                write('/octoroach/run_start', 'std_msgs/msg/UInt32', stamp,
                      store.types['std_msgs/msg/UInt32'](data=run))
            for topic, msgtype, message in pose(build, run, k, stamp, x, y, heading):
                write(topic, msgtype, stamp, message)
    return path


def _vicon(build, run, k, stamp, x, y, heading):
    yield ('/vicon/octoroach/octoroach', 'geometry_msgs/msg/TransformStamped',
           build.transform(stamp if k % 9 else 0, x, y, heading))  # some zero stamps


def _pose_stamped(build, run, k, stamp, x, y, heading):
    yield ('/robot/pose', 'geometry_msgs/msg/PoseStamped',
           build.types['geometry_msgs/msg/PoseStamped'](header=build.header(stamp),
                                                        pose=build.pose(x, y, heading)))


def _odometry(build, run, k, stamp, x, y, heading):
    types = build.types
    covariance = np.arange(36, dtype=float) * k
    zero = types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
    yield ('/odom', 'nav_msgs/msg/Odometry', types['nav_msgs/msg/Odometry'](
        header=build.header(stamp, 'odom'), child_frame_id='base_link',
        pose=types['geometry_msgs/msg/PoseWithCovariance'](
            pose=build.pose(x, y, heading), covariance=covariance),
        twist=types['geometry_msgs/msg/TwistWithCovariance'](
            twist=types['geometry_msgs/msg/Twist'](linear=zero, angular=zero),
            covariance=covariance)))


def _own_type(build, run, k, stamp, x, y, heading):
    types = build.types
    yield ('/lab/robot', 'lab_msgs/msg/Tracked', types['lab_msgs/msg/Tracked'](
        header=build.header(stamp), body='robot', quality=k % 256,
        position=types['geometry_msgs/msg/Point32'](x=x, y=y, z=0.02),
        orientation=build.quaternion(heading), residuals=np.full(4, 0.5 * k)))


def _changing_frames(build, run, k, stamp, x, y, heading):
    """Every fifth child frame differs in one letter; the last run's is longer."""
    child = 'vicon/octoroach/octoroach'
    if k % 5 == 4:
        child = 'vicon/octoroach/octoroacX'
    if run == 2:
        child = 'vicon/octoroach/octoroach_2'
    yield ('/vicon/octoroach/octoroach', 'geometry_msgs/msg/TransformStamped',
           build.transform(stamp, x, y, heading, child))


def _sequence(build, run, k, stamp, x, y, heading):
    yield ('/lab/cloud', 'lab_msgs/msg/Cloud', build.types['lab_msgs/msg/Cloud'](
        header=build.header(stamp), extra=np.zeros(k % 3), pose=build.pose(x, y, heading)))


def _two_robots(build, run, k, stamp, x, y, heading):
    """Two VICON subjects, their messages alternating."""
    for subject, shift in (('a', 0.0), ('b', 1.0)):
        yield (f'/vicon/{subject}/{subject}', 'geometry_msgs/msg/TransformStamped',
               build.transform(stamp, x + shift, y, heading, f'vicon/{subject}/{subject}'))


def _copy_mcap(source: Path, target: Path, compression: CompressionType,
               crcs: bool = True) -> Path:
    """Copy a bag's messages into one .mcap file written by mcap's Writer (4 KiB chunks)."""
    reader = BagReader(source)
    reader.topics()
    with target.open('wb') as stream:
        writer = Writer(stream, compression=compression, chunk_size=4096, enable_crcs=crcs)
        writer.start(profile='ros2', library='test')
        channels = {}
        for index, channel in enumerate(reader.channels):
            schema = writer.register_schema(channel.msgtype, channel.schema_encoding,
                                            channel.schema_data)
            channels[index] = writer.register_channel(channel.topic, channel.message_encoding,
                                                      schema, channel.metadata)
        for message in reader.messages():
            writer.add_message(channels[message.channel], message.log_time_ns, message.data,
                               message.publish_time_ns)
        writer.finish()
    return target


def _cut(source: Path, target: Path, fraction: float) -> Path:
    data = source.read_bytes()
    target.write_bytes(data[:int(fraction * len(data))])
    return target


BAGS: dict[str, Callable[[Path], Path]] = {
    'the package bag': lambda folder: write_paths_bag(folder / 'bag', om.simulate(
        3, seed=5, cycles=2)),
    'TransformStamped with zero stamps': lambda folder: _rosbags_bag(folder / 'b', _vicon),
    'PoseStamped': lambda folder: _rosbags_bag(folder / 'b', _pose_stamped),
    'Odometry': lambda folder: _rosbags_bag(folder / 'b', _odometry),
    "a lab's own type": lambda folder: _rosbags_bag(folder / 'b', _own_type),
    'frames that change': lambda folder: _rosbags_bag(folder / 'b', _changing_frames),
    'two robots interleaved': lambda folder: _rosbags_bag(folder / 'b', _two_robots),
    'zstd chunks': lambda folder: _copy_mcap(BAGS['the package bag'](folder), folder / 'z.mcap',
                                             CompressionType.ZSTD),
    'lz4 chunks': lambda folder: _copy_mcap(BAGS['the package bag'](folder), folder / 'l.mcap',
                                            CompressionType.LZ4),
    'cut': lambda folder: _cut(_copy_mcap(BAGS['the package bag'](folder), folder / 'p.mcap',
                                          CompressionType.NONE), folder / 'cut.mcap', 0.6),
    'a sequence before the pose': lambda folder: _rosbags_bag(folder / 'b', _sequence),
    'big-endian CDR': lambda folder: _rosbags_bag(folder / 'b', _vicon, little_endian=False),
}
WITHOUT_BLOCKS = ('a sequence before the pose', 'big-endian CDR')


# -- reading both ways ----------------------------------------------------------------------

def read(path: Path, blocks: bool) -> tuple[list, list[str]] | str:
    """Pose chunks and notes of a bag, or the one-line error it ends in."""
    notes: list[str] = []
    try:
        chunks = list(iter_bag_pose_chunks(path, ReadOptions(), notes, CHUNK_SAMPLES,
                                           blocks=blocks))
    except (BagError, DataError) as error:
        return f'{type(error).__name__}: {error}'
    return chunks, notes


def assert_same(new: tuple[list, list[str]] | str, old: tuple[list, list[str]] | str) -> None:
    """Check two readings: the same error, or the same notes and chunks bit for bit."""
    if isinstance(new, str) or isinstance(old, str):
        assert new == old
        return
    (chunks, notes), (old_chunks, old_notes) = new, old
    assert notes == old_notes
    assert len(chunks) == len(old_chunks)
    for chunk, old_chunk in zip(chunks, old_chunks):
        for name in chunk._fields:
            value, expected = getattr(chunk, name), getattr(old_chunk, name)
            if isinstance(value, np.ndarray):
                assert value.dtype == expected.dtype and value.shape == expected.shape, name
                assert value.tobytes() == expected.tobytes(), name
            elif not (isinstance(value, float) and math.isnan(value) and math.isnan(expected)):
                assert value == expected, name


def blocks_read(path: Path) -> int:
    """Count the messages of a bag's pose topics that came decoded in blocks."""
    reader = BagReader(path)
    topics = reader.topics()
    from octoroach_model.recordings.poses.bag_streams import choose_streams

    plan = choose_streams(reader, topics, ReadOptions())
    return sum(len(item) for item in reader.pose_messages(list(plan.pose_topics),
                                                          plan.pose_topics)
               if isinstance(item, PoseBlock))


@pytest.mark.parametrize('kind', list(BAGS))
def test_blocks_read_every_bag_as_message_by_message(tmp_path: Path, kind: str) -> None:
    path = BAGS[kind](tmp_path)
    new = read(path, blocks=True)
    assert not isinstance(new, str), new
    assert_same(new, read(path, blocks=False))
    decoded = blocks_read(path)
    if kind in WITHOUT_BLOCKS:
        assert decoded == 0
    else:
        poses = sum(len(chunk.x) for chunk in new[0])
        assert decoded >= 0.5 * poses, (decoded, poses)


def test_the_reference_bag_reads_the_same_both_ways() -> None:
    assert_same(read(REPO / 'bags' / 'reference', blocks=True),
                read(REPO / 'bags' / 'reference', blocks=False))


def test_a_block_that_decodes_wrongly_is_refused_by_the_check(tmp_path: Path,
                                                              monkeypatch) -> None:
    """Every chunk's last decoded message is checked against rosbags: a wrong one is caught."""
    path = BAGS['the package bag'](tmp_path)
    expected = read(path, blocks=False)
    decode = FixedLayout.decode

    def wrong(self, records):
        arrays = decode(self, records)
        if len(records) > 1:           # the template (one record) still decodes right
            arrays.values[-1, 0] = np.nextafter(arrays.values[-1, 0], np.inf)
        return arrays

    monkeypatch.setattr(FixedLayout, 'decode', wrong)
    assert_same(read(path, blocks=True), expected)
    assert blocks_read(path) == 0


def test_mutated_chunks_read_the_same_both_ways(tmp_path: Path) -> None:
    """Bytes changed inside chunks without checksums reach the block walker: same result."""
    source = _copy_mcap(BAGS['the package bag'](tmp_path), tmp_path / 'plain.mcap',
                        CompressionType.NONE, crcs=False)
    data = source.read_bytes()
    with source.open('rb') as stream:
        records = StreamReader(stream, emit_chunks=True).records
        spans = []
        for record in records:
            if isinstance(record, Chunk):
                spans.append((stream.tell() - len(record.data), stream.tell()))
    rng = random.Random(7)
    for number in range(30):
        out = bytearray(data)
        start, end = rng.choice(spans)
        for _ in range(rng.randint(1, 6)):
            where = rng.randrange(start, end)
            out[where] = rng.choice([0, 5, 0xff, rng.randrange(256)])
        mutant = tmp_path / f'mutant_{number}.mcap'
        mutant.write_bytes(bytes(out))
        assert_same(read(mutant, blocks=True), read(mutant, blocks=False))


def test_the_file_walk_gives_the_records_mcap_s_stream_reader_gives(tmp_path: Path) -> None:
    """Check the walk against StreamReader, less the index records it skips unparsed."""
    bag = BAGS['the package bag'](tmp_path)
    kept = (Schema, Channel, Metadata, Message, Chunk, DataEnd, Footer)
    for path in (next(bag.glob('*.mcap')),
                 _copy_mcap(bag, tmp_path / 'z.mcap', CompressionType.ZSTD)):
        with path.open('rb') as stream:
            expected = [record for record in StreamReader(stream, emit_chunks=True).records
                        if isinstance(record, kept)]
        with path.open('rb') as stream:
            walked = []
            for record in file_records(stream, path.stat().st_size):
                walked.append(record)
                if isinstance(record, Footer):
                    break
        assert walked == expected
