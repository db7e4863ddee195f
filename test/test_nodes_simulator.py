"""
The simulator node: its messages, its parameters, its command line.

In-process tests run rclpy in a context of their own (fixture `ros`), a node and a listener in
one executor; the process-level behaviour (exit codes, one-line errors) goes through `main`.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
import math
import time

import numpy as np
import pytest

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402

from octoroach_model.nodes import common, messages, simulator  # noqa: E402
from octoroach_model.nodes.simulator import RunSettings, Simulator  # noqa: E402

FAST = [Parameter('rate', value=100.0), Parameter('pause_s', value=0.5),
        Parameter('cycles', value=1), Parameter('seed', value=7)]


@pytest.fixture
def ros():
    """
    Give this test an rclpy context and executor of its own.

    Its nodes are destroyed after it, so no publisher of this test stays visible to later ones.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    rclpy.init(args=[], context=context)
    executor = SingleThreadedExecutor(context=context)
    yield context, executor
    nodes = executor.get_nodes()
    executor.shutdown()
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)
    context.destroy()


def spin_until(executor, condition: Callable[[], object], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        executor.spin_once(timeout_sec=0.05)


@dataclass
class Listener:
    """Poses and markers of one subject, in middleware reception order."""

    events: list[tuple[int, str, object]] = field(default_factory=list)

    def markers(self) -> list[int]:
        return [msg.data for _, kind, msg in sorted(self.events, key=lambda e: e[0])
                if kind == 'marker']

    def runs(self) -> dict[int, list[object]]:
        """Run index -> its poses, split at the markers."""
        runs: dict[int, list[object]] = {}
        current = None
        for _, kind, msg in sorted(self.events, key=lambda e: e[0]):
            if kind == 'marker':
                current = msg.data
                runs[current] = []
            elif current is not None:
                runs[current].append(msg)
        return runs


def listen(context, executor, subject: str = 'octoroach') -> Listener:
    from geometry_msgs.msg import TransformStamped
    from rclpy.node import Node
    from std_msgs.msg import UInt32

    listener = Listener()
    node = Node(f'listener_{subject}', context=context)

    def keep(kind: str) -> Callable[[object, dict], None]:
        return lambda msg, info: listener.events.append((info['received_timestamp'], kind, msg))

    qos = common.vicon_qos()
    node.create_subscription(TransformStamped, f'/vicon/{subject}/{subject}', keep('pose'), qos)
    node.create_subscription(UInt32, f'/{subject}/run_start', keep('marker'), qos)
    executor.add_node(node)
    return listener


def test_runs_are_published_as_vicon_transforms_with_a_marker_before_each(ros):
    context, executor = ros
    listener = listen(context, executor)
    node = Simulator(context=context, parameter_overrides=FAST)
    executor.add_node(node)
    spin_until(executor, lambda: len(listener.markers()) >= 3, 10.0, 'three run markers')
    runs = listener.runs()
    assert listener.markers()[:3] == [0, 1, 2]
    for index in (0, 1):
        poses = runs[index]
        assert len(poses) == 51  # 1 cycle at 2 Hz = 0.5 s at 100 Hz, both ends
        expected = node.settings.simulate(node.settings.run_seed(index)).poses[0]
        got = np.array([messages.transform_to_pose(msg) for msg in poses])
        np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-12)
        turn = np.angle(np.exp(1j * (got[:, 2] - expected[:, 2])))
        np.testing.assert_allclose(turn, 0.0, atol=1e-9)
        for msg in poses:
            assert msg.header.frame_id == 'vicon/world'
            assert msg.child_frame_id == 'vicon/octoroach/octoroach'
            q = msg.transform.rotation
            assert math.isclose(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2, 1.0, rel_tol=1e-12)
            assert msg.transform.translation.z == 0.0
        stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in poses])
        assert np.median(np.diff(stamps)) == pytest.approx(0.01, abs=0.002)
    gap = (runs[1][0].header.stamp.sec + runs[1][0].header.stamp.nanosec * 1e-9) - \
        (runs[0][-1].header.stamp.sec + runs[0][-1].header.stamp.nanosec * 1e-9)
    assert gap > 0.5  # readers split runs at gaps longer than 0.5 s


