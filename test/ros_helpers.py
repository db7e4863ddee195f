"""Node processes for end-to-end tests: isolated ROS env, stop by signal, logs on failure.

Every node runs as `python -m octoroach_model NAME ARGS` in its own process, with the test
process's ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (set per pytest process in
conftest.py) passed explicitly, so parallel workers never hear each other. Output goes to a
log file (no pipe to fill up); `NodeProcess.log` is what a failing assertion should show.

    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(bag))
        nodes.start('simulator', '--ros-args', '-p', 'runs:=2').wait(timeout=30)
        assert recorder.stop() == 0, recorder.log
"""
from __future__ import annotations

import itertools
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


_NODE_SETS = itertools.count()


def fresh_domain() -> int:
    """A ROS domain for one test's node processes, not this process's own one.

    Derived from this process's domain (pid and worker, see conftest.py), so in-process rclpy
    tests of the same worker (their participants may outlive a test until garbage
    collection) and earlier tests' processes are never heard.
    """
    base = int(os.environ['ROS_DOMAIN_ID'])
    return 1 + (base - 1 + 100 + 23 * next(_NODE_SETS)) % 200


def ros_env(domain: int | None = None, **extra: str) -> dict[str, str]:
    """The environment for a node process: ROS isolation (localhost, `domain`), plain logs."""
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain if domain is not None else os.environ['ROS_DOMAIN_ID'])
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    env['PYTHONUNBUFFERED'] = '1'
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH')) if p)
    env.update(extra)
    return env


def wait_until(condition: Callable[[], object], timeout: float, what: str,
               period: float = 0.05) -> object:
    """Poll `condition` until it returns something truthy; AssertionError after `timeout`."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out after {timeout:g} s waiting for {what}')
        time.sleep(period)


class NodeProcess:
    """One `python -m octoroach_model NAME ...` process with its output in a log file."""

    def __init__(self, name: str, args: list[str], log_dir: Path,
                 env: dict[str, str] | None = None) -> None:
        self.name = name
        self.log_path = log_dir / f'{name}-{time.monotonic_ns()}.log'
        self._log_file = self.log_path.open('wb')
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'octoroach_model', name, *args], cwd=log_dir,
            env=env or ros_env(), stdout=self._log_file, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL)

    @property
    def log(self) -> str:
        """Everything the process printed so far (stdout and stderr)."""
        if not self._log_file.closed:
            self._log_file.flush()
        return f'--- {self.name} log ---\n' + self.log_path.read_text(errors='replace')

    def wait_for_log(self, pattern: str, timeout: float = 60.0) -> re.Match[str]:
        """First match of regex `pattern` in the output, waiting for it to appear."""
        def find() -> re.Match[str] | None:
            if self.process.poll() is not None and not re.search(pattern, self.log):
                raise AssertionError(f'{self.name} exited ({self.process.returncode}) before '
                                     f'printing {pattern!r}\n{self.log}')
            return re.search(pattern, self.log)

        try:
            return wait_until(find, timeout, f'{self.name} to print {pattern!r}')
        except AssertionError as error:
            raise AssertionError(f'{error}\n{self.log}') from None

    def matches(self, pattern: str) -> list[str]:
        """All matches of `pattern` (its first group if it has one) in the output so far."""
        return re.findall(pattern, self.log)

    def wait(self, timeout: float) -> int:
        """Exit code, waiting up to `timeout` s for the process to end by itself."""
        try:
            return self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f'{self.name} still running after {timeout:g} s\n{self.log}')

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send `sig` and wait for the exit code (killed after `timeout`)."""
        if self.process.poll() is None:
            self.process.send_signal(sig)
        return self.wait(timeout)

    def kill(self) -> None:
        """SIGKILL, as a crash would."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(timeout=10)
        self._log_file.close()


class NodeSet:
    """Node processes of one test, on a ROS domain of their own (`domain`; pass it to
    `call_trigger`); whatever is still running at the end is killed."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.domain = fresh_domain()
        self.nodes: list[NodeProcess] = []

    def start(self, name: str, *args: str, env: dict[str, str] | None = None) -> NodeProcess:
        node = NodeProcess(name, list(args), self.log_dir, env or ros_env(self.domain))
        self.nodes.append(node)
        return node

    def logs(self) -> str:
        """All logs, for assertion messages."""
        return '\n'.join(node.log for node in self.nodes)

    def __enter__(self) -> NodeSet:
        return self

    def __exit__(self, *exc_info: object) -> None:
        for node in self.nodes:
            node.kill()


def call_trigger(service: str, domain: int, timeout: float = 20.0) -> tuple[bool, str]:
    """Call a std_srvs/Trigger service on `domain` from a throwaway rclpy context:
    (success, message)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    context = Context()
    rclpy.init(args=[], context=context, domain_id=domain)
    node = Node('trigger_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        client = node.create_client(Trigger, service)
        if not client.wait_for_service(timeout_sec=timeout):
            raise AssertionError(f'service {service} did not appear within {timeout:g} s')
        future = client.call_async(Trigger.Request())
        rclpy.spin_until_future_complete(node, future, executor=executor, timeout_sec=timeout)
        if not future.done():
            raise AssertionError(f'service {service} did not answer within {timeout:g} s')
        response = future.result()
        return bool(response.success), str(response.message)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        context.destroy()
