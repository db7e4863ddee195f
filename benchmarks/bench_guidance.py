"""
How soon the validator's live guidance follows a new run, on a bag as a recorder grows it.

For each session size N: a bag is written run by run (TransformStamped on the VICON topic, a
run marker before each run, flushed after each run as the recorder flushes), the validator
runs as its own process on it (`python -m octoroach_model validator`, as deployed) with
`question:=TERM question_size:=SIZE` (`--question`, default persistent_turning=3; the
runs carry that effect at that size), and once its guidance stands at N runs,
`--new-runs` more runs are written one at a time. Measured for each, from the flush that put
the run on disk: to the first guidance that counts it arriving at a subscriber in this
process (latched ~/guidance: the count and the runs still needed, carried at once), and to
the guidance of the look taken on it (`decision_runs`); and the time the look itself took
(`decided_in_s`). The first fit of the baseline (in the node's worker process) is timed too.

Isolated on a ROS domain of this benchmark and on localhost. Run:
``.venv/bin/python benchmarks/bench_guidance.py [--runs 100 300 500] [--new-runs 5]
[--question TERM=SIZE]``
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

os.environ.setdefault('ROS_DOMAIN_ID', str(1 + (os.getpid() * 11) % 200))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


class Listener:
    """A subscriber to the latched ~/guidance, in a context of its own, on a thread."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = Node('bench_guidance_listener', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.messages: list[tuple[float, dict[str, str]]] = []
        self.arrived = threading.Condition()
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(DiagnosticArray, '/validator/guidance', self._keep, qos)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def _keep(self, message: Any) -> None:
        values = {kv.key: kv.value for kv in message.status[0].values}
        with self.arrived:
            self.messages.append((time.monotonic(), values))
            self.arrived.notify_all()

    def wait(self, condition: Any, timeout: float) -> tuple[float, dict[str, str]]:
        """Return the first message (arrival time, values) satisfying `condition`."""
        deadline = time.monotonic() + timeout
        with self.arrived:
            while True:
                for arrival, values in self.messages:
                    if condition(values):
                        return arrival, values
                left = deadline - time.monotonic()
                if left <= 0:
                    raise SystemExit(f'error: no matching guidance within {timeout:g} s')
                self.arrived.wait(left)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown()
        self.thread.join(timeout=10)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.context.destroy()


def session(runs: int, new_runs: int, listener: Listener, folder: Path, term: str,
            size: float) -> dict[str, Any]:
    """Grow a bag to `runs` runs, start the validator on it, then add runs one at a time."""
    import octoroach_model as om
    from octoroach_model.recordings.standard_bag.pose_writer import PoseBagWriter
    from octoroach_model.studies.terms import term_values

    effects = {term: term_values(term, size, {}, 5.0)}
    paths = om.simulate(runs + new_runs, seed=runs, effects=effects)
    period_ns = int(round(float(paths.t[-1]) * 1e9)) + 1_000_000_000
    bag = folder / f'session_{runs}'
    listener.messages.clear()
    with PoseBagWriter(bag) as writer:
        def write(run: int) -> None:
            stamps = 1_000_000_000_000 + run * period_ns + np.round(
                (paths.t - paths.t[0]) * 1e9).astype(np.int64)
            writer.write_marker(run, int(stamps[0]))
            writer.write_poses(stamps, paths.poses[run])
            writer._bag.flush()       # what the recorder does every flush_period_s

        for run in range(runs):
            write(run)
        env = dict(os.environ, PYTHONUNBUFFERED='1')
        started = time.monotonic()
        node = subprocess.Popen(
            [sys.executable, '-m', 'octoroach_model', 'validator', '--ros-args', '-p',
             f'bags:=[{bag}]', '-p', f'question:={term}', '-p',
             f'question_size:={size!r}', '-p', 'guidance_period_s:=0.1'],
            cwd=folder, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            first, _ = listener.wait(lambda v: v['runs'] == str(runs) and v['status'] not in (
                'fitting', 'waiting'), 600)
            latencies, decisions, looks = [], [], []
            for run in range(runs, runs + new_runs):
                time.sleep(1.0)                       # runs come seconds apart
                write(run)
                flushed = time.monotonic()
                arrival, _ = listener.wait(lambda v, n=run + 1: v['runs'] == str(n), 60)
                decided, values = listener.wait(
                    lambda v, n=run + 1: v.get('decision_runs') == str(n), 60)
                latencies.append(arrival - flushed)
                decisions.append(decided - flushed)
                looks.append(float(values.get('decided_in_s', 'nan')))
        finally:
            node.send_signal(signal.SIGINT)
            node.wait(timeout=60)
    return {'runs': runs, 'first_s': first - started, 'latencies': latencies,
            'decisions': decisions, 'looks': looks}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--runs', type=int, nargs='+', default=[100, 300, 500])
    parser.add_argument('--new-runs', type=int, default=5)
    parser.add_argument('--question', default='persistent_turning=3',
                        help='TERM=SIZE: the question, and the effect put into the runs')
    args = parser.parse_args(argv)
    term, _, size = args.question.partition('=')
    listener = Listener()
    results = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            for runs in args.runs:
                results.append(session(runs, args.new_runs, listener, Path(folder), term,
                                       float(size)))
                print(f'{runs} runs done', file=sys.stderr, flush=True)
    finally:
        listener.close()
    print(f'question {term} = {size}, the effect at that size in the runs\n')
    print('| runs in the bag | first guidance after start, s | a new run to the guidance that '
          'counts it, s (median / max) | to the look on it, s (median / max) | the look '
          'itself, s (median) |')
    print('| --- | --- | --- | --- | --- |')
    for result in results:
        latency, decision = np.array(result['latencies']), np.array(result['decisions'])
        print(f'| {result["runs"]} | {result["first_s"]:.1f} | {np.median(latency):.2f} / '
              f'{latency.max():.2f} | {np.median(decision):.2f} / {decision.max():.2f} | '
              f'{np.median(result["looks"]):.2f} |')
    load = os.getloadavg()[0]
    print(f'\nload average (1 min) at the end: {load:.2f} on {os.cpu_count()} cores')
    return 0


if __name__ == '__main__':
    sys.exit(main())