def test_start_pose_and_seed_reach_the_model(ros):
    context, executor = ros
    listener = listen(context, executor)
    overrides = FAST + [Parameter('start_x', value=1.5), Parameter('start_y', value=-2.0),
                        Parameter('start_heading', value=0.0)]
    node = Simulator(context=context, parameter_overrides=overrides)
    executor.add_node(node)
    spin_until(executor, lambda: len(listener.markers()) >= 2, 10.0, 'two run markers')
    first = messages.transform_to_pose(listener.runs()[0][0])
    assert first == pytest.approx((1.5, -2.0, 0.0), abs=1e-12)
    assert node.settings.run_seed(0) == RunSettings.from_values(
        common.current_values(node, simulator.simulator_specs())).run_seed(0)


@pytest.mark.parametrize(('name', 'value', 'words'), [
    ('sigma1', 5.0, 'sigma1'),
    ('rate', 50, 'DOUBLE'),
    ('draws', 'sometimes', 'stance, run'),
    ('effect', 'wobble', 'must be one of'),
    ('effect', 'SECRET', 'got text (6 characters, not shown)'),
    ('effect', 'measurment_noise', '(did you mean measurement_noise?)'),
    ('draws', 'SECRET', 'not shown'),
    ('effect_params.fraction', 0.95, 'fraction'),
    ('subject', 'two words', 'must be a name'),
    ('segment', 'SECRET words', 'segment must be a name'),
    ('world_frame', '', 'frame'),
    ('world_frame', 'SECRET frame', 'world_frame must be a frame name'),
    ('robots', 0, 'robots'),
])
def test_an_invalid_setting_is_rejected_with_a_reason(ros, name, value, words):
    context, executor = ros
    node = Simulator(context=context, parameter_overrides=FAST)
    executor.add_node(node)
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful
    assert words in result.reason
    assert 'SECRET' not in result.reason    # any process on the domain sets parameters
    assert node.get_parameter(name).value != value


def test_a_valid_setting_applies_from_the_next_run(ros):
    context, executor = ros
    listener = listen(context, executor)
    node = Simulator(context=context, parameter_overrides=FAST)
    executor.add_node(node)
    spin_until(executor, lambda: listener.markers()[:1] == [0], 10.0, 'run 0')
    result = node.set_parameters([Parameter('sigma1', value=0.3),
                                  Parameter('effect', value='measurement_noise'),
                                  Parameter('effect_params.position_std_cm', value=1.0)])[0]
    assert result.successful, result.reason
    assert node.settings.sigma1 == pytest.approx(0.12)  # run 0 keeps what it started with
    spin_until(executor, lambda: 1 in listener.markers(), 10.0, 'run 1')
    assert node.settings.sigma1 == 0.3
    assert node.settings.effects() == {'measurement_noise': {'position_std_cm': 1.0}}


def test_an_extension_family_drifts_over_the_session_run_by_run(ros):
    context, executor = ros
    listener = listen(context, executor)
    overrides = FAST + [Parameter('runs', value=3), Parameter('cycles', value=2),
                        Parameter('extension', value='run_order_drift'),
                        Parameter('extension_params.parameter', value='yaw_rate'),
                        Parameter('extension_params.change', value=40.0)]
    node = Simulator(context=context, parameter_overrides=overrides)
    executor.add_node(node)
    spin_until(executor, lambda: len(listener.runs().get(2, [])) >= 101, 20.0, 'three runs')
    turns = []
    for index in range(3):
        got = np.array([messages.transform_to_pose(msg) for msg in listener.runs()[index]])
        expected = node.settings.simulate(node.settings.run_seed(index), index).poses[0]
        np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-12)
        plain = RunSettings.from_values({**common.current_values(
            node, simulator.simulator_specs()), 'extension': 'none'}).simulate(
            node.settings.run_seed(index)).poses[0]
        turns.append(expected[-1, 2] - plain[-1, 2])
    # run k of 3 turns at 40 k / 2 deg/s more than the plain model, over its 1 s
    np.testing.assert_allclose(np.degrees(turns), [0.0, 20.0, 40.0], atol=1e-6)
    rejected = node.set_parameters([Parameter('runs', value=1)])[0]
    assert not rejected.successful and 'runs >= 2' in rejected.reason


