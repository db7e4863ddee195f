"""
Every bag format is read into the same runs as the package's own TransformStamped bag.

The same runs are written by independent writers (rosbags' ROS 1 writer, its rosbag2 sqlite3
and MCAP writers) as TransformStamped on the VICON topic, as TFMessage on /tf, as Odometry
and as a lab's own message type known only from the bag's embedded definition; each must read
back (and convert) to the reference runs within 1e-6 m / 1e-6 rad.
"""
from __future__ import annotations

from collections.abc import Callable
import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import get_types_from_msg, get_typestore, Stores

from octoroach_model.cli import convert_main, validate_main
from octoroach_model.errors import BagError
from octoroach_model.paths import Paths
from octoroach_model.recordings import (
    bag_topics,
    DEFAULT_MARKER_TOPIC,
    DEFAULT_POSE_TOPIC,
    iter_pose_samples,
    load_measured,
    read_runs,
    ReadOptions,
    write_paths_bag,
)
from octoroach_model.recordings.mocap import c3d_file
from octoroach_model.recordings.standard_bag.from_inputs import convert_to_bag

RATE_HZ = 50.0
START_NS = 1_700_000_000 * 10**9
PERIOD_NS = 4 * 10**9  # one run every 4 s: 2 s of poses, 2 s of silence
ROBOT = 'vicon/octoroach/octoroach'
CUSTOM_TYPE = 'lab_msgs/msg/RigidBody'
CUSTOM_DEFINITION = """std_msgs/Header header
string name
uint32 quality
geometry_msgs/Pose pose
"""


def turning_paths(n_runs: int = 4, seed: int = 7) -> Paths:
    """Make runs that cross heading +-pi (so every reader must unwrap), each different."""
    rng = np.random.default_rng(seed)
    print(f'turning_paths seed {seed}')
    t = np.arange(int(2.0 * RATE_HZ) + 1) / RATE_HZ
    rate = rng.uniform(0.5, 1.5, size=(n_runs, 1))
    heading = 2.8 + rate * t  # from 2.8 rad well past pi
    speed = 0.15 + 0.05 * rng.random((n_runs, 1))
    x = np.cumsum(speed * np.cos(heading), axis=1) / RATE_HZ + rng.normal(0, 0.1, (n_runs, 1))
    y = np.cumsum(speed * np.sin(heading), axis=1) / RATE_HZ
    return Paths(t, np.stack([x, y, heading], axis=-1))


def samples(paths: Paths):
    """(run index, stamp ns, x, y, heading) of every sample, runs PERIOD_NS apart."""
    offsets = np.round(paths.t * 1e9).astype(np.int64)
    for run in range(paths.n_paths):
        for k, offset in enumerate(offsets):
            x, y, heading = paths.poses[run, k]
            yield run, k, START_NS + run * PERIOD_NS + int(offset), x, y, heading


class Messages:
    """Builds messages of one typestore (ROS 1 headers carry a seq, ROS 2 ones do not)."""

    def __init__(self, store) -> None:
        self.store = store
        self.types = store.types

    def header(self, stamp_ns: int, frame: str):
        fields = {'stamp': self.types['builtin_interfaces/msg/Time'](
            sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), 'frame_id': frame}
        if any(name == 'seq' for name, _ in self.store.fielddefs['std_msgs/msg/Header'][1]):
            fields['seq'] = 0
        return self.types['std_msgs/msg/Header'](**fields)

    def quaternion(self, heading: float):
        return self.types['geometry_msgs/msg/Quaternion'](
            x=0.0, y=0.0, z=math.sin(heading / 2), w=math.cos(heading / 2))

    def pose(self, x: float, y: float, heading: float):
        return self.types['geometry_msgs/msg/Pose'](
            position=self.types['geometry_msgs/msg/Point'](x=x, y=y, z=0.0),
            orientation=self.quaternion(heading))

    def transform(self, stamp_ns: int, parent: str, child: str, x: float, y: float,
                  heading: float, z: float = 0.0):
        return self.types['geometry_msgs/msg/TransformStamped'](
            header=self.header(stamp_ns, parent), child_frame_id=child,
            transform=self.types['geometry_msgs/msg/Transform'](
                translation=self.types['geometry_msgs/msg/Vector3'](x=x, y=y, z=z),
                rotation=self.quaternion(heading)))

    def tf(self, transforms: list):
        return self.types['tf2_msgs/msg/TFMessage'](transforms=transforms)

    def odometry(self, stamp_ns: int, x: float, y: float, heading: float):
        types = self.types
        covariance = np.zeros(36)
        twist = types['geometry_msgs/msg/Twist'](
            linear=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
            angular=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0))
        return types['nav_msgs/msg/Odometry'](
            header=self.header(stamp_ns, 'odom'), child_frame_id='base_link',
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=self.pose(x, y, heading), covariance=covariance),
            twist=types['geometry_msgs/msg/TwistWithCovariance'](
                twist=twist, covariance=covariance))

    def marker(self, run: int):
        return self.types['std_msgs/msg/UInt32'](data=run)


