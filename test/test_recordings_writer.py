"""
The one writer writes bags as rosbag2 Jazzy does, and its crash-safe mode keeps what it flushed.

Each bag is checked with readers other than ours: rosbags' rosbag2 Reader, mcap's indexed
reader with mcap-ros2-support's decoder, and plain YAML.
"""
from __future__ import annotations

from pathlib import Path
import shutil
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
import yaml

from octoroach_model import simulate
from octoroach_model.errors import DataError, OutputError
from octoroach_model.recordings import (
    BagReader,
    BagWriter,
    DEFAULT_POSE_TOPIC,
    PoseBagWriter,
    QosOverride,
    QosProfile,
    replay_profile,
    write_paths_bag,
)
from octoroach_model.recordings.bagio.qos import dump_profiles, INFINITE_NS, load_profiles

# RIHS01 of geometry_msgs/msg/TransformStamped, as rclpy reports it on Jazzy
TRANSFORM_HASH = 'RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206'
INFINITE = {'sec': 9223372036, 'nsec': 854775807}  # RMW_DURATION_INFINITE as rosbag2 writes it


@pytest.fixture(scope='module')
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_paths_bag(tmp_path_factory.mktemp('writer') / 'runs', simulate(3, seed=4,
                                                                                cycles=2))


def metadata(bag: Path) -> dict:
    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def test_metadata_yaml_is_jazzys_version_9(bag: Path) -> None:
    info = metadata(bag)
    assert info['version'] == 9 and info['ros_distro'] == 'jazzy'
    assert info['storage_identifier'] == 'mcap'
    assert info['relative_file_paths'] == ['runs_0.mcap']
    assert info['files'][0]['path'] == 'runs_0.mcap'
    assert info['files'][0]['message_count'] == info['message_count'] == 3 * 51 + 3
    topic = next(entry['topic_metadata'] for entry in info['topics_with_message_count']
                 if entry['topic_metadata']['name'] == DEFAULT_POSE_TOPIC)
    assert topic['type_description_hash'] == TRANSFORM_HASH
    (profile,) = topic['offered_qos_profiles']  # a list, not YAML text (version 9)
    assert profile['reliability'] == 'reliable' and profile['durability'] == 'volatile'
    assert profile['deadline'] == profile['lifespan'] == INFINITE
    assert profile['liveliness_lease_duration'] == INFINITE


