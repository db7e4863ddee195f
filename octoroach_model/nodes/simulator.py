"""
simulator: the model's runs as a live VICON pose stream, so ROS tools can be tried on it.

Runs of `cycles` gait cycles follow one another, separated by a pause of `pause_s` with no
poses; a run marker (std_msgs/msg/UInt32, data = run index) goes out one sample period before
each run's first pose. Each run is drawn in one `RunSettings.simulate` call during the pause
before it, with the parameters in force then (drawn again at its start if they changed
meanwhile). A single steady (wall-rate) timer then sends, for all robots at once, the samples
due on the run's schedule, each a TransformStamped stamped from the node clock (so
use_sim_time is honoured): a late tick delays samples but never drops them. The run settings
live in `octoroach_model.run_settings`, the message conversion in `messages`; this module is
the ROS glue between them.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import sys
import time
from typing import Any

from octoroach_model.errors import OctoroachError
from octoroach_model.nodes.common import (
    current_values, declare_parameters, fail, field_specs, node_parser, ParamSpec, ParamValue,
    run_node, set_parameters_callback, split_ros_args, SubscriberWait, UsageError, vicon_qos)
from octoroach_model.nodes.messages import (
    fill_transform, planar_rows, PlanarPose, run_marker, transform_message)
from octoroach_model.run_settings import (
    effect_settings, extension_settings, marker_topic, pose_topic, RunSettings)

__all__ = ['RunSettings', 'Simulator', 'main', 'marker_topic', 'pose_topic',
           'simulator_specs']

SUMMARY = ('ROS node: publishes model-generated VICON poses (geometry_msgs/msg/TransformStamped,'
           ' metres, unit quaternion, heading = yaw) at `rate` Hz, runs one after another with a'
           ' pause and a run marker between them. Every setting is a ROS parameter; changes are'
           ' checked when set and apply from the next run.')
NOTES = """
Effect parameters keep the causes' own keys and units (heading_std_deg is in degrees,
position_std_cm in centimetres, ...); only the ones of the selected `effect` are used.
The same holds for `extension` and its extension_params.* (docs/extensions.md);
run_order_drift places run k of the session at k / (runs - 1), so it needs runs >= 2.
With robots > 1 each robot i is subject SUBJECT_i (segment SEGMENT_i, or SUBJECT_i when
segment is empty) on /vicon/SUBJECT_i/SEGMENT_i with markers on /SUBJECT_i/run_start; all
robots start their runs together. QoS of every topic: reliable, volatile, keep_last 100.
To lose no run, start the recorder first and set wait_subscribers to 1. Params file:
config/simulator.yaml (share/octoroach_model/config when installed).
Example: python -m octoroach_model simulator --ros-args -p robots:=3 -p sigma1:=0.2
"""
TOPICS = (
    ('publishes', '/vicon/SUBJECT/SEGMENT', 'geometry_msgs/msg/TransformStamped, `rate` Hz'),
    ('publishes', '/SUBJECT/run_start', 'std_msgs/msg/UInt32 run index, before each run'),
)


def simulator_specs() -> list[ParamSpec]:
    """
    List the simulator's parameters: RunSettings' fields, the wait, the model's tables.

    The model's defaults come from config/table2.yaml (through RunSettings); the causes' and
    the extension terms' parameters from the model's tables (`run_settings.effect_settings`).
    """
    return [
        *field_specs(RunSettings, ('robots', 'subject', 'segment', 'world_frame', 'rate',
                                   'pause_s', 'runs')),
        *field_specs(SubscriberWait, ('wait_subscribers', 'wait_timeout_s')),
        *field_specs(RunSettings, ('cycles', 'sigma1', 'sigma2', 'stride_frequency', 'draws',
                                   'seed', 'start_x', 'start_y', 'start_heading', 'effect')),
        *(ParamSpec.of(name, default, described)
          for name, (default, described) in effect_settings().items()),
        *field_specs(RunSettings, ('extension',)),
        *(ParamSpec.of(name, default, described)
          for name, (default, described) in extension_settings().items()),
    ]


def _reject_reason(values: dict[str, ParamValue]) -> str | None:
    try:
        RunSettings.from_values(values)
    except OctoroachError as error:
        return str(error)
    return None


try:  # the node class needs rclpy; --help and the settings above do not
    from rclpy.clock import Clock, ClockType
    from rclpy.node import Node
    from rclpy.task import Future
except ImportError:  # pragma: no cover - rclpy missing: main() reports it
    Node = object  # type: ignore[assignment,misc]


@dataclass
class _Robot:
    """The publishers of one robot's subject."""

    subject: str
    poses: Any   # rclpy Publisher of geometry_msgs/msg/TransformStamped
    marker: Any  # rclpy Publisher of std_msgs/msg/UInt32