class Ros2Bag:
    """rosbags' rosbag2 writer (MCAP or sqlite3) with typed connections."""

    def __init__(self, path: Path, storage: StoragePlugin, store) -> None:
        self.writer = Ros2Writer(path, version=9, storage_plugin=storage)
        self.store = store
        self.connections: dict[str, tuple] = {}

    def __enter__(self):
        self.writer.open()
        return self

    def __exit__(self, *exc) -> None:
        self.writer.close()

    def write(self, topic: str, msgtype: str, stamp_ns: int, message, **connection) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(
                topic, msgtype, typestore=self.store, **connection)
        self.writer.write(self.connections[topic], stamp_ns,
                          self.store.serialize_cdr(message, msgtype))


class Ros1Bag(Ros2Bag):
    """rosbags' ROS 1 writer, same interface."""

    def __init__(self, path: Path, store) -> None:
        self.writer = Ros1Writer(path)
        self.store = store
        self.connections = {}

    def write(self, topic: str, msgtype: str, stamp_ns: int, message, **connection) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype,
                                                                 typestore=self.store)
        self.writer.write(self.connections[topic], stamp_ns,
                          self.store.serialize_ros1(message, msgtype))


def write_runs(bag: Ros2Bag, paths: Paths, pose: Callable, markers: bool = True) -> None:
    """Each sample through `pose(bag, stamp, x, y, heading)`, a marker before each run."""
    build = Messages(bag.store)
    for run, k, stamp, x, y, heading in samples(paths):
        if markers and k == 0:
            bag.write(DEFAULT_MARKER_TOPIC, 'std_msgs/msg/UInt32', stamp, build.marker(run))
        pose(bag, build, stamp, x, y, heading)


def vicon_pose(bag, build, stamp, x, y, heading) -> None:
    bag.write(DEFAULT_POSE_TOPIC, 'geometry_msgs/msg/TransformStamped', stamp,
              build.transform(stamp, 'vicon/world', ROBOT, x, y, heading))


def tf_pose(bag, build, stamp, x, y, heading) -> None:
    """Write the robot and a fixed frame on /tf, as mocap drivers broadcast them."""
    bag.write('/tf', 'tf2_msgs/msg/TFMessage', stamp, build.tf([
        build.transform(stamp, 'world', 'vicon/world', 0.0, 0.0, 0.0),
        build.transform(stamp, '/vicon/world', ROBOT, x, y, heading)]))


def odometry_pose(bag, build, stamp, x, y, heading) -> None:
    bag.write('/odom', 'nav_msgs/msg/Odometry', stamp, build.odometry(stamp, x, y, heading))


def custom_pose(bag, build, stamp, x, y, heading) -> None:
    message = build.types[CUSTOM_TYPE](header=build.header(stamp, 'vicon/world'),
                                       name='octoroach', quality=3,
                                       pose=build.pose(x, y, heading))
    bag.write('/mocap/rigid_body', CUSTOM_TYPE, stamp, message)


def jazzy_with_custom_type():
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(CUSTOM_DEFINITION, CUSTOM_TYPE))
    return store


WRITERS = {
    'ros2 sqlite3 TransformStamped': lambda path, paths: _ros2(
        path, paths, StoragePlugin.SQLITE3, vicon_pose),
    'ros2 mcap /tf': lambda path, paths: _ros2(path, paths, StoragePlugin.MCAP, tf_pose),
    'ros2 sqlite3 /tf': lambda path, paths: _ros2(path, paths, StoragePlugin.SQLITE3, tf_pose),
    'ros2 mcap Odometry': lambda path, paths: _ros2(
        path, paths, StoragePlugin.MCAP, odometry_pose),
    'ros2 mcap own type': lambda path, paths: _ros2(
        path, paths, StoragePlugin.MCAP, custom_pose, jazzy_with_custom_type()),
    'ros1 TransformStamped and /tf': lambda path, paths: _ros1(
        path, paths, lambda *a: (vicon_pose(*a), tf_pose(*a))),
    'ros1 /tf only': lambda path, paths: _ros1(path, paths, tf_pose),
}