def test_many_robots_each_have_their_own_subject_and_topics(ros):
    context, executor = ros
    last = listen(context, executor, 'octoroach_2')
    node = Simulator(context=context,
                     parameter_overrides=FAST + [Parameter('robots', value=3)])
    executor.add_node(node)
    spin_until(executor, lambda: len(last.runs().get(0, [])) >= 5, 10.0, 'robot 2 poses')
    msg = last.runs()[0][0]
    assert msg.child_frame_id == 'vicon/octoroach_2/octoroach_2'
    topics = dict(node.get_topic_names_and_types())
    for i in range(3):
        assert topics[f'/vicon/octoroach_{i}/octoroach_{i}'] == [
            'geometry_msgs/msg/TransformStamped']
        assert topics[f'/octoroach_{i}/run_start'] == ['std_msgs/msg/UInt32']


def test_topic_names_follow_the_recordings_convention():
    from octoroach_model import recordings

    assert simulator.pose_topic('octoroach', 'octoroach') == recordings.DEFAULT_POSE_TOPIC
    assert simulator.marker_topic('octoroach') == recordings.DEFAULT_MARKER_TOPIC
    assert simulator.pose_topic('r_3', 'r_3') == recordings.pose_topic('r_3')


def test_messages_round_trip_poses_through_serialized_transforms():
    from geometry_msgs.msg import TransformStamped
    from rclpy.serialization import deserialize_message, serialize_message

    poses = np.array([[1.5, -2.25, math.pi / 2], [0.1, 0.2, -3.0], [0.0, 0.0, 7.0]])
    stamp_ns = 1_700_000_000_123_456_789
    [rows] = messages.planar_rows(poses)
    template = messages.transform_message('vicon/world', 'vicon/octoroach/octoroach')
    for row, pose in zip(rows, poses):
        filled = messages.fill_transform(template, row, stamp_ns)
        expected = messages.pose_to_transform(pose, stamp_ns, 'vicon/world',
                                              'vicon/octoroach/octoroach')
        back = deserialize_message(serialize_message(filled), TransformStamped)
        assert back == expected
        assert (back.header.stamp.sec, back.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
        x, y, heading = messages.transform_to_pose(back)
        assert (x, y) == (pose[0], pose[1])
        assert math.isclose(math.remainder(heading - pose[2], 2 * math.pi), 0.0, abs_tol=1e-12)
        q = back.transform.rotation
        assert (q.x, q.y) == (0.0, 0.0)
        assert math.isclose(q.z ** 2 + q.w ** 2, 1.0, rel_tol=1e-12)


def test_help_lists_every_parameter_with_range_and_unit_without_starting_ros(capsys):
    assert simulator.main(['--help']) == 0
    text = capsys.readouterr().out
    for spec in simulator.simulator_specs():
        assert spec.name in text
    assert '[0.5, 3600]' in text and 'deg' in text and '/vicon/SUBJECT/SEGMENT' in text


@pytest.mark.parametrize(('args', 'message'), [
    (['--ros-args', '-p', 'sigma1:=5.0'], 'error: sigma1 = 5.0 rad is outside [0, 1.5)'),
    (['--ros-args', '-p', 'rate:=50'], 'error: rate must be a double'),
    (['--ros-args', '-p', 'rate'], "error: parameter rule 'rate' must read NAME:=VALUE"),
    (['--frobnicate'], 'error: unrecognized arguments: --frobnicate'),
])
def test_bad_input_at_start_is_one_error_line(capfd, args, message):
    assert simulator.main(args) == 2
    err = capfd.readouterr().err
    assert err.startswith(message), err
    assert err.count('\n') == 1 and 'Traceback' not in err


def test_split_ros_args_keeps_node_flags_apart():
    own, ros = common.split_ros_args(['a', '--ros-args', '-p', 'x:=1', '--', 'b'])
    assert own == ['a', 'b'] and ros == ['--ros-args', '-p', 'x:=1']
    with pytest.raises(common.UsageError, match='NAME:=VALUE'):
        common.split_ros_args(['--ros-args', '-p', 'x'])


def test_a_node_stuck_on_its_way_out_still_ends(tmp_path):
    """The shutdown watchdog ends a process whose way out hangs, and says where it hung."""
    import subprocess
    import sys

    script = ('import threading, time\n'
              'from octoroach_model.nodes.common import shutdown_watchdog\n'
              "shutdown_watchdog('stuck_node', 0, deadline_s=0.5)\n"
              'threading.Thread(target=time.sleep, args=(60,)).start()\n')
    started = time.monotonic()
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 1
    assert time.monotonic() - started < 20
    assert 'stuck_node: shutdown stuck for 0 s' in done.stderr
    assert 'in sleep' in done.stderr or 'Thread' in done.stderr
