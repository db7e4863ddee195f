"""
Timing of the ROS nodes: simulator rate and jitter, replay -> recorder throughput and loss.

- simulator, 1 and 50 robots at 50 Hz: one run of `--cycles` cycles per robot, received here
  by a raw subscriber; achieved rate = (samples - 1) / (last - first reception) per robot
  (worst robot reported), jitter = p50 / p99 of the inter-message intervals per topic
  (middleware reception times, so this process's own lag does not count).
- simulator -> recorder, live: the same runs recorded by a recorder subscribed to every
  VICON topic; loss = poses and markers sent - messages in the recorded bag.
- replay -> recorder: a bag of `--runs` model runs written offline, replayed at 20x (and
  100x) into a recorder; throughput = messages / replay wall time, loss = messages in the
  bag - messages in the recorded bag.

Each node is its own process (`python -m octoroach_model X`), isolated on a ROS domain of
this benchmark (ROS_DOMAIN_ID from the pid unless set) and on localhost.

Run: ``.venv/bin/python benchmarks/bench_nodes.py [--cycles 20] [--runs 20]``
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

os.environ.setdefault('ROS_DOMAIN_ID', str(1 + (os.getpid() * 7) % 200))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


def _env() -> dict[str, str]:
    env = dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_LOGGING_BUFFERED_STREAM='0')
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH')) if p)
    return env


def _start(name: str, args: list[str], log: Path) -> tuple[subprocess.Popen, Path]:
    stream = log.open('wb')
    process = subprocess.Popen([sys.executable, '-m', 'octoroach_model', name, *args],
                               stdout=stream, stderr=subprocess.STDOUT, env=_env(),
                               stdin=subprocess.DEVNULL, cwd=log.parent)
    return process, log


def bench_simulator(robots: int, cycles: int, workdir: Path) -> dict[str, float]:
    """Achieved rate and jitter of one run of `robots` robots, as received here."""
    import rclpy
    from geometry_msgs.msg import TransformStamped
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import UInt32

    from octoroach_model.nodes.common import vicon_qos

    context = Context()
    rclpy.init(args=[], context=context)
    node = Node('bench_listener', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    received: list[list[int]] = [[] for _ in range(robots)]
    sent: list[list[int]] = [[] for _ in range(robots)]
    subjects = ['octoroach'] if robots == 1 else [f'octoroach_{i}' for i in range(robots)]
    for index, subject in enumerate(subjects):
        def keep(data: bytes, info: dict, times=received[index], sources=sent[index]) -> None:
            times.append(info['received_timestamp'])
            sources.append(info['source_timestamp'])

        node.create_subscription(TransformStamped, f'/vicon/{subject}/{subject}', keep,
                                 vicon_qos(1000), raw=True)
        node.create_subscription(UInt32, f'/{subject}/run_start', lambda data: None,
                                 vicon_qos(), raw=True)
    process, log = _start('simulator', [
        '--ros-args', '-p', f'robots:={robots}', '-p', f'cycles:={cycles}', '-p', 'runs:=1',
        '-p', 'wait_subscribers:=1', '-p', 'seed:=1'], workdir / f'sim{robots}.log')
    expected = int(round(cycles / 2.0 * 50)) + 1
    deadline = time.monotonic() + cycles / 2.0 + 40
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
        if all(len(times) >= expected for times in received):
            break
    process.wait(timeout=30)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    counts = [len(times) for times in received]
    rates, intervals = [], []
    for times in received:
        stamps = np.sort(np.array(times, dtype=np.int64)) / 1e9
        if len(stamps) > 1:
            rates.append((len(stamps) - 1) / (stamps[-1] - stamps[0]))
            intervals.append(np.diff(stamps))
    steps = np.concatenate(intervals) * 1e3
    sent_steps = np.concatenate([np.diff(np.sort(np.array(t, dtype=np.int64)))
                                 for t in sent if len(t) > 1]) / 1e6
    return {'messages': sum(counts), 'expected': expected * robots,
            'rate_hz': min(rates), 'p50_ms': float(np.percentile(steps, 50)),
            'p99_ms': float(np.percentile(steps, 99)), 'max_ms': float(steps.max()),
            'sent_p50_ms': float(np.percentile(sent_steps, 50)),
            'sent_p99_ms': float(np.percentile(sent_steps, 99)), 'log': str(log)}


def _stop_recorder(recorder: subprocess.Popen, log: Path, expected: int, bag: Path) -> int:
    """
    Stop the recorder with SIGINT once it logs `expected` messages (10 s at most).

    Return the message count of the bag it closed.
    """
    import yaml

    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        counts = [int(n) for n in re.findall(r'(\d+) messages recorded', log.read_text())]
        if counts and counts[-1] >= expected:
            break
        time.sleep(0.1)
    recorder.send_signal(signal.SIGINT)
    recorder.wait(timeout=60)
    return int(yaml.safe_load((bag / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']['message_count'])


def bench_replay(rate: float, runs: int, workdir: Path) -> dict[str, float]:
    """Replay a bag of `runs` model runs at `rate` into a recorder; throughput and loss."""
    import yaml

    from octoroach_model import simulate
    from octoroach_model.recordings import write_paths_bag

    source, copy = workdir / f'source_{rate:g}', workdir / f'copy_{rate:g}'
    if not source.exists():
        write_paths_bag(source, simulate(runs, seed=2, cycles=10))
    info = yaml.safe_load((source / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    expected = int(info['message_count'])
    recorder, recorder_log = _start('recorder', ['-o', str(copy), '--ros-args', '-p',
                                                 'log_period_s:=0.5'],
                                    workdir / f'rec{rate:g}.log')
    while 'recording' not in recorder_log.read_text():
        time.sleep(0.05)
    replay, replay_log = _start('replay', [str(source), '--rate', f'{rate:g}',
                                           '--wait-subscribers', '1'],
                                workdir / f'replay{rate:g}.log')
    replay.wait(timeout=600)
    found = re.search(r'published (\d+) messages on \d+ topic\(s\) in ([\d.]+) s',
                      replay_log.read_text())
    published, seconds = (int(found[1]), float(found[2])) if found else (0, float('nan'))
    recorded = _stop_recorder(recorder, recorder_log, expected, copy)
    duration = (int(info['duration']['nanoseconds']) / 1e9) / rate
    return {'messages': expected, 'published': published, 'recorded': recorded,
            'loss': expected - recorded, 'seconds': seconds, 'nominal_s': duration,
            'throughput': published / seconds if seconds else float('nan')}


def bench_live_recording(robots: int, cycles: int, workdir: Path) -> dict[str, float]:
    """Count the messages lost from a simulator of `robots` robots (a run each) to a recorder."""
    copy = workdir / f'live_{robots}'
    topics = '[/vicon/*,/*/run_start]'
    recorder, recorder_log = _start('recorder', ['-o', str(copy), '--ros-args', '-p',
                                                 f'topics:={topics}', '-p',
                                                 'log_period_s:=0.5'],
                                    workdir / f'live_rec{robots}.log')
    while 'recording' not in recorder_log.read_text():
        time.sleep(0.05)
    simulator, _ = _start('simulator', ['--ros-args', '-p', f'robots:={robots}', '-p',
                                        'runs:=1', '-p', f'cycles:={cycles}', '-p', 'seed:=3',
                                        '-p', 'wait_subscribers:=1'],
                          workdir / f'live_sim{robots}.log')
    simulator.wait(timeout=600)
    samples = int(round(cycles / 2.0 * 50)) + 1        # default stride frequency 2 Hz
    expected = robots * (samples + 1)                   # poses and one marker per robot
    recorded = _stop_recorder(recorder, recorder_log, expected, copy)
    return {'expected': expected, 'recorded': recorded, 'loss': expected - recorded}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--cycles', type=int, default=20, help='cycles of the simulated run')
    parser.add_argument('--runs', type=int, default=20, help='runs in the replayed bag')
    parser.add_argument('--robots', type=int, nargs='*', default=[1, 50])
    parser.add_argument('--rates', type=float, nargs='*', default=[20.0, 100.0, 300.0])
    args = parser.parse_args(argv)
    print(f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, {os.cpu_count()} cores')
    with tempfile.TemporaryDirectory(prefix='bench_nodes_') as folder:
        workdir = Path(folder)
        print('\nsimulator (nominal 50 Hz), as received by a raw subscriber')
        print('(intervals: received = middleware reception here; sent = source timestamps)')
        print(f'{"robots":>6} {"messages":>13} {"worst rate Hz":>13} {"of nominal":>10} '
              f'{"recv p50":>8} {"recv p99":>8} {"recv max":>8} {"sent p50":>8} '
              f'{"sent p99":>8}  (ms)')
        for robots in args.robots:
            r = bench_simulator(robots, args.cycles, workdir)
            print(f'{robots:>6} {r["messages"]:>6}/{r["expected"]:<6} {r["rate_hz"]:>13.3f} '
                  f'{r["rate_hz"] / 50.0:>10.2%} {r["p50_ms"]:>8.2f} {r["p99_ms"]:>8.2f} '
                  f'{r["max_ms"]:>8.2f} {r["sent_p50_ms"]:>8.2f} {r["sent_p99_ms"]:>8.2f}')
        print('\nsimulator -> recorder, live (one run per robot)')
        print(f'{"robots":>6} {"messages":>8} {"recorded":>8} {"loss":>5}')
        for robots in args.robots:
            r = bench_live_recording(robots, args.cycles, workdir)
            print(f'{robots:>6} {r["expected"]:>8} {r["recorded"]:>8} {r["loss"]:>5}')
        print('\nreplay -> recorder')
        print(f'{"rate":>5} {"messages":>8} {"recorded":>8} {"loss":>5} {"wall s":>7} '
              f'{"nominal s":>9} {"msg/s":>8}')
        for rate in args.rates:
            r = bench_replay(rate, args.runs, workdir)
            print(f'{rate:>4g}x {r["messages"]:>8} {r["recorded"]:>8} {r["loss"]:>5} '
                  f'{r["seconds"]:>7.2f} {r["nominal_s"]:>9.2f} {r["throughput"]:>8.0f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
