"""Bags written by `write_paths_bag` are real rosbag2 MCAP bags, and read back exactly."""
from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
import yaml

from octoroach_model.errors import DataError, OutputError
from octoroach_model.paths import Paths
from octoroach_model.recordings import (
    bag_topics,
    DEFAULT_MARKER_TOPIC,
    DEFAULT_POSE_TOPIC,
    heading_to_quaternion,
    iter_pose_samples,
    load_measured,
    marker_topic,
    MARKER_TYPE,
    POSE_STAMPED,
    pose_topic,
    PoseBagWriter,
    quaternion_to_heading,
    read_runs,
    subject_of,
    TRANSFORM_STAMPED,
    write_paths_bag,
)

RATE_HZ = 50.0


def curved_paths(n_runs: int = 4, duration_s: float = 3.0, seed: int = 0) -> Paths:
    """Smooth runs that start at the origin heading +y and curve a little, each differently."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * RATE_HZ) + 1) / RATE_HZ
    turn_rate = rng.normal(0.0, 0.3, size=(n_runs, 1))
    heading = np.pi / 2 + turn_rate * t + 0.05 * np.sin(2 * np.pi * 2 * t)
    speed = 0.2 + 0.02 * rng.standard_normal((n_runs, 1))
    dt = np.diff(t, prepend=0.0)
    x = np.cumsum(speed * np.cos(heading) * dt, axis=1)
    y = np.cumsum(speed * np.sin(heading) * dt, axis=1)
    return Paths(t, np.stack([x - x[:, :1], y - y[:, :1], heading], axis=-1), {'seed': seed})


@pytest.fixture(scope='module')
def paths() -> Paths:
    return curved_paths()


@pytest.fixture(scope='module')
def bag(tmp_path_factory: pytest.TempPathFactory, paths: Paths) -> Path:
    return write_paths_bag(tmp_path_factory.mktemp('bags') / 'runs', paths)


def test_paths_survive_a_round_trip_through_a_bag(bag: Path, paths: Paths) -> None:
    run_set = read_runs(bag)
    back = run_set.to_paths(rate_hz=RATE_HZ)
    assert len(run_set.runs) == paths.n_paths
    np.testing.assert_allclose(back.t, paths.t, atol=1e-12)
    np.testing.assert_allclose(back.poses, paths.poses, atol=1e-9, rtol=0)


def test_runs_start_at_their_first_sample_one_second_apart_or_more(bag: Path) -> None:
    runs = read_runs(bag).runs
    assert all(run.t[0] == 0.0 for run in runs)
    starts = np.array([run.start_stamp_s for run in runs])
    ends = starts + np.array([run.duration_s for run in runs])
    assert np.all(starts[1:] - ends[:-1] >= 1.0 - 1e-9)
    assert runs[0].source.endswith(f'{DEFAULT_POSE_TOPIC} run 0')


def test_markers_split_runs_even_when_the_gaps_are_ignored(bag: Path, paths: Paths) -> None:
    by_markers = read_runs(bag, gap_s=30.0)
    by_gaps = read_runs(bag, gap_s=30.0, use_markers=False)
    assert len(by_markers.runs) == paths.n_paths
    assert len(by_gaps.runs) == 1
    assert any(f'split by run markers on {DEFAULT_MARKER_TOPIC}' in note
               for note in by_markers.notes)


def test_a_bag_without_markers_is_split_by_gaps(tmp_path: Path, paths: Paths) -> None:
    bag = write_paths_bag(tmp_path / 'no_markers', paths, marker_topic=None)
    assert set(bag_topics(bag)) == {DEFAULT_POSE_TOPIC}
    run_set = read_runs(bag)
    assert len(run_set.runs) == paths.n_paths
    assert any('split by gaps longer than 0.5 s' in note for note in run_set.notes)
    np.testing.assert_allclose(run_set.to_paths().poses, paths.poses, atol=1e-9, rtol=0)


def test_rosbags_reader_reads_the_bag(bag: Path, paths: Paths) -> None:
    n_samples = paths.n_paths * len(paths.t)
    with Reader(bag) as reader:
        types = {connection.topic: connection.msgtype for connection in reader.connections}
        counts = {connection.topic: connection.msgcount for connection in reader.connections}
        assert types == {DEFAULT_POSE_TOPIC: TRANSFORM_STAMPED, DEFAULT_MARKER_TOPIC: MARKER_TYPE}
        assert counts == {DEFAULT_POSE_TOPIC: n_samples, DEFAULT_MARKER_TOPIC: paths.n_paths}
        assert sum(1 for _ in reader.messages()) == n_samples + paths.n_paths
        assert all(connection.digest.startswith('RIHS01_') for connection in reader.connections)
        assert all(connection.ext.offered_qos_profiles for connection in reader.connections)


def test_mcap_reader_decodes_the_bag_with_its_message_definitions(bag: Path,
                                                                  paths: Paths) -> None:
    counts: dict[str, int] = {}
    with (bag / 'runs_0.mcap').open('rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schema_names = {schema.name for schema in summary.schemas.values()}
        assert schema_names == {TRANSFORM_STAMPED, MARKER_TYPE}
        first_pose = None
        for _, channel, _, message in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if first_pose is None and channel.topic == DEFAULT_POSE_TOPIC:
                first_pose = message
    assert counts == {DEFAULT_POSE_TOPIC: paths.n_paths * len(paths.t),
                      DEFAULT_MARKER_TOPIC: paths.n_paths}
    assert first_pose.header.frame_id == 'vicon/world'
    assert first_pose.child_frame_id == 'vicon/octoroach/octoroach'


def test_metadata_yaml_counts_every_message(bag: Path, paths: Paths) -> None:
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['storage_identifier'] == 'mcap'
    assert info['message_count'] == paths.n_paths * (len(paths.t) + 1)
    by_topic = {entry['topic_metadata']['name']: entry['message_count']
                for entry in info['topics_with_message_count']}
    assert by_topic[DEFAULT_POSE_TOPIC] == paths.n_paths * len(paths.t)


def test_poses_follow_the_vicon_bridge_convention(bag: Path, paths: Paths) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        connection = next(c for c in reader.connections if c.topic == DEFAULT_POSE_TOPIC)
        _, stamp_ns, data = next(reader.messages(connections=[connection]))
    message = store.deserialize_cdr(data, TRANSFORM_STAMPED)
    rotation, translation = message.transform.rotation, message.transform.translation
    assert message.header.stamp.sec * 10**9 + message.header.stamp.nanosec == stamp_ns
    assert translation.z == 0.0 and rotation.x == 0.0 and rotation.y == 0.0
    assert rotation.z ** 2 + rotation.w ** 2 == pytest.approx(1.0)
    assert 2 * np.arctan2(rotation.z, rotation.w) == pytest.approx(paths.poses[0, 0, 2])


def test_each_run_has_one_marker_just_before_its_first_pose(bag: Path, paths: Paths) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        messages = [(c.topic, t, d) for c, t, d in reader.messages()]
    marker_positions = [i for i, (topic, _, _) in enumerate(messages)
                        if topic == DEFAULT_MARKER_TOPIC]
    assert len(marker_positions) == paths.n_paths
    for run_index, position in enumerate(marker_positions):
        _, marker_time, data = messages[position]
        assert store.deserialize_cdr(data, MARKER_TYPE).data == run_index
        assert messages[position + 1][0] == DEFAULT_POSE_TOPIC
        assert messages[position + 1][1] == marker_time


def test_pose_stamped_bags_are_read_like_transform_stamped(tmp_path: Path,
                                                           paths: Paths) -> None:
    bag = write_paths_bag(tmp_path / 'pose_stamped', paths, message_type=POSE_STAMPED)
    assert bag_topics(bag)[DEFAULT_POSE_TOPIC].msgtype == POSE_STAMPED
    np.testing.assert_allclose(read_runs(bag).to_paths().poses, paths.poses, atol=1e-9)


def test_a_bare_mcap_file_is_accepted(bag: Path, paths: Paths) -> None:
    run_set = read_runs(bag / 'runs_0.mcap')
    assert len(run_set.runs) == paths.n_paths


def test_several_bags_in_one_call_give_all_their_runs(tmp_path: Path, paths: Paths) -> None:
    first = write_paths_bag(tmp_path / 'first', paths)
    second = write_paths_bag(tmp_path / 'second', paths.subset(slice(0, 2)), marker_topic=None)
    run_set = read_runs([first, second / 'second_0.mcap'])
    assert len(run_set.runs) == paths.n_paths + 2
    assert run_set.runs[-1].source.startswith(str(second / 'second_0.mcap'))


def test_a_folder_of_bags_and_data_sets_expands_to_all_of_them(tmp_path: Path,
                                                               paths: Paths) -> None:
    write_paths_bag(tmp_path / 'bags' / 'a', paths)
    write_paths_bag(tmp_path / 'bags' / 'nested' / 'b', paths.subset([0]))
    (tmp_path / 'bags' / 'README.md').write_text('not a bag')
    assert len(read_runs(tmp_path / 'bags').runs) == paths.n_paths + 1
    assert load_measured(tmp_path / 'bags').n_paths == paths.n_paths + 1


def test_a_bag_with_two_subjects_gives_one_stream_per_subject(tmp_path: Path,
                                                              paths: Paths) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    writer = Writer(tmp_path / 'two', version=9, storage_plugin=StoragePlugin.MCAP)
    with writer:
        connections = {name: writer.add_connection(pose_topic(name), POSE_STAMPED,
                                                   typestore=store) for name in ('ant', 'bee')}
        for k in range(100):
            for offset, name in enumerate(connections):
                stamp_ns = 10**18 + k * 20_000_000
                message = types[POSE_STAMPED](
                    header=types['std_msgs/msg/Header'](
                        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // 10**9,
                                                                   nanosec=stamp_ns % 10**9),
                        frame_id='vicon/world'),
                    pose=types['geometry_msgs/msg/Pose'](
                        position=types['geometry_msgs/msg/Point'](x=float(offset), y=0.01 * k,
                                                                  z=0.0),
                        orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0,
                                                                          w=1.0)))
                writer.write(connections[name], stamp_ns,
                             store.serialize_cdr(message, POSE_STAMPED))
    runs = read_runs(tmp_path / 'two').runs
    assert [run.source.split()[-3] for run in runs] == ['/vicon/ant/ant', '/vicon/bee/bee']
    assert [run.poses[0, 0] for run in runs] == [0.0, 1.0]


def test_a_zero_header_stamp_falls_back_to_the_log_time(tmp_path: Path) -> None:
    log_times = 10**18 + np.arange(50) * 20_000_000
    with PoseBagWriter(tmp_path / 'zero', marker_topic=None) as writer:
        writer.write_poses(np.zeros(50, dtype=np.int64), np.zeros((50, 3)),
                           log_time_ns=log_times)
    (run,) = read_runs(tmp_path / 'zero').runs
    np.testing.assert_allclose(run.t, (log_times - log_times[0]) / 1e9)


def test_samples_stream_in_chunks_and_each_stream_ends_with_a_last_chunk(
        bag: Path, paths: Paths) -> None:
    notes: list[str] = []
    chunks = list(iter_pose_samples(bag, notes=notes, chunk_size=100))
    assert [chunk.is_last for chunk in chunks].count(True) == 1 and chunks[-1].is_last
    assert max(len(chunk.x) for chunk in chunks) == 100
    assert sum(len(chunk.x) for chunk in chunks) == paths.n_paths * len(paths.t)
    assert sum(len(chunk.marker_value) for chunk in chunks) == paths.n_paths
    stamps = np.concatenate([chunk.stamp_s for chunk in chunks])
    assert np.all(np.diff(stamps) > 0)
    assert {chunk.topic for chunk in chunks} == {DEFAULT_POSE_TOPIC}
    assert [note for note in notes if ': clock: ' not in note] == []  # a clean bag: its clock
    assert 'clock: header stamps (equal to the log times), 50 Hz' in notes[0]


def test_writing_over_an_existing_bag_is_refused(bag: Path, paths: Paths) -> None:
    with pytest.raises(OutputError, match=r'runs: cannot write the bag: .*exists already'):
        write_paths_bag(bag, paths)


def test_runs_closer_than_one_second_are_refused(tmp_path: Path, paths: Paths) -> None:
    with pytest.raises(DataError, match=r'gap between runs must be at least 1 s'):
        write_paths_bag(tmp_path / 'tight', paths, gap_s=0.5)


def test_heading_and_quaternion_convert_both_ways() -> None:
    headings = np.linspace(-3.0, 3.0, 13)
    qx, qy, qz, qw = heading_to_quaternion(headings)
    np.testing.assert_allclose(qx**2 + qy**2 + qz**2 + qw**2, 1.0)
    np.testing.assert_allclose(quaternion_to_heading(qx, qy, qz, qw), headings, atol=1e-12)
    np.testing.assert_allclose(quaternion_to_heading(0, 0, 2 * qz, 2 * qw), headings, atol=1e-12)
    assert np.isnan(quaternion_to_heading(0.0, 0.0, 0.0, 0.0))
    assert np.isnan(quaternion_to_heading(np.nan, 0.0, 0.0, 1.0))


def test_topic_helpers_follow_the_subject_naming() -> None:
    assert pose_topic('octoroach') == DEFAULT_POSE_TOPIC
    assert marker_topic('octoroach') == DEFAULT_MARKER_TOPIC
    assert subject_of('/vicon/ant/ant') == 'ant'
    assert subject_of('/robot/pose') is None