def _ros2(path: Path, paths: Paths, storage: StoragePlugin, pose: Callable,
          store=None) -> Path:
    with Ros2Bag(path, storage, store or get_typestore(Stores.ROS2_JAZZY)) as bag:
        write_runs(bag, paths, pose)
    return path


def noetic_with_tf() -> object:
    """ROS 1 Noetic's types plus tf2_msgs/TFMessage (rosbags' Noetic store lacks tf2_msgs)."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg('geometry_msgs/TransformStamped[] transforms',
                                      'tf2_msgs/msg/TFMessage'))
    return store


def _ros1(path: Path, paths: Paths, pose: Callable) -> Path:
    path = path.with_suffix('.bag')
    with Ros1Bag(path, noetic_with_tf()) as bag:
        write_runs(bag, paths, pose)
    return path


@pytest.fixture(scope='module')
def truth() -> Paths:
    return turning_paths()


@pytest.fixture(scope='module')
def reference(tmp_path_factory: pytest.TempPathFactory, truth: Paths):
    """Read the runs of the package's own standard bag of `truth`."""
    bag = write_paths_bag(tmp_path_factory.mktemp('reference') / 'reference', truth,
                          gap_s=(PERIOD_NS / 1e9) - float(truth.t[-1]),
                          start_time_ns=START_NS)
    return read_runs(bag)


def assert_same_runs(runs, reference) -> None:
    assert len(runs.runs) == len(reference.runs), runs.notes
    for run, expected in zip(runs.runs, reference.runs):
        np.testing.assert_allclose(run.t, expected.t, atol=1e-9, rtol=0)
        np.testing.assert_allclose(run.poses[:, :2], expected.poses[:, :2], atol=1e-6, rtol=0)
        np.testing.assert_allclose(run.poses[:, 2], expected.poses[:, 2], atol=1e-6, rtol=0)
        assert run.start_stamp_s == pytest.approx(expected.start_stamp_s, abs=1e-6)


def test_the_reference_bag_holds_the_truth(reference, truth: Paths) -> None:
    np.testing.assert_allclose(reference.to_paths().poses, truth.poses, atol=1e-9)


@pytest.mark.parametrize('kind', sorted(WRITERS))
def test_each_format_reads_into_the_reference_runs(tmp_path: Path, kind: str, reference,
                                                   truth: Paths) -> None:
    source = WRITERS[kind](tmp_path / 'input', truth)
    runs = read_runs(source)
    assert_same_runs(runs, reference)
    assert any('split by run markers' in note for note in runs.notes), runs.notes


@pytest.mark.parametrize('kind', sorted(WRITERS))
def test_each_format_converts_into_the_standard_bag(tmp_path: Path, kind: str, reference,
                                                    truth: Paths) -> None:
    source = WRITERS[kind](tmp_path / 'input', truth)
    report = convert_to_bag([source], tmp_path / 'standard')
    assert report.samples == truth.n_paths * len(truth.t) and report.markers == truth.n_paths
    topics = bag_topics(report.bag)
    assert {topic: info.msgtype for topic, info in topics.items()} == {
        DEFAULT_POSE_TOPIC: 'geometry_msgs/msg/TransformStamped',
        DEFAULT_MARKER_TOPIC: 'std_msgs/msg/UInt32'}
    assert_same_runs(read_runs(report.bag), reference)


def test_notes_say_what_was_converted(tmp_path: Path, truth: Paths) -> None:
    notes: list[str] = []
    for kind in ('ros2 mcap /tf', 'ros2 mcap Odometry', 'ros1 /tf only'):
        source = WRITERS[kind](tmp_path / kind.replace(' ', '_').replace('/', ''), truth)
        list(iter_pose_samples(source, notes=notes))
    text = '\n'.join(notes)
    assert f'/tf, child frame {ROBOT} relative to vicon/world' in text
    assert 'poses from /odom [nav_msgs/msg/Odometry], fields pose.pose.position' in text
    assert 'ROS 1 bag' in text


