"""replay: a recorded bag published again on its topics with its recorded timing.

What `ros2 bag play` does on a full ROS install, for this package's bags on a PyPI-only one:
every message goes out as the recorded CDR bytes (raw publish, recorded type, nothing
rewritten, header stamps included) at its log time divided by `rate`. Publishing runs in its
own thread, paced by a monotonic clock, while the executor serves parameters; the node exits
when the bag is done (unless `loop`). Before the first message it waits (bounded) for
subscribers on every topic, and before exiting until every reliable message is acknowledged,
so a recorder listening gets every message.
"""
from __future__ import annotations

import importlib
import struct
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from octoroach_model.errors import BagError, OctoroachError
from octoroach_model.nodes.common import (
    ParamSpec, UsageError, declare_parameters, fail, node_parser, run_node,
    with_defaults,
    set_parameters_callback, split_ros_args, vicon_qos)

SUMMARY = ('ROS node: publishes every message of a rosbag2 MCAP bag (directory or .mcap file) '
           'on its recorded topics with the recorded types (raw CDR, nothing rewritten) and the '
           'recorded timing divided by --rate; exits when done unless --loop.')
NOTES = """
Publisher QoS: reliable, volatile, keep_last qos_depth. A bag cut short by a killed recorder
(no metadata.yaml, no MCAP summary) plays up to the damage. Example: python -m
octoroach_model replay runs_bag --rate 10 --wait-subscribers 1
"""
TOPICS = (('publishes', 'each topic of the bag', 'its recorded type, raw CDR'),)
WAIT_POLL_S = 0.01
MIN_SLEEP_S = 2e-4  # shorter waits cost more than they are worth: send at once
ACK_TIMEOUT_S = 5.0


def replay_specs() -> list[ParamSpec]:
    """The replay node's parameters."""
    return [
        ParamSpec('bag', '', 'bag directory or .mcap file to play', read_only=True),
        ParamSpec('rate', 1.0, 'speed factor: recorded intervals are divided by it', '',
                  0.01, 1000.0),
        ParamSpec('loop', False, 'start again from the beginning when done'),
        ParamSpec('wait_subscribers', 0, 'before starting, wait until every topic has this '
                  'many subscribers', '', 0, 1000),
        ParamSpec('wait_timeout_s', 10.0, 'longest wait for wait_subscribers, then start',
                  's', 0.0, 3600.0),
        ParamSpec('qos_depth', 1000, 'history depth of the publishers', '', 1, 100_000,
                  read_only=True),
    ]


@dataclass
class BagMessages:
    """All messages of a bag in log-time order: topic index, log time (ns), CDR bytes."""

    topics: list[tuple[str, str]] = field(default_factory=list)  # (topic, type)
    log_ns: list[int] = field(default_factory=list)
    topic_index: list[int] = field(default_factory=list)
    data: list[bytes] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.log_ns)


