"""
recorder: VICON topics to a rosbag2 MCAP bag, and the bag to a multisample data set.

ROS glue only: messages are taken raw (serialized CDR, as in demo_nodes_py's
listener_serialized) with their middleware reception time, and handed to the bag layer's
`Recording` unchanged: it writes them in reception order into a crash-safe rosbag2 Jazzy bag
(message definitions, RIHS01 type hashes, the publishers' offered QoS, metadata.yaml) and
flushes it every `flush_period_s`. A recorder killed with SIGKILL leaves a bag that the
package reads up to the last flush and that `repair` makes complete.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
import fnmatch
import functools
import importlib
import os
from pathlib import Path
import sys
import time
from typing import Any

from octoroach_model.errors import DataError, exit_code, OctoroachError, OutputError
from octoroach_model.fileio import check_writable
from octoroach_model.nodes.common import (
    add_flag,
    declare_parameters,
    fail,
    field_specs,
    flags_given,
    node_parser,
    NodeArgumentParser,
    ParamSpec,
    run_node,
    set_parameters_callback,
    split_ros_args,
    start_exit_code,
    UsageError,
    vicon_qos,
    with_defaults,
)
from octoroach_model.recordings import (
    DEFAULT_GAP_S, DEFAULT_MARKER_TOPIC, DEFAULT_POSE_TOPIC, DEFAULT_RATE_HZ)
from octoroach_model.recordings.options import FORWARD_AXIS, GAP_S, UP_AXIS
from octoroach_model.settings import setting, settings_of, shown

SUMMARY = ('ROS node: records VICON pose topics (TransformStamped or PoseStamped) and run '
           'markers to a rosbag2 MCAP bag directory (ROS 2 Jazzy layout), flushed every '
           'second; on exit (SIGINT, SIGTERM) it closes the bag and, if `dataset` is set, '
           'turns it into a multisample data set (.npz); the ~/export service does that on '
           'demand.')
NOTES = """
Topics are subscribed when they appear in the ROS graph, with the type they are published
with; entries of `topics` may be fnmatch patterns ('/vicon/*'). The data set holds the runs
as read_runs splits them (run markers, else gaps longer than gap_s), resampled at
export_rate_hz over their common duration, read with forward_axis and up_axis. Log time in
the bag = middleware reception time.
A recorder killed with SIGKILL leaves an .mcap without metadata.yaml that the package's
readers still read, up to about one flush period before the kill; `python -m octoroach_model
repair BAG` (ros2 run octoroach_model repair BAG) makes it a complete bag for any tool.
"""
TOPICS = (
    ('subscribes', '`topics`', 'TransformStamped / PoseStamped / UInt32 (raw CDR)'),
    ('service', '~/export', 'std_srvs/srv/Trigger: write the data set now'),
)
DRAIN_PERIOD_S = 0.1
DISCOVERY_PERIOD_S = 0.2
MAX_TAKEN_PER_CALLBACK = 1000  # then let timers (flush, drain) run


@dataclass(frozen=True)
class RecorderSettings:
    """
    The recorder's parameters: the one source of their help, unit, range and default.

    Its parameters, its flags (-o/--output, --dataset, --topics) and config/recorder.yaml
    are made from these fields; the reading ones are shared with the offline programs.
    """

    output: str = setting('', 'bag directory to create; empty: ./octoroach_YYYYmmdd_HHMMSS',
                          read_only=True)
    topics: tuple[str, ...] = setting((DEFAULT_POSE_TOPIC, DEFAULT_MARKER_TOPIC),
                                      'topics to record (names or fnmatch patterns)',
                                      read_only=True)
    dataset: str = setting('', 'data set file (.npz) written on exit and by ~/export; empty: '
                           'none; must not exist at start', read_only=True)
    gap_s: float = setting(float(DEFAULT_GAP_S), GAP_S)
    export_rate_hz: float = setting(float(DEFAULT_RATE_HZ), 'sample rate of the data set',
                                    unit='Hz', low=1.0, high=1000.0)
    forward_axis: str = setting('x', FORWARD_AXIS)
    up_axis: str = setting('z', UP_AXIS)
    flush_period_s: float = setting(1.0, 'bag file flushed this often', unit='s', low=0.1,
                                    high=10.0)
    log_period_s: float = setting(5.0, 'progress logged this often', unit='s', low=0.5,
                                  high=3600.0)
    qos_depth: int = setting(1000, 'history depth of the subscriptions', low=1, high=100_000,
                             read_only=True)


def recorder_specs() -> list[ParamSpec]:
    """List the recorder's parameters."""
    return field_specs(RecorderSettings, tuple(settings_of(RecorderSettings)))