@dataclass
class _PreparedRun:
    """The next run, drawn during the pause so that its start costs no time."""

    values: dict[str, ParamValue]
    settings: RunSettings
    seed: int
    duration_s: float
    samples: list[list[PlanarPose]]  # per robot, per sample: x, y, qz, qw
    messages: list[Any]              # per robot, a TransformStamped filled at every sample


class Simulator(Node):
    """
    Publishes model runs as VICON poses; see the module docstring.

    Sample k of a run is due at t0 + k / rate on the steady clock (t0: the timer tick after
    the run's marker). Each tick sends every sample due by then, so a late or skipped tick
    delays samples but never drops them or stretches the run; the header stamp of sample k
    is its due time on the node clock.
    """

    def __init__(self, **node_options: Any) -> None:
        super().__init__('simulator', **node_options)
        self._specs = simulator_specs()
        values = declare_parameters(self, self._specs)
        self._settings = RunSettings.from_values(values)
        self.add_on_set_parameters_callback(
            set_parameters_callback(self, self._specs, _reject_reason))
        self.done = Future()
        self._robots: list[_Robot] = []
        self._run: _PreparedRun | None = None
        self._next: _PreparedRun | None = None
        self._in_run = False
        self._sample = 0
        self._t0_ns = 0
        self._run_index = 0
        self._published = 0
        self._created = time.monotonic()
        self._waited = False
        self._build_publishers(self._settings)
        self._pause_left = self._pause_ticks(self._settings)  # discovery time before run 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(1.0 / self._settings.rate, self._tick,
                                        clock=self._steady)
        self.get_logger().info(
            f'publishing {self._settings.robots} robot(s) at {self._settings.rate:g} Hz on '
            f'{", ".join(r.poses.topic_name for r in self._robots[:3])}'
            f'{" ..." if len(self._robots) > 3 else ""}')

    @staticmethod
    def _pause_ticks(settings: RunSettings) -> int:
        return max(1, round(settings.pause_s * settings.rate))

    def _build_publishers(self, settings: RunSettings) -> None:
        from geometry_msgs.msg import TransformStamped
        from std_msgs.msg import UInt32

        for robot in self._robots:
            self.destroy_publisher(robot.poses)
            self.destroy_publisher(robot.marker)
        self._robots = [
            _Robot(subject,
                   self.create_publisher(TransformStamped, pose_topic(subject, segment),
                                         vicon_qos()),
                   self.create_publisher(UInt32, marker_topic(subject), vicon_qos()))
            for subject, segment in settings.subjects()]

    def _tick(self) -> None:
        """One timer period: send the samples due, else prepare / count down / start a run."""
        if self._in_run:
            self._publish_due()
        elif self._pause_left > 1:
            self._pause_left -= 1
            if self._next is None:
                self._next = self._prepare()
        elif self._subscribers_ready():
            self._start_run()

    def _prepare(self) -> _PreparedRun:
        """Draw the next run with the parameters in force now."""
        values = current_values(self, self._specs)
        settings = RunSettings.from_values(values)
        seed = settings.run_seed(self._run_index)
        paths = settings.simulate(seed, self._run_index)
        messages = [transform_message(settings.world_frame, f'vicon/{subject}/{segment}')
                    for subject, segment in settings.subjects()]
        return _PreparedRun(values, settings, seed, float(paths.t[-1]),
                            planar_rows(paths.poses), messages)

    def _publish_due(self) -> None:
        """Send samples self._sample .. (due now) - 1 of every robot, stamped."""
        run = self._run
        assert run is not None
        now_ns = self._steady.now().nanoseconds
        period_ns = 1e9 / self._settings.rate
        samples = len(run.samples[0])
        due = min(samples, int((now_ns - self._t0_ns) / period_ns + 0.1) + 1)
        if due <= self._sample:
            return
        clock_ns = self.get_clock().now().nanoseconds
        for k in range(self._sample, due):
            stamp_ns = clock_ns - (now_ns - (self._t0_ns + round(k * period_ns)))
            for robot, poses, message in zip(self._robots, run.samples, run.messages):
                robot.poses.publish(fill_transform(message, poses[k], stamp_ns))
        self._published += (due - self._sample) * len(self._robots)
        self._sample = due
        if due == samples:
            self._end_run()

    def _subscribers_ready(self) -> bool:
        """Tell whether run 0 may start: `wait_subscribers` matched on every topic, or timeout."""
        if self._waited:
            return True
        wanted = int(self.get_parameter('wait_subscribers').value)
        ready = all(robot.poses.get_subscription_count() >= wanted
                    and robot.marker.get_subscription_count() >= wanted
                    for robot in self._robots)
        timeout = float(self.get_parameter('wait_timeout_s').value)
        if not ready and time.monotonic() - self._created < timeout:
            return False
        if not ready:
            self.get_logger().warning(f'fewer than {wanted} subscriber(s) after {timeout:g} s;'
                                      ' starting anyway')
        self._waited = True
        return True

    def _start_run(self) -> None:
        """Send the markers; the run's first sample goes at the next tick."""
        if self._next is None or self._next.values != current_values(self, self._specs):
            self._next = self._prepare()  # parameters changed during the pause
        run, self._next = self._next, None
        settings = run.settings
        if settings.subjects() != self._settings.subjects():
            self._build_publishers(settings)
        if settings.rate != self._settings.rate:
            self._timer.timer_period_ns = round(1e9 / settings.rate)
        self._settings = settings
        self._run = run
        for robot in self._robots:
            robot.marker.publish(run_marker(self._run_index))
        self._t0_ns = self._steady.now().nanoseconds + self._timer.time_until_next_call()
        self.get_logger().info(
            f'run {self._run_index}: {settings.robots} x {len(run.samples[0])} poses '
            f'({run.duration_s:.2f} s), seed {run.seed}, sigma1 {settings.sigma1:g} rad, '
            f'sigma2 {settings.sigma2:g} rad, draws {settings.draws}, effect {settings.effect}')
        self._in_run = True
        self._sample = 0

    def _end_run(self) -> None:
        self._in_run = False
        self._run_index += 1
        self._pause_left = self._pause_ticks(self._settings)
        runs = int(self.get_parameter('runs').value)
        if runs and self._run_index >= runs:
            from rclpy.duration import Duration

            for robot in self._robots:  # reliable: let subscribers have the last samples
                robot.poses.wait_for_all_acked(Duration(seconds=2.0))
                robot.marker.wait_for_all_acked(Duration(seconds=2.0))
            self.get_logger().info(f'{runs} run(s) published ({self._published} poses); done')
            self._timer.cancel()
            self.done.set_result(0)

    @property
    def published(self) -> int:
        """Poses published so far, all robots."""
        return self._published

    @property
    def run_index(self) -> int:
        """Index of the current (or next) run."""
        return self._run_index

    @property
    def settings(self) -> RunSettings:
        """Return the settings of the current (or last) run."""
        return self._settings


def main(argv: Sequence[str] | None = None) -> int:
    """Run `simulator [--help] [--ros-args ...]`; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        node_parser('simulator', SUMMARY, simulator_specs(), TOPICS, NOTES).parse_args(own)
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error))
    return run_node(Simulator, ros, 'simulator')
