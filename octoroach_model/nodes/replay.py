"""
replay: a recorded bag published again on its topics with its recorded timing and QoS.

What `ros2 bag play` does on a full ROS install, for rosbag2 bags (MCAP or sqlite3) on a
PyPI-only one; ROS glue only, the bag is read by the bag layer's `BagReader`. Every message
goes out as the recorded CDR bytes (raw publish, recorded type, nothing rewritten, header
stamps included) at its log time divided by `rate`, streamed from the file in recorded order.
Each topic is published with the QoS its publishers offered when it was recorded
(reliability, durability and depth from the bag's metadata, see `recordings.replay_profile`)
unless the `reliability`, `durability` or `qos_depth` parameters override it. Publishing runs
in its own thread, paced by a monotonic clock, while the executor serves parameters; the node
exits when the bag is done (unless `loop`). Before the first message it waits (bounded) for
subscribers on every topic, and before exiting until every reliable message is acknowledged,
so a recorder listening gets every message.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import importlib
from pathlib import Path
import sys
import threading
import time
from typing import Any

from octoroach_model.errors import BagError, OctoroachError
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
    SubscriberWait,
    UsageError,
    with_defaults,
)
from octoroach_model.settings import setting

SUMMARY = ('ROS node: publishes every message of a rosbag2 bag (MCAP directory or file, or '
           'sqlite3 directory) on its recorded topics with the recorded types (raw CDR, '
           'nothing rewritten), the recorded QoS and the recorded timing divided by --rate; '
           'exits when done unless --loop.')
NOTES = """
Publisher QoS per topic: as recorded (reliability and durability of the publishers' offered
profiles; depth where the recording knows it, else 1000), unless overridden with
reliability, durability or qos_depth. A bag cut short by a killed recorder (no metadata.yaml,
no MCAP summary) plays up to the damage. ROS 1 bags: `convert` them first. Example: python -m
octoroach_model replay runs_bag --rate 10 --wait-subscribers 1
"""
TOPICS = (('publishes', 'each topic of the bag', 'its recorded type, raw CDR, recorded QoS'),)
WAIT_POLL_S = 0.01
MIN_SLEEP_S = 2e-4  # shorter waits cost more than they are worth: send at once
ACK_TIMEOUT_S = 5.0
FALLBACK_DEPTH = 1000


@dataclass(frozen=True)
class ReplaySettings:
    """
    The replay node's own parameters: the one source of their help, unit, range and default.

    Its parameters and flags are made from these fields and from `SubscriberWait`'s.
    """

    bag: str = setting('', 'bag directory or .mcap file to play', read_only=True)
    rate: float = setting(1.0, 'speed factor: recorded intervals are divided by it',
                          low=0.01, high=1000.0)
    loop: bool = setting(False, 'start again from the beginning when done')
    reliability: str = setting('', "publishers' reliability; empty: as recorded",
                               choices=('', 'reliable', 'best_effort'), read_only=True)
    durability: str = setting('', "publishers' durability; empty: as recorded",
                              choices=('', 'volatile', 'transient_local'), read_only=True)
    qos_depth: int = setting(0, f'history depth of the publishers; 0: as recorded (else '
                             f'{FALLBACK_DEPTH})', low=0, high=100_000, read_only=True)


def replay_specs() -> list[ParamSpec]:
    """List the replay node's parameters."""
    return [*field_specs(ReplaySettings, ('bag', 'rate', 'loop')),
            *field_specs(SubscriberWait, ('wait_subscribers', 'wait_timeout_s')),
            *field_specs(ReplaySettings, ('reliability', 'durability', 'qos_depth'))]


def _message_class(msgtype: str) -> Any:
    package, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError, ValueError):
        return None


