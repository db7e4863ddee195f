"""
Latency of the validator node's answers while a long validation runs.

The node runs as its own process (`python -m octoroach_model validator`), as deployed; this
process sends the requests from a client node spun on a background thread. Measured from
`call_async` to the response callback:

- idle: get_parameters, and ~/validate with no `bags` (answers at once with an error), i.e.
  the round trip of a Trigger call without work;
- busy: while a validation of `--runs` model runs on a `--grid-points`^2 search runs,
  get_parameters, set_parameters and a second ~/validate (which answers "busy").

Isolated on a ROS domain of this benchmark (ROS_DOMAIN_ID from the pid unless set) and on
localhost. Run: ``.venv/bin/python benchmarks/bench_validator_busy.py [--samples 50]``
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import re
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

os.environ.setdefault('ROS_DOMAIN_ID', str(1 + (os.getpid() * 7) % 200))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


def _env() -> dict[str, str]:
    env = dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_LOGGING_BUFFERED_STREAM='0')
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH')) if p)
    return env


class Client:
    """A client node in its own context; calls are timed from send to response callback."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = Node('bench_validator_client', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.clients: dict[str, Any] = {}
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def start(self, srv_type: Any, name: str, request: Any) -> dict[str, Any]:
        """Send; the returned dict gets 'seconds' and 'response' when the answer arrives."""
        if name not in self.clients:
            client = self.node.create_client(srv_type, name)
            if not client.wait_for_service(timeout_sec=30):
                raise SystemExit(f'error: service {name} did not appear')
            self.clients[name] = client
        call: dict[str, Any] = {'event': threading.Event()}

        def arrived(future: Any) -> None:
            call['seconds'] = time.perf_counter() - call['sent']
            call['response'] = future.result()
            call['event'].set()

        call['sent'] = time.perf_counter()
        self.clients[name].call_async(request).add_done_callback(arrived)
        return call

    def call(self, srv_type: Any, name: str, request: Any, timeout: float = 30) -> dict:
        call = self.start(srv_type, name, request)
        if not call['event'].wait(timeout):
            raise SystemExit(f'error: {name} did not answer within {timeout} s')
        return call

    def close(self) -> None:
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def requests() -> dict[str, tuple[Any, str, Any]]:
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter
    from std_srvs.srv import Trigger

    return {
        'get_parameters': (GetParameters, '/validator/get_parameters',
                           GetParameters.Request(names=['rho', 'k'])),
        'set_parameters': (SetParameters, '/validator/set_parameters', SetParameters.Request(
            parameters=[Parameter('seed', value=1).to_parameter_msg()])),
        '~/validate': (Trigger, '/validator/validate', Trigger.Request()),
    }


def wait_for(log: Path, pattern: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not re.search(pattern, log.read_text(errors='replace')):
        if time.monotonic() > deadline:
            raise SystemExit(f'error: no {pattern!r} in the node log:\n{log.read_text()}')
        time.sleep(0.05)


def sample(client: Client, kinds: list[str], samples: int, pause_s: float,
           while_running: dict | None = None) -> dict[str, list[float]]:
    """Interleaved calls of every kind; stops early if the running job ends."""
    calls = requests()
    seconds: dict[str, list[float]] = {kind: [] for kind in kinds}
    for _ in range(samples):
        for kind in kinds:
            if while_running is not None and while_running['event'].is_set():
                return seconds
            call = client.call(*calls[kind])
            if kind == '~/validate' and while_running is not None:
                message = json.loads(call['response'].message)
                assert message['error'].startswith('busy'), message
            seconds[kind].append(call['seconds'])
            time.sleep(pause_s)
    return seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--samples', type=int, default=50, help='calls per kind and state')
    parser.add_argument('--runs', type=int, default=200, help='model runs in the data set')
    parser.add_argument('--grid-points', type=int, default=101,
                        help='search grid per spread: the job must outlast the samples')
    parser.add_argument('--pause-s', type=float, default=0.02, help='pause between calls')
    args = parser.parse_args()

    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    import octoroach_model as om
    from octoroach_model.recordings import save_dataset

    with tempfile.TemporaryDirectory() as tmp:
        data = save_dataset(Path(tmp) / 'runs.npz', om.simulate(args.runs, seed=2))
        log = Path(tmp) / 'validator.log'
        command = [sys.executable, '-m', 'octoroach_model', 'validator', '--ros-args',
                   '-p', 'epsilon:=0.3', '-p', 'delta:=0.3', '-p', 'k:=4',
                   '-p', f'grid_points:={args.grid_points}', '-p', 'nominal:=table2']
        with log.open('wb') as out:
            node = subprocess.Popen(command, env=_env(), stdout=out, stderr=subprocess.STDOUT)
        client = Client()
        try:
            wait_for(log, 'ready', 30)
            idle = sample(client, ['get_parameters', '~/validate'], args.samples, args.pause_s)
            client.call(SetParameters, '/validator/set_parameters', SetParameters.Request(
                parameters=[Parameter('bags', value=[str(data)]).to_parameter_msg()]))
            calls = requests()
            started = time.monotonic()
            long_call = client.start(*calls['~/validate'])
            wait_for(log, r'validation +[0-9.]+%: sigma search', 120)
            busy = sample(client, list(calls), args.samples, args.pause_s, long_call)
            finished = long_call['event'].wait(600)
            job_s = time.monotonic() - started
        finally:
            client.close()
            node.send_signal(signal.SIGINT)
            code = node.wait(timeout=30)

    print(f'validator answers while a validation runs ({args.runs} runs, '
          f'{args.grid_points}x{args.grid_points} grid, n = 11, k = 4; the job took '
          f'{job_s:.1f} s{"" if finished else ", unfinished"}; node exit code {code}; '
          f'{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f})')
    print(f'{"request":<16} {"state":<6} {"samples":>7} {"p50 ms":>8} {"p99 ms":>8} '
          f'{"max ms":>8}')
    for state, table in (('idle', idle), ('busy', busy)):
        for kind, values in table.items():
            ms = np.array(values) * 1000
            note = ' (no bags: immediate error)' if state == 'idle' and kind == '~/validate' \
                else ' (answers busy)' if kind == '~/validate' else ''
            print(f'{kind:<16} {state:<6} {len(ms):>7} {np.percentile(ms, 50):>8.1f} '
                  f'{np.percentile(ms, 99):>8.1f} {ms.max():>8.1f}{note}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
