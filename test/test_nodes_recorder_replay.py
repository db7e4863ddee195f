"""
Recorder and replay, end to end with real rclpy in separate processes.

simulator -> recorder -> bag must give back the model's runs; a bag replayed at 10x into the
recorder must give back the same messages; a recorder killed with SIGKILL must leave a bag
readable up to its last flush.
"""
from __future__ import annotations

import signal

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')

from octoroach_model import recordings, simulate  # noqa: E402
from octoroach_model.nodes import recorder as recorder_node  # noqa: E402
from octoroach_model.nodes import replay as replay_node  # noqa: E402
from octoroach_model.nodes.simulator import RunSettings, simulator_specs  # noqa: E402
from octoroach_model.recordings.bagio.reader import BagReader  # noqa: E402
from octoroach_model.recordings.bagio.recording import Recording  # noqa: E402
from ros_helpers import call_trigger, NodeSet, wait_until  # noqa: E402

# RIHS01 type hashes of Jazzy's messages (what rclpy reports for its publishers)
TRANSFORM_HASH = 'RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206'
RECORDED = r'(\d+) messages recorded'


def bag_messages(bag) -> list:
    """Every readable message of a bag (damaged or not), in file order."""
    return list(BagReader(bag).messages())


def recorded_count(node) -> int:
    return max((int(n) for n in node.matches(RECORDED)), default=0)


def bag_topics(bag) -> dict[str, dict]:
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return {entry['topic_metadata']['name']: entry
            for entry in info['topics_with_message_count']}


def test_simulated_runs_are_recorded_and_read_back_as_the_models_runs(tmp_path):
    from geometry_msgs.msg import TransformStamped
    from rclpy.serialization import deserialize_message

    bag, dataset = tmp_path / 'sim_bag', tmp_path / 'sim.npz'
    overrides = {'runs': 3, 'cycles': 2, 'seed': 11}
    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(bag), '--dataset', str(dataset),
                               '--ros-args', '-p', 'log_period_s:=0.5')
        recorder.wait_for_log('recording .* to')
        parameters = [arg for name, value in overrides.items()
                      for arg in ('-p', f'{name}:={value}')]
        sim = nodes.start('simulator', '--ros-args', '-p', 'wait_subscribers:=1',
                          '-p', 'wait_timeout_s:=60.0', *parameters)
        assert sim.wait(timeout=90) == 0, nodes.logs()
        expected = 3 * 51 + 3  # 1 s runs at 50 Hz, both ends, and one marker each
        wait_until(lambda: recorded_count(recorder) == expected, 30.0,
                   f'{expected} messages recorded\n{nodes.logs()}')
        assert recorder.stop(signal.SIGINT) == 0, nodes.logs()

    topics = bag_topics(bag)
    pose = topics[recordings.DEFAULT_POSE_TOPIC]
    assert pose['message_count'] == 153
    assert topics[recordings.DEFAULT_MARKER_TOPIC]['message_count'] == 3
    assert pose['topic_metadata']['type'] == 'geometry_msgs/msg/TransformStamped'
    assert pose['topic_metadata']['type_description_hash'] == TRANSFORM_HASH
    qos = pose['topic_metadata']['offered_qos_profiles'][0]
    assert (qos['reliability'], qos['durability']) == ('reliable', 'volatile')

    runs = recordings.read_runs([bag])
    assert len(runs.runs) == 3, runs.notes
    values = {spec.name: spec.default for spec in simulator_specs()} | overrides
    settings = RunSettings.from_values(values)
    for index, run in enumerate(runs.runs):
        assert len(run.t) == 51
        assert np.median(np.diff(run.t)) == pytest.approx(0.02, abs=0.002)
        assert run.duration_s == pytest.approx(1.0, abs=0.05)
        model = settings.simulate(settings.run_seed(index)).poses[0]
        np.testing.assert_allclose(run.poses, model, atol=1e-9)

    for message in bag_messages(bag):
        if message.topic != recordings.DEFAULT_POSE_TOPIC:
            continue
        msg = deserialize_message(message.data, TransformStamped)
        assert msg.header.frame_id == recordings.DEFAULT_WORLD_FRAME
        assert msg.child_frame_id == recordings.DEFAULT_CHILD_FRAME
        q = msg.transform.rotation
        assert q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2 == pytest.approx(1.0, abs=1e-12)

    data = recordings.load_dataset(dataset)
    assert data.poses.shape[0] == 3 and data.poses.shape[2] == 3