def test_the_vicon_topic_wins_over_tf_in_a_vicon_bridge_bag(tmp_path: Path,
                                                            truth: Paths) -> None:
    source = WRITERS['ros1 TransformStamped and /tf'](tmp_path / 'bridge', truth)
    chunks = list(iter_pose_samples(source))
    assert {chunk.topic for chunk in chunks} == {DEFAULT_POSE_TOPIC}
    by_frame = list(iter_pose_samples(source, options=ReadOptions(frame=ROBOT)))
    assert {chunk.topic for chunk in by_frame} == {f'/tf:{ROBOT}'}


def several_robots(path: Path, truth: Paths) -> Path:
    """Two robots on /tf, the second a shifted copy of the first."""
    def two(bag, build, stamp, x, y, heading):
        bag.write('/tf', 'tf2_msgs/msg/TFMessage', stamp, build.tf([
            build.transform(stamp, 'world', 'robot_a', x, y, heading),
            build.transform(stamp, 'world', 'robot_b', x + 1.0, y, heading)]))

    return _ros2(path, truth, StoragePlugin.MCAP, two)


def test_several_moving_frames_need_a_frame_and_the_error_names_them(
        tmp_path: Path, truth: Paths, reference, capsys: pytest.CaptureFixture) -> None:
    source = several_robots(tmp_path / 'two', truth)
    with pytest.raises(BagError, match=r'several moving frames on /tf '
                                       r'\[tf2_msgs/msg/TFMessage\] \(robot_a at 50 Hz, '
                                       r'robot_b at 50 Hz\); choose one with --frame'):
        read_runs(source)
    assert validate_main([str(source), '--k', '2']) == 1
    err = capsys.readouterr().err
    assert err.startswith('error: validate: ') and err.count('\n') == 1
    assert 'robot_a at 50 Hz, robot_b at 50 Hz' in err and '--frame' in err
    chosen = read_runs(source, options=ReadOptions(frame='robot_b'))
    first = read_runs(source, options=ReadOptions(frame='robot_a'))
    assert_same_runs(first, reference)
    for run, other in zip(chosen.runs, first.runs):
        np.testing.assert_allclose(run.poses[:, 0], other.poses[:, 0] + 1.0, atol=1e-9)
    with pytest.raises(BagError, match=r'no child frame robot_c .*robot_a, robot_b'):
        read_runs(source, options=ReadOptions(frame='robot_c'))


def test_a_frame_fixed_to_the_robot_by_tf_static_is_followed(
        tmp_path: Path, truth: Paths) -> None:
    offset_m, turn = 0.05, math.pi / 2
    store = get_typestore(Stores.ROS2_JAZZY)
    build = Messages(store)
    with Ros2Bag(tmp_path / 'static', StoragePlugin.MCAP, store) as bag:
        bag.write('/tf_static', 'tf2_msgs/msg/TFMessage', START_NS, build.tf([
            build.transform(START_NS, ROBOT, 'base_link', offset_m, 0.0, turn, z=0.02)]))
        write_runs(bag, truth, tf_pose)
    runs = read_runs(tmp_path / 'static', options=ReadOptions(frame='base_link'))
    assert len(runs.runs) == truth.n_paths
    for run, expected in zip(runs.runs, truth.poses):
        x, y, heading = expected.T
        np.testing.assert_allclose(run.poses[:, 0], x + offset_m * np.cos(heading), atol=1e-9)
        np.testing.assert_allclose(run.poses[:, 1], y + offset_m * np.sin(heading), atol=1e-9)
        turned = np.angle(np.exp(1j * (run.poses[:, 2] - heading - turn)))
        np.testing.assert_allclose(turned, 0.0, atol=1e-9)
    assert any('through /tf_static' in note for note in runs.notes)


@pytest.mark.parametrize('axis, offset', [('y', math.pi / 2), ('-x', math.pi),
                                          ('-y', -math.pi / 2)])
def test_the_forward_axis_turns_the_heading(reference, tmp_path: Path, truth: Paths,
                                            axis: str, offset: float) -> None:
    source = WRITERS['ros2 mcap Odometry'](tmp_path / 'odom', truth)
    runs = read_runs(source, options=ReadOptions(forward_axis=axis))
    for run, expected in zip(runs.runs, reference.runs):
        np.testing.assert_allclose(run.poses[:, :2], expected.poses[:, :2], atol=1e-9)
        turned = np.angle(np.exp(1j * (run.poses[:, 2] - expected.poses[:, 2] - offset)))
        np.testing.assert_allclose(turned, 0.0, atol=1e-9)
    assert any(f'forward axis {axis}' in note for note in runs.notes)