def read_bag_messages(source: str | Path) -> BagMessages:
    """Every message of a bag directory or .mcap file; a cut file is read up to the damage."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, DataEnd, Message, Schema
    from mcap.stream_reader import StreamReader

    from octoroach_model.recordings import bag_files

    bag = bag_files(source)
    found = BagMessages(notes=list(bag.notes))
    index: dict[tuple[str, str], int] = {}
    stamped: list[tuple[int, int, int, bytes]] = []  # log time, serial, topic index, data
    for path in bag.files:
        schemas: dict[int, str] = {}
        channels: dict[int, int] = {}
        try:
            with path.open('rb') as stream:
                for record in StreamReader(stream).records:
                    if isinstance(record, Message):
                        if record.channel_id in channels:
                            stamped.append((record.log_time, len(stamped),
                                            channels[record.channel_id], record.data))
                    elif isinstance(record, Channel):
                        key = (record.topic, schemas.get(record.schema_id, ''))
                        if record.message_encoding == 'cdr' and key[1].count('/') == 2:
                            channels[record.id] = index.setdefault(key, len(index))
                    elif isinstance(record, Schema):
                        schemas[record.id] = record.name
                    elif isinstance(record, DataEnd):
                        break
        except (McapError, EOFError, struct.error, ValueError) as error:
            found.notes.append(f'{path}: cut short ({type(error).__name__}); played up to it')
        except OSError as error:
            raise BagError(f'{path}: cannot read: {error.strerror or error}') from None
    stamped.sort(key=lambda item: (item[0], item[1]))
    found.topics = sorted(index, key=index.__getitem__)
    found.log_ns = [item[0] for item in stamped]
    found.topic_index = [item[2] for item in stamped]
    found.data = [item[3] for item in stamped]
    return found


def _message_class(msgtype: str) -> Any:
    package, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        return None


try:  # the node class needs rclpy; --help does not
    from rclpy.node import Node
    from rclpy.task import Future
except ImportError:  # pragma: no cover
    Node = object  # type: ignore[assignment,misc]


class Replay(Node):  # type: ignore[misc,valid-type]
    """Plays one bag; see the module docstring. `done` holds the exit code when finished."""

    def __init__(self, defaults: dict[str, Any] | None = None, **node_options: Any) -> None:
        super().__init__('replay', **node_options)
        self._specs = with_defaults(replay_specs(), defaults)
        values = declare_parameters(self, self._specs)
        self.add_on_set_parameters_callback(set_parameters_callback(self, self._specs))
        if not values['bag']:
            raise UsageError('no bag given (BAG argument or -p bag:=PATH)')
        self._bag = read_bag_messages(values['bag'])
        for note in self._bag.notes:
            self.get_logger().warning(note)
        if not len(self._bag):
            raise BagError(f'{values["bag"]}: no messages to play')
        qos = vicon_qos(int(values['qos_depth']))
        self._outputs: list[Any] = []
        for topic, msgtype in self._bag.topics:
            message_class = _message_class(msgtype)
            if message_class is None:
                self.get_logger().warning(f'not playing {topic}: type {msgtype} unknown here')
                self._outputs.append(None)
                continue
            self._outputs.append(self.create_publisher(message_class, topic, qos))
        if not any(self._outputs):
            raise BagError(f'{values["bag"]}: no topic with a known message type')
        self.published = 0
        self._rate = float(values['rate'])
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.done = Future()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play, name='replay', daemon=True)
        self._thread.start()

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
                    f'published {self.published} messages on {len(self._bag.topics)} topic(s) '
                    f'in {played:.2f} s (all acknowledged after '
                    f'{time.monotonic() - started:.2f} s)')
        except Exception as error:  # noqa: BLE001 - shutting down under us ends the play
            if not self._stop.is_set():
                self.get_logger().error(f'replay stopped: {error}')
                code = 1
        finally:
            self.done.set_result(code)

    def _live(self) -> list[Any]:
        return [pub for pub in self._outputs if pub is not None]

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
        """One pass over the bag at `rate`; a rate change re-anchors the clock."""
        bag, publishers, stop = self._bag, self._outputs, self._stop
        rate = self._rate
        wall0, bag0 = time.monotonic(), bag.log_ns[0]
        for log_ns, topic, data in zip(bag.log_ns, bag.topic_index, bag.data):
            publisher = publishers[topic]
            if publisher is None:
                continue
            if self._rate != rate:
                wall0, bag0, rate = time.monotonic(), log_ns, self._rate
            delay = wall0 + (log_ns - bag0) / 1e9 / rate - time.monotonic()
            if delay > MIN_SLEEP_S and stop.wait(delay) or stop.is_set():
                return
            publisher.publish(data)
            self.published += 1

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


def main(argv: Sequence[str] | None = None) -> int:
    """`replay BAG [--rate R] [--loop] [--wait-subscribers N] [--wait-timeout S]`."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        parser = node_parser('replay', SUMMARY, replay_specs(), TOPICS, NOTES,
                             'BAG [--rate R] [--loop] [--wait-subscribers N] [--wait-timeout S]')
        parser.add_argument('bag', nargs='?', help='bag directory or .mcap file (parameter bag)')
        parser.add_argument('--rate', type=float, help='speed factor (parameter rate)')
        parser.add_argument('--loop', action='store_true', default=None,
                            help='play again and again (parameter loop)')
        parser.add_argument('--wait-subscribers', type=int, metavar='N',
                            help='subscribers to wait for on every topic (wait_subscribers)')
        parser.add_argument('--wait-timeout', type=float, metavar='S',
                            help='longest wait for them, seconds (wait_timeout_s)')
        args = parser.parse_args(own)
        if args.bag is not None and not Path(args.bag).exists():
            raise BagError(f'{args.bag}: no such bag (directory or .mcap file)')
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error))
    flags = {'bag': args.bag, 'rate': args.rate, 'loop': args.loop,
             'wait_subscribers': args.wait_subscribers, 'wait_timeout_s': args.wait_timeout}
    defaults = {name: value for name, value in flags.items() if value is not None}
    return run_node(lambda: Replay(defaults), ros, 'replay')