def default_output() -> str:
    """./octoroach_YYYYmmdd_HHMMSS, like rosbag2's default name."""
    return datetime.now().strftime('octoroach_%Y%m%d_%H%M%S')


def qos_profile_of(profile: Any) -> Any:
    """Turn an rclpy QoSProfile (as discovery reports it) into the bag's QosProfile."""
    from octoroach_model.recordings.bagio.qos import (
        Durability,
        DURABILITY,
        History,
        HISTORY,
        Liveliness,
        LIVELINESS,
        QosProfile,
        Reliability,
        RELIABILITY,
    )

    return QosProfile(
        history=HISTORY.get(int(profile.history), History.UNKNOWN), depth=int(profile.depth),
        reliability=RELIABILITY.get(int(profile.reliability), Reliability.UNKNOWN),
        durability=DURABILITY.get(int(profile.durability), Durability.UNKNOWN),
        deadline_ns=int(profile.deadline.nanoseconds),
        lifespan_ns=int(profile.lifespan.nanoseconds),
        liveliness=LIVELINESS.get(int(profile.liveliness), Liveliness.UNKNOWN),
        liveliness_lease_duration_ns=int(profile.liveliness_lease_duration.nanoseconds),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))


FileIdentity = tuple[int, int, int, int, int]


def _identity(path: str) -> FileIdentity | None:
    """
    Return what tells the file at `path` (a link is not followed) from any other, or None.

    Device and inode, and size and change times: a file removed and made anew often gets
    the inode number back.
    """
    try:
        status = os.lstat(path)
    except OSError:
        return None
    return (status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns,
            status.st_ctime_ns)


def _message_class(msgtype: str) -> Any:
    """Python class of 'pkg/msg/Name', or None when not installed."""
    package, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        return None


def export_dataset(bag: Path, dataset: str, gap_s: float, rate_hz: float,
                   replace: bool = False, options: Any = None) -> str:
    """
    Resample the runs of `bag` (read_runs) into data set `dataset`; say what was written.

    `options`: the ReadOptions (axes) the poses are read with.
    """
    from octoroach_model.recordings import read_runs, save_dataset

    paths = read_runs([bag], gap_s=gap_s, options=options).to_paths(rate_hz=rate_hz)
    target = save_dataset(dataset, paths, replace=replace)
    return f'{paths.n_paths} run(s) of {paths.t[-1]:.2f} s at {rate_hz:g} Hz written to {target}'


@dataclass
class _Recorded:
    """One recorded topic: its type, its publishers' QoS, its subscription."""

    topic: str
    msgtype: str
    offered: list[Any]
    type_hash: str = ''
    subscription: Any = None


try:  # the node class needs rclpy; --help does not
    from rclpy.node import Node
except ImportError:  # pragma: no cover
    Node = object  # type: ignore[assignment,misc]