def test_a_type_without_a_definition_says_why_it_is_unreadable(tmp_path: Path,
                                                               truth: Paths) -> None:
    store = jazzy_with_custom_type()
    path = tmp_path / 'no_definition'
    with Ros2Bag(path, StoragePlugin.MCAP, store) as bag:
        build = Messages(store)
        bag.write('/mocap/rigid_body', CUSTOM_TYPE, START_NS, build.types[CUSTOM_TYPE](
            header=build.header(START_NS, 'w'), name='x', quality=1, pose=build.pose(0, 0, 0)),
            msgdef='', rihs01='RIHS01_' + '0' * 64)
    with pytest.raises(BagError, match=r'no pose topic .*undecodable types: '
                                       r'lab_msgs/msg/RigidBody'):
        read_runs(path)


def test_a_damaged_ros1_bag_is_one_error_naming_it(tmp_path: Path, truth: Paths) -> None:
    source = WRITERS['ros1 /tf only'](tmp_path / 'old', truth)
    data = source.read_bytes()
    (tmp_path / 'cut.bag').write_bytes(data[:len(data) // 2])  # the index is at the end
    with pytest.raises(BagError, match=r'cut\.bag: unreadable ROS 1 bag'):
        read_runs(tmp_path / 'cut.bag')
    (tmp_path / 'text.bag').write_text('not a bag')
    with pytest.raises(BagError, match=r'text\.bag: not a ROS 1 bag of format 2\.0'):
        read_runs(tmp_path / 'text.bag')


def test_every_reader_accepts_the_formats_directly(tmp_path: Path, truth: Paths) -> None:
    folder = tmp_path / 'lab'
    folder.mkdir()
    WRITERS['ros1 /tf only'](folder / 'old', truth)
    WRITERS['ros2 sqlite3 TransformStamped'](folder / 'sqlite', truth)
    measured = load_measured([folder])
    assert measured.n_paths == 2 * truth.n_paths
    assert len(measured.info['inputs']) == 2


def test_mocap_files_go_to_their_reader(tmp_path: Path) -> None:
    path = tmp_path / 'take.csv'
    path.write_text('Objects\n')
    with pytest.raises(BagError, match='not a Vicon CSV export header'):
        list(iter_pose_samples(path))


def test_c3d_files_without_the_c3d_package_say_it_is_missing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(c3d_file, 'c3d', None)
    path = tmp_path / 'take.c3d'
    path.write_text('Objects\n')
    with pytest.raises(BagError, match='C3D files cannot be read by this installation'):
        list(iter_pose_samples(path))


def test_convert_on_the_command_line_writes_a_bag_and_a_data_set(
        tmp_path: Path, truth: Paths, capsys: pytest.CaptureFixture) -> None:
    import json

    source = WRITERS['ros1 /tf only'](tmp_path / 'old', truth)
    out, dataset = tmp_path / 'standard', tmp_path / 'runs.npz'
    assert convert_main([str(source), '--out', str(out), '--subject', 'roach',
                         '--dataset', str(dataset)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['subject'] == 'roach' and summary['poses'] == truth.n_paths * len(truth.t)
    assert summary['dataset']['runs'] == truth.n_paths
    assert set(bag_topics(out)) == {'/vicon/roach/roach', '/roach/run_start'}
    assert any('ROS 1 bag' in note for note in summary['notes'])
    assert convert_main([str(source), '--out', str(out)]) == 3   # the output exists: exit 3
    err = capsys.readouterr().err
    assert err.startswith('error: convert: ') and 'exists already' in err


def test_convert_refuses_an_ambiguous_input_and_leaves_nothing_behind(
        tmp_path: Path, truth: Paths, capsys: pytest.CaptureFixture) -> None:
    source = several_robots(tmp_path / 'two', truth)
    assert convert_main([str(source), '--out', str(tmp_path / 'out')]) == 1
    err = capsys.readouterr().err
    assert 'robot_a at 50 Hz, robot_b at 50 Hz' in err and err.count('\n') == 1
    assert not (tmp_path / 'out').exists()
    assert convert_main([str(source), '--out', str(tmp_path / 'out'), '--frame',
                         'robot_b']) == 0