def test_a_killed_recorder_leaves_a_bag_that_repair_makes_complete(tmp_path):
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    from octoroach_model.cli import repair_main

    bag = tmp_path / 'killed'
    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(bag), '--ros-args',
                               '-p', 'log_period_s:=0.5')
        recorder.wait_for_log('recording .* to')
        recorder.wait_for_log(f'if this recorder dies, make the bag complete with: '
                              f'python -m octoroach_model repair {bag}')
        nodes.start('simulator', '--ros-args', '-p', 'wait_subscribers:=1', '-p', 'cycles:=2',
                    '-p', 'pause_s:=0.5', '-p', 'seed:=5', '-p', 'wait_timeout_s:=60.0')
        wait_until(lambda: recorded_count(recorder) >= 160, 60.0,
                   f'160 messages recorded\n{nodes.logs()}')
        logged = recorded_count(recorder)
        recorder.kill()

    assert not (bag / 'metadata.yaml').exists()
    survivors = [(m.topic, m.log_time_ns, bytes(m.data)) for m in bag_messages(bag)]
    # flushed at least once a second: at most ~1 s (50 poses) plus the log delay missing
    assert len(survivors) >= logged - 75, (len(survivors), logged)
    runs = recordings.read_runs([bag])
    assert len(runs.runs) >= 2
    assert all(len(run.t) == 51 for run in runs.runs[:2])
    assert any('metadata.yaml' in note or 'truncated' in note for note in runs.notes)

    assert repair_main([str(bag)]) == 0
    assert (bag / 'metadata.yaml').is_file()
    with AnyReader([bag]) as reader:
        assert [(c.topic, t, bytes(d)) for c, t, d in reader.messages()] == survivors
    (file,) = bag.glob('*.mcap')
    with file.open('rb') as stream:
        indexed = make_reader(stream)
        assert indexed.get_summary().chunk_indexes
        assert [(c.topic, m.log_time, bytes(m.data)) for _, c, m in
                indexed.iter_messages(log_time_order=False)] == survivors


@pytest.mark.parametrize('message_type', [recordings.TRANSFORM_STAMPED,
                                          recordings.POSE_STAMPED])
def test_a_bag_replayed_at_10x_into_the_recorder_comes_back_unchanged(tmp_path, message_type):
    source, copy, dataset = tmp_path / 'source', tmp_path / 'copy', tmp_path / 'copy.npz'
    n_runs = 4 if message_type == recordings.TRANSFORM_STAMPED else 2
    recordings.write_paths_bag(source, simulate(n_runs, seed=3, cycles=4),
                               message_type=message_type)
    expected = n_runs * 101 + n_runs
    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(copy), '--dataset', str(dataset),
                               '--ros-args', '-p', 'log_period_s:=0.5')
        recorder.wait_for_log('recording .* to')
        replay = nodes.start('replay', str(source), '--rate', '10', '--wait-subscribers', '1',
                             '--wait-timeout', '60')
        assert replay.wait(timeout=90) == 0, nodes.logs()
        replay.wait_for_log(f'published {expected} messages')
        wait_until(lambda: recorded_count(recorder) == expected, 30.0,
                   f'{expected} messages recorded\n{nodes.logs()}')
        if message_type == recordings.TRANSFORM_STAMPED:
            success, message = call_trigger('/recorder/export', nodes.domain)
            assert success, message
            assert f'{n_runs} run(s)' in message and dataset.exists()
        assert recorder.stop(signal.SIGTERM) == 0, nodes.logs()

    for topic, entry in bag_topics(copy).items():
        original = bag_topics(source)[topic]
        assert entry['message_count'] == original['message_count']
        assert entry['topic_metadata']['type'] == original['topic_metadata']['type']
        assert entry['topic_metadata']['type'] in (message_type, recordings.MARKER_TYPE)
    before, after = recordings.read_runs([source]), recordings.read_runs([copy])
    assert len(after.runs) == len(before.runs) == n_runs, after.notes
    for old, new in zip(before.runs, after.runs):
        np.testing.assert_array_equal(new.t, old.t)
        np.testing.assert_array_equal(new.poses, old.poses)
        assert new.start_stamp_s == old.start_stamp_s  # header stamps are not rewritten
    assert recordings.load_dataset(dataset).n_paths == n_runs


def test_recording_writes_in_reception_order_and_flushes_a_readable_file(tmp_path):
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    marker = store.types['std_msgs/msg/UInt32']
    bag = Recording(tmp_path / 'bag')
    channel = bag.add_topic('/octoroach/run_start', 'std_msgs/msg/UInt32')
    for received in (30, 10, 20, 50, 40):
        data = store.serialize_cdr(marker(data=received), 'std_msgs/msg/UInt32')
        bag.push(channel, received, bytes(data))
    bag.drain(older_than_ns=35)
    bag.flush()
    messages = bag_messages(tmp_path / 'bag')
    assert [m.log_time_ns for m in messages] == [10, 20, 30]
    assert [store.deserialize_cdr(m.data, 'std_msgs/msg/UInt32').data
            for m in messages] == [10, 20, 30]
    bag.close()
    assert [m.log_time_ns for m in bag_messages(tmp_path / 'bag')] == [10, 20, 30, 40, 50]
    assert bag_topics(tmp_path / 'bag')['/octoroach/run_start']['message_count'] == 5


def publishers_of(topic: str, domain: int, node_name: str, timeout: float = 30.0) -> list:
    """Get the QoS profiles of `node_name`'s publishers on `topic` from the ROS graph."""
    import time as clock

    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(args=[], context=context, domain_id=domain)
    node = Node('qos_probe', context=context)
    try:
        deadline = clock.monotonic() + timeout
        while clock.monotonic() < deadline:
            found = [info.qos_profile for info in node.get_publishers_info_by_topic(topic)
                     if info.node_name == node_name]
            if found:
                return found
            clock.sleep(0.1)
        raise AssertionError(f'no publisher of {node_name} on {topic} within {timeout:g} s')
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        context.destroy()