def rclpy_qos(profile: Any) -> Any:
    """Turn the bag layer's QosProfile (keep_last, reliability, durability) into rclpy's."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from octoroach_model.recordings.bagio.qos import Durability, Reliability

    return QoSProfile(
        depth=int(profile.depth),
        reliability=ReliabilityPolicy.BEST_EFFORT
        if profile.reliability is Reliability.BEST_EFFORT else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL
        if profile.durability is Durability.TRANSIENT_LOCAL else DurabilityPolicy.VOLATILE)


try:  # the node class needs rclpy; --help does not
    from rclpy.node import Node
    from rclpy.task import Future
except ImportError:  # pragma: no cover
    Node = object  # type: ignore[assignment,misc]


class Replay(Node):
    """Plays one bag; see the module docstring. `done` holds the exit code when finished."""

    def __init__(self, defaults: dict[str, Any] | None = None, **node_options: Any) -> None:
        super().__init__('replay', **node_options)
        self._specs = with_defaults(replay_specs(), defaults)
        values = declare_parameters(self, self._specs)
        self.add_on_set_parameters_callback(set_parameters_callback(self, self._specs))
        if not values['bag']:
            raise UsageError('no bag given (BAG argument or -p bag:=PATH)')
        self._source = str(values['bag'])
        self._outputs = self._make_publishers(values)
        self._notes_logged = False
        self.published = 0
        self._rate = float(values['rate'])
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.done = Future()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play, name='replay', daemon=True)
        self._thread.start()

    def _make_publishers(self, values: dict[str, Any]) -> dict[str, Any]:
        """One publisher per recorded topic of a known type, with its recorded QoS."""
        from octoroach_model.recordings import BagReader, QosOverride, replay_profile
        from octoroach_model.recordings.bagio.bag_files import Storage

        reader = BagReader(self._source)
        if reader.storage is Storage.ROS1:
            raise BagError(f'{self._source}: a ROS 1 bag; `convert` it to a rosbag2 bag first')
        topics = reader.topics()
        override = QosOverride.of_names(str(values['reliability']), str(values['durability']),
                                        int(values['qos_depth']))
        publishers: dict[str, Any] = {}
        self.qos: dict[str, Any] = {}
        for topic, info in sorted(topics.items()):
            message_class = _message_class(info.msgtype)
            if info.serialization_format != 'cdr' or message_class is None:
                self.get_logger().warning(f'not playing {topic}: type {info.msgtype} '
                                          f'({info.serialization_format}) unknown here')
                continue
            if info.count == 0:
                continue
            profile, note = replay_profile(info.offered_qos, override, FALLBACK_DEPTH)
            self.qos[topic] = profile
            publishers[topic] = self.create_publisher(message_class, topic, rclpy_qos(profile))
            self.get_logger().info(
                f'{topic} [{info.msgtype}]: {profile.reliability}, {profile.durability}, '
                f'depth {profile.depth}' + (f' ({note})' if note else ''))
        if not publishers:
            raise BagError(f'{self._source}: no messages of a known type to play')
        return publishers

    def _on_parameters_set(self, parameters: list[Any]) -> None:
        for parameter in parameters:
            if parameter.name == 'rate':
                self._rate = float(parameter.value)  # read by the thread at every message

    def _value(self, name: str) -> Any:
        return self.get_parameter(name).value

    def _play(self) -> None:
        """Thread: wait for subscribers, play (and loop), wait for acks, set `done`."""
        code = 0
        try:
            self._wait_for_subscribers()
            started = time.monotonic()
            while not self._stop.is_set():
                self._play_once()
                if not self._value('loop'):
                    break
            played = time.monotonic() - started
            self._wait_acknowledged()
            if not self._stop.is_set():
                self.get_logger().info(
                    f'published {self.published} messages on {len(self._outputs)} topic(s) '
                    f'in {played:.2f} s (all acknowledged after '
                    f'{time.monotonic() - started:.2f} s)')
        except Exception as error:  # noqa: BLE001 - shutting down under us ends the play
            if not self._stop.is_set():
                self.get_logger().error(f'replay stopped: {error}')
                code = 1
        finally:
            self.done.set_result(code)

    def _live(self) -> list[Any]:
        return list(self._outputs.values())

    def _wait_for_subscribers(self) -> None:
        wanted = int(self._value('wait_subscribers'))
        if not wanted:
            return
        deadline = time.monotonic() + float(self._value('wait_timeout_s'))
        while not all(pub.get_subscription_count() >= wanted for pub in self._live()):
            if time.monotonic() > deadline:
                self.get_logger().warning(f'fewer than {wanted} subscriber(s) on some topic '
                                          'after the timeout; starting anyway')
                return
            if self._stop.wait(WAIT_POLL_S):
                return

    def _play_once(self) -> None:
        """One pass over the bag at `rate`, streamed; a rate change re-anchors the clock."""
        from octoroach_model.recordings import BagReader

        notes: list[str] = []
        reader = BagReader(self._source, notes)
        publishers, stop = self._outputs, self._stop
        rate = self._rate
        wall0 = 0.0
        bag0: int | None = None  # log time of the first message, played at wall0
        for message in reader.messages(list(publishers)):
            if bag0 is None:
                wall0, bag0 = time.monotonic(), message.log_time_ns
            if self._rate != rate:
                wall0, bag0, rate = time.monotonic(), message.log_time_ns, self._rate
            delay = wall0 + (message.log_time_ns - bag0) / 1e9 / rate - time.monotonic()
            if delay > MIN_SLEEP_S and stop.wait(delay) or stop.is_set():
                return
            publishers[message.topic].publish(message.data)
            self.published += 1
        if not self._notes_logged:
            self._notes_logged = True
            for note in notes:
                self.get_logger().warning(note)

    def _wait_acknowledged(self) -> None:
        from rclpy.duration import Duration

        for publisher in self._live():
            if self._stop.is_set():
                return
            publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))

    def destroy_node(self) -> None:
        """Stop the publishing thread before the publishers go."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        super().destroy_node()


def parser() -> NodeArgumentParser:
    """Build the command line: its flags are parameters' (`add_flag`), --ros-args the rest."""
    result = node_parser('replay', SUMMARY, replay_specs(), TOPICS, NOTES,
                         'BAG [--rate R] [--loop] [--wait-subscribers N] [--wait-timeout S]')
    add_flag(result, ReplaySettings, 'bag', 'bag', nargs='?')
    add_flag(result, ReplaySettings, 'rate')
    add_flag(result, ReplaySettings, 'loop')
    add_flag(result, SubscriberWait, 'wait_subscribers', metavar='N')
    add_flag(result, SubscriberWait, 'wait_timeout_s', metavar='S')
    add_flag(result, ReplaySettings, 'reliability')
    add_flag(result, ReplaySettings, 'durability')
    add_flag(result, ReplaySettings, 'qos_depth', metavar='N')
    return result


def main(argv: Sequence[str] | None = None) -> int:
    """Run `replay BAG [--rate R] [--loop] [--wait-subscribers N] [--reliability R] ...`."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        args = parser().parse_args(own)
        if args.bag is not None and not Path(args.bag).exists():
            raise BagError(f'{args.bag}: no such bag (directory or .mcap file)')
        if args.bag is not None and Path(args.bag).suffix == '.npz':
            raise BagError(f'{args.bag}: a multisample data set holds runs, not recorded '
                           'messages; replay plays bags (directories or .mcap files)')
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error), start_exit_code(error))
    defaults = flags_given(args, ReplaySettings, SubscriberWait)
    return run_node(lambda: Replay(defaults), ros, 'replay')