class Recorder(Node):
    """Records the configured topics; see the module docstring."""

    def __init__(self, defaults: dict[str, Any] | None = None, **node_options: Any) -> None:
        super().__init__('recorder', **node_options)
        self._specs = with_defaults(recorder_specs(), defaults)
        values = declare_parameters(self, self._specs)
        self.add_on_set_parameters_callback(set_parameters_callback(self, self._specs))
        self._patterns = [self._resolve(topic, number)
                          for number, topic in enumerate(values['topics'], 1)]
        from octoroach_model.recordings.bagio.recording import Recording, REORDER_WINDOW_S

        output = Path(values['output'] or default_output())
        self._own_dataset: FileIdentity | None = None   # the file this recorder wrote
        if values['dataset']:
            if os.path.lexists(values['dataset']):
                raise OutputError(f'dataset {values["dataset"]} exists already; choose a new '
                                  'path (the recorder never replaces a file it did not write)')
            check_writable(values['dataset'], 'dataset')
        self._reorder_ns = int(REORDER_WINDOW_S * 1e9)
        self._bag = Recording(output, flush_period_s=float(values['flush_period_s']))
        self._recording: dict[str, _Recorded] = {}
        self._connections: dict[tuple[str, str], Any] = {}
        self._refused: set[str] = set()
        self._logged = 0
        self.get_logger().info(f'recording {", ".join(self._patterns)} to {output}')
        self.get_logger().info(f'if this recorder dies, make the bag complete with: '
                               f'python -m octoroach_model repair {output}')
        self._discover()
        self.create_timer(DISCOVERY_PERIOD_S, self._discover)
        self.create_timer(DRAIN_PERIOD_S, self._drain)
        self._flush_timer = self.create_timer(values['flush_period_s'], self._flush)
        self._log_timer = self.create_timer(values['log_period_s'], self._log_progress)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        from std_srvs.srv import Trigger

        self.create_service(Trigger, '~/export', self._on_export)

    def _resolve(self, topic: str, number: int) -> str:
        if any(ch in topic for ch in '*?['):
            return topic
        try:
            return self.resolve_topic_name(topic)
        except Exception:  # noqa: BLE001 - rclpy raises several name errors (quoting the name)
            raise UsageError(f'bad topic name: entry {number} of topics, {shown(topic)}, is no '
                             'ROS topic name (letters, digits, _ and /; no token starts with a '
                             'digit)') from None

    def _wanted(self, topic: str) -> bool:
        return any(fnmatch.fnmatchcase(topic, pattern) for pattern in self._patterns)

    def _discover(self) -> None:
        """
        Subscribe to wanted topics that have appeared, with the type they are published with.

        A topic listed with several types (a stale endpoint of a process gone, a publisher
        that changed type) gets the first usable one; when no publisher of that type is left
        but another type is on offer, the subscription switches to it.
        """
        for topic, types in self.get_topic_names_and_types():
            if topic in self._refused or not self._wanted(topic):
                continue
            current = self._recording.get(topic)
            if current is not None and (types == [current.msgtype]
                                        or current.subscription.get_publisher_count()):
                continue
            usable = [t for t in types if self._bag.knows(t) and _message_class(t)
                      and (current is None or t != current.msgtype)]
            if not usable:
                if current is None:
                    self.get_logger().warning(f'not recording {topic}: type(s) '
                                              f'{", ".join(types)} unknown here')
                    self._refused.add(topic)
                continue
            if current is not None:
                self.get_logger().warning(f'{topic}: no publisher of {current.msgtype} left; '
                                          f'switching to {usable[0]}')
                self.destroy_subscription(current.subscription)
            elif len(types) > 1:
                self.get_logger().warning(f'{topic} has several types {types}; '
                                          f'recording {usable[0]}')
            self._subscribe(topic, usable[0])

    def _subscribe(self, topic: str, msgtype: str) -> None:
        from rclpy.qos import ReliabilityPolicy

        offered = [info.qos_profile for info in self.get_publishers_info_by_topic(topic)
                   if info.topic_type == msgtype]
        qos = vicon_qos(int(self.get_parameter('qos_depth').value))
        if any(profile.reliability == ReliabilityPolicy.BEST_EFFORT for profile in offered):
            qos.reliability = ReliabilityPolicy.BEST_EFFORT  # else we would match none of them
        hashes = {str(info.topic_type_hash) for info in self.get_publishers_info_by_topic(topic)
                  if info.topic_type == msgtype and str(info.topic_type_hash).startswith('RIHS')}
        recorded = _Recorded(topic, msgtype, [qos_profile_of(p) for p in offered],
                             hashes.pop() if len(hashes) == 1 else '')
        recorded.subscription = self.create_subscription(
            _message_class(msgtype), topic, functools.partial(self._on_message, recorded), qos,
            raw=True)
        self._recording[topic] = recorded
        self.get_logger().info(f'recording {topic} [{msgtype}]')

    def _connection(self, recorded: _Recorded) -> Any:
        """
        Get the bag channel of a topic and type, made at its first message.

        So a type that never delivers leaves no trace in the bag.
        """
        key = (recorded.topic, recorded.msgtype)
        connection = self._connections.get(key)
        if connection is None:
            connection = self._connections[key] = self._bag.add_topic(
                recorded.topic, recorded.msgtype, recorded.offered, recorded.type_hash)
        return connection

    def _on_message(self, recorded: _Recorded, data: bytes, info: dict[str, Any]) -> None:
        """
        Queue the message, then whatever else waits on its subscription.

        The executor hands over one message per wake-up at a cost of a few hundred
        microseconds; taking the backlog here (as rclpy's wait_for_message does) lets a
        recorder keep up with bursts such as a replay at 100x.
        """
        push, connection = self._bag.push, self._connection(recorded)
        push(connection, int(info.get('received_timestamp') or time.time_ns()), data)
        subscription = recorded.subscription
        with subscription.handle:
            for _ in range(MAX_TAKEN_PER_CALLBACK):
                taken = subscription.handle.take_message(subscription.msg_type, True)
                if taken is None:
                    break
                data, info = taken
                push(connection, int(info.get('received_timestamp') or time.time_ns()), data)

    def _drain(self) -> None:
        self._bag.drain(time.time_ns() - self._reorder_ns)
        self._bag.flush_if_due()

    def _flush(self) -> None:
        self._drain()
        self._bag.flush()

    def _log_progress(self) -> None:
        if self._bag.written != self._logged:
            self._logged = self._bag.written
            counts = self._bag.per_topic
            detail = ', '.join(f'{topic} {count}' for topic, count in counts.items()) \
                if len(counts) <= 4 else f'{len(counts)} topics'
            self.get_logger().info(f'{self._bag.written} messages recorded ({detail})')

    def _on_parameters_set(self, parameters: list[Any]) -> None:
        for parameter in parameters:
            if parameter.name == 'flush_period_s':
                self._flush_timer.timer_period_ns = int(parameter.value * 1e9)
                self._bag.flush_period_s = float(parameter.value)
            elif parameter.name == 'log_period_s':
                self._log_timer.timer_period_ns = int(parameter.value * 1e9)

    def _export(self) -> str:
        """
        Write the data set; only the file this recorder wrote before is replaced.

        `dataset` is read-only and did not exist at start, so no other process on the domain
        can aim an export at a file of its choice; a file put there meanwhile is refused.
        """
        dataset = str(self.get_parameter('dataset').value)
        if not dataset:
            raise DataError('parameter dataset is empty: no data set file to write')
        own = self._own_dataset is not None and _identity(dataset) == self._own_dataset
        if os.path.lexists(dataset) and not own:
            raise OutputError(f'dataset {dataset} exists and was not written by this '
                              'recorder; it is left as it is')
        from octoroach_model.recordings import ReadOptions

        options = ReadOptions(forward_axis=str(self.get_parameter('forward_axis').value),
                              up_axis=str(self.get_parameter('up_axis').value))
        message = export_dataset(self._bag.path, dataset,
                                 float(self.get_parameter('gap_s').value),
                                 float(self.get_parameter('export_rate_hz').value),
                                 replace=own, options=options)
        self._own_dataset = _identity(dataset)
        return message

    def _on_export(self, request: Any, response: Any) -> Any:
        """~/export: flush the bag, write the data set from it, say what was written."""
        self._bag.drain()
        self._bag.flush()
        try:
            response.message = self._export()
            response.success = True
        except OctoroachError as error:
            response.message = str(error)
            response.success = False
        self.get_logger().info(f'export: {response.message}')
        return response

    def finish(self) -> int:
        """Close the bag (metadata.yaml); write the data set if asked. The exit code."""
        self._bag.close()
        self.get_logger().info(f'bag {self._bag.path} closed: {self._bag.written} messages')
        if not self.get_parameter('dataset').value:
            return 0
        try:
            self.get_logger().info(self._export())
        except OctoroachError as error:
            return fail(f'cannot write the data set: {error}', exit_code(error))
        return 0


def parser() -> NodeArgumentParser:
    """Build the command line: its flags are parameters' (`add_flag`), --ros-args the rest."""
    result = node_parser('recorder', SUMMARY, recorder_specs(), TOPICS, NOTES,
                         '[-o BAG] [--dataset FILE] [--topics TOPIC ...]')
    add_flag(result, RecorderSettings, 'output', '-o', '--output')
    add_flag(result, RecorderSettings, 'dataset')
    add_flag(result, RecorderSettings, 'topics', metavar='TOPIC')
    return result


def main(argv: Sequence[str] | None = None) -> int:
    """Run `recorder [-o BAG] [--dataset FILE] [--topics T ...] [--ros-args ...]`."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        args = parser().parse_args(own)
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error), start_exit_code(error))
    defaults = flags_given(args, RecorderSettings)
    return run_node(lambda: Recorder(defaults), ros, 'recorder')