def test_mcap_channels_carry_the_type_hash_and_the_offered_qos(bag: Path) -> None:
    with (bag / 'runs_0.mcap').open('rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        channel = next(c for c in summary.channels.values() if c.topic == DEFAULT_POSE_TOPIC)
        assert channel.metadata['topic_type_hash'] == TRANSFORM_HASH
        (profile,) = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert profile['deadline'] == INFINITE and profile['history'] == 'unknown'
        assert summary.schemas[channel.schema_id].encoding == 'ros2msg'
        records = {m.name: m.metadata for m in reader.iter_metadata()}
        serialized = yaml.safe_load(records['rosbag2']['serialized_metadata'])
        assert serialized['ros_distro'] == 'jazzy' and serialized['message_count'] == 156
        decoded = [message for _, _, _, message in reader.iter_decoded_messages(
            topics=[DEFAULT_POSE_TOPIC])]
    assert len(decoded) == 153 and decoded[0].child_frame_id == 'vicon/octoroach/octoroach'


def test_rosbags_reads_the_qos_and_the_hash(bag: Path) -> None:
    with Reader(bag) as reader:
        assert reader.ros_distro == 'jazzy'
        for connection in reader.connections:
            assert connection.digest.startswith('RIHS01_')
            (qos,) = connection.ext.offered_qos_profiles
            assert qos.reliability == QosReliability.RELIABLE
            assert qos.durability == QosDurability.VOLATILE
            assert (qos.deadline.sec, qos.deadline.nsec) == (9223372036, 854775807)


def test_the_writer_refuses_an_existing_bag_and_negative_times(bag: Path,
                                                               tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=r'runs: cannot write the bag: it exists already'):
        BagWriter(bag).create()
    with pytest.raises(DataError, match=r'negative time stamps'):
        with PoseBagWriter(tmp_path / 'negative') as writer:
            writer.write_poses(np.array([-5]), np.zeros((1, 3)))


def test_a_flushed_bag_survives_its_writer(tmp_path: Path) -> None:
    """What is on disk after a flush (a copy taken while the writer runs) reads back whole."""
    store = get_typestore(Stores.ROS2_JAZZY)
    message = store.types['std_msgs/msg/UInt32']
    writer = BagWriter(tmp_path / 'live', flush_period_s=0.05).create()
    channel = writer.add_topic('/counter', 'std_msgs/msg/UInt32')

    def write(values: range) -> None:
        for value in values:
            writer.write(channel, 10**18 + value,
                         bytes(store.serialize_cdr(message(data=value), 'std_msgs/msg/UInt32')))

    def on_disk(name: str) -> list[int]:
        copy = tmp_path / name
        shutil.copytree(tmp_path / 'live', copy)
        assert not (copy / 'metadata.yaml').exists()
        return [store.deserialize_cdr(m.data, 'std_msgs/msg/UInt32').data
                for m in BagReader(copy).messages()]

    write(range(100))
    writer.flush()
    assert on_disk('after_flush') == list(range(100))
    write(range(100, 110))  # a few bytes: still in the open chunk
    assert on_disk('before_the_period') == list(range(100))
    time.sleep(0.06)
    assert writer.flush_if_due()
    assert on_disk('after_the_period') == list(range(110))
    writer.close()
    assert len(list(BagReader(tmp_path / 'live').messages())) == 110


def test_the_mcap_api_the_bag_layer_relies_on_is_there() -> None:
    """
    Check the public mcap API the reader and the crash-safe writer use.

    Fails on an upgrade that drops it: Writer.flush ends the open chunk; breakup_chunk
    decodes one chunk.
    """
    import io

    from mcap.stream_reader import breakup_chunk, StreamReader
    from mcap.writer import Writer

    stream = io.BytesIO()
    writer = Writer(stream, chunk_size=2**20)
    writer.start(profile='ros2', library='test')
    schema = writer.register_schema('std_msgs/msg/UInt32', 'ros2msg', b'uint32 data')
    channel = writer.register_channel('/a', 'cdr', schema)
    writer.add_message(channel, 1, b'\x00\x01\x00\x00\x07\x00\x00\x00', 1)
    before = stream.tell()
    writer.flush()
    assert stream.tell() > before  # the open chunk is on the stream now
    writer.finish()
    stream.seek(0)
    chunks = [r for r in StreamReader(stream, emit_chunks=True).records
              if type(r).__name__ == 'Chunk']
    assert [type(r).__name__ for r in breakup_chunk(chunks[0], validate_crc=True)] == [
        'Schema', 'Channel', 'Message']


# --- QoS profiles


def test_qos_profiles_round_trip_through_rosbag2_yaml() -> None:
    profiles = (QosProfile(reliability='best_effort', depth=5, deadline_ns=1_500_000_000),
                QosProfile(history='unknown', depth=0, durability='transient_local'))
    assert load_profiles(dump_profiles(profiles)) == profiles
    assert yaml.safe_load(dump_profiles(profiles))[0]['deadline'] == {'sec': 1,
                                                                      'nsec': 500000000}


def test_foxy_infinities_and_numbered_policies_are_read_as_rosbag2_reads_them() -> None:
    foxy = {'history': 1, 'depth': 10, 'reliability': 2, 'durability': 1,
            'deadline': {'sec': 2147483647, 'nsec': 4294967295},
            'lifespan': {'sec': 2147483647, 'nsec': 2147483647},
            'liveliness': 1, 'liveliness_lease_duration': {'sec': 0, 'nsec': 0},
            'avoid_ros_namespace_conventions': False}
    (profile,) = load_profiles(yaml.safe_dump([foxy]))
    assert profile.reliability == 'best_effort' and profile.durability == 'transient_local'
    assert profile.deadline_ns == profile.lifespan_ns == INFINITE_NS
    assert profile.liveliness_lease_duration_ns == 0
    assert profile.to_rosbag2()['deadline'] == INFINITE


def test_replay_offers_what_the_publishers_offered() -> None:
    reliable, best_effort = QosProfile(history='unknown', depth=0), \
        QosProfile(reliability='best_effort', depth=7)
    chosen, note = replay_profile([best_effort])
    assert (chosen.reliability, chosen.durability, chosen.depth) == ('best_effort', 'volatile',
                                                                     7)
    assert not note
    chosen, note = replay_profile([reliable], fallback_depth=1000)
    assert (chosen.reliability, chosen.depth) == ('reliable', 1000)
    chosen, note = replay_profile([reliable, best_effort])
    assert chosen.reliability == 'best_effort' and 'reliable' in note
    latched = QosProfile(durability='transient_local', depth=1)
    assert replay_profile([latched])[0].durability == 'transient_local'
    assert replay_profile([latched, reliable])[0].durability == 'volatile'
    forced, _ = replay_profile([best_effort], QosOverride('reliable', 'transient_local', 3))
    assert (forced.reliability, forced.durability, forced.depth) == (
        'reliable', 'transient_local', 3)