def best_effort_bag(path):
    """One run of a bag whose publishers offered best-effort QoS when it was recorded."""
    from octoroach_model.recordings import PoseBagWriter, QosProfile

    paths = simulate(1, seed=2, cycles=2)
    stamps = 10**18 + np.round(paths.t * 1e9).astype(np.int64)
    offered = (QosProfile(history='unknown', depth=0, reliability='best_effort'),)
    with PoseBagWriter(path, offered_qos=offered) as writer:
        writer.write_marker(0, int(stamps[0]))
        writer.write_poses(stamps, paths.poses[0])
    return path


def test_replay_keeps_the_recorded_best_effort_qos_unless_overridden(tmp_path):
    from rclpy.qos import ReliabilityPolicy

    source, copy = best_effort_bag(tmp_path / 'best_effort'), tmp_path / 'copy'
    topic = recordings.DEFAULT_POSE_TOPIC
    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(copy), '--ros-args',
                               '-p', 'log_period_s:=0.5')
        recorder.wait_for_log('recording .* to')
        replay = nodes.start('replay', str(source), '--rate', '5', '--loop',
                             '--wait-subscribers', '1', '--wait-timeout', '60')
        replay.wait_for_log(f'{topic} .*: best_effort, volatile, depth 1000')
        (profile,) = publishers_of(topic, nodes.domain, 'replay')
        assert profile.reliability == ReliabilityPolicy.BEST_EFFORT
        wait_until(lambda: recorded_count(recorder) > 0, 30.0, f'a recording\n{nodes.logs()}')
        assert replay.stop(signal.SIGINT) == 0, nodes.logs()
        assert recorder.stop(signal.SIGINT) == 0, nodes.logs()
        forced = nodes.start('replay', str(source), '--loop', '--reliability', 'reliable',
                             '--qos-depth', '20')
        forced.wait_for_log(f'{topic} .*: reliable, volatile, depth 20')
        (profile,) = publishers_of(topic, nodes.domain, 'replay')
        assert profile.reliability == ReliabilityPolicy.RELIABLE
        assert forced.stop(signal.SIGINT) == 0, nodes.logs()
    # the recorder saw a best-effort publisher, and its bag says so
    recorded = bag_topics(copy)[topic]['topic_metadata']['offered_qos_profiles']
    assert [profile['reliability'] for profile in recorded] == ['best_effort']


def test_replay_of_a_missing_bag_is_one_error_line(tmp_path, capfd):
    assert replay_node.main([str(tmp_path / 'nothing')]) == 1      # input unusable: exit 1
    err = capfd.readouterr().err
    assert err.startswith('error: ') and 'no such bag' in err and err.count('\n') == 1


def test_replay_rejects_a_rate_out_of_range(tmp_path, capfd):
    recordings.write_paths_bag(tmp_path / 'b', simulate(1, seed=1, cycles=1))
    assert replay_node.main([str(tmp_path / 'b'), '--rate', '0']) == 2
    err = capfd.readouterr().err
    assert err.startswith('error: rate = 0.0 is outside [0.01, 1000]'), err


def test_replay_of_a_data_set_says_what_it_is(tmp_path, capfd):
    data = recordings.save_dataset(tmp_path / 'x.npz', simulate(2, seed=1, cycles=1))
    assert replay_node.main([str(data)]) == 1
    err = capfd.readouterr().err
    assert 'a multisample data set' in err and 'not an MCAP' not in err, err


def test_recorder_refuses_to_overwrite_a_bag(tmp_path, capfd):
    (tmp_path / 'exists').mkdir()
    assert recorder_node.main(['-o', str(tmp_path / 'exists')]) == 3     # as every program
    err = capfd.readouterr().err
    assert err.startswith('error: ') and 'exists already' in err, err
    assert 'Traceback' not in err and err.count('\n') == 1, err


def test_recorder_refuses_a_bad_topic_name_by_its_entry_without_quoting_it(tmp_path, capfd):
    """The error of rclpy quotes the name over three lines; a parameter may come from anyone."""
    code = recorder_node.main(['-o', str(tmp_path / 'new'), '--topics', '/vicon/a',
                               '/SECRET topic'])
    err = capfd.readouterr().err
    assert code == 2, err
    assert err.startswith('error: bad topic name: entry 2 of topics, text (13 characters, not '
                          'shown), is no ROS topic name'), err
    assert 'SECRET' not in err and err.count('\n') == 1, err


def test_help_of_recorder_and_replay_exits_0(capsys):
    assert recorder_node.main(['--help']) == 0
    assert replay_node.main(['--help']) == 0
    text = capsys.readouterr().out
    for spec in recorder_node.recorder_specs() + replay_node.replay_specs():
        assert spec.name in text
    assert '~/export' in text and '--wait-subscribers' in text
