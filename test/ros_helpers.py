"""
Node processes for end-to-end tests: isolated ROS env, stop by signal, logs on failure.

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

from collections.abc import Callable
from dataclasses import dataclass
import itertools
import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import threading
import time
from typing import Any

REPO = Path(__file__).resolve().parents[1]


_NODE_SETS = itertools.count()


def fresh_domain() -> int:
    """
    Pick a ROS domain for one test's node processes, not this process's own one.

    Derived from this process's domain (pid and worker, see conftest.py), so in-process rclpy
    tests of the same worker (their participants may outlive a test until garbage
    collection) and earlier tests' processes are never heard.
    """
    base = int(os.environ['ROS_DOMAIN_ID'])
    return 1 + (base - 1 + 100 + 23 * next(_NODE_SETS)) % 200


def ros_env(domain: int | None = None, **extra: str) -> dict[str, str]:
    """Return a node process's environment: ROS isolation (localhost, `domain`), plain logs."""
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
    """
    Node processes of one test, on a ROS domain of their own (`domain`).

    Pass the domain to `call_trigger`; whatever is still running at the end is killed.
    """

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
    """
    Call a std_srvs/Trigger service on `domain` from a throwaway rclpy context.

    Return (success, message).
    """
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


# -- a client in its own context ------------------------------------------------------------


class Client:
    """
    Service calls and subscriptions from a node of this test, spun on its own thread.

    `domain`: the ROS domain of the nodes to talk to (NodeSet.domain for node processes);
    default this process's own.
    """

    def __init__(self, domain: int | None = None) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context = Context()
        rclpy.init(args=[], context=self.context,
                   domain_id=int(os.environ['ROS_DOMAIN_ID']) if domain is None else domain)
        self.node = Node('validator_test_client', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._clients: dict[str, Any] = {}
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def client(self, srv_type: Any, name: str, timeout: float = 20.0) -> Any:
        if name not in self._clients:
            client = self.node.create_client(srv_type, name)
            if not client.wait_for_service(timeout_sec=timeout):
                seen = sorted(n for n, _ in self.node.get_service_names_and_types())
                raise AssertionError(f'service {name} did not appear within {timeout:g} s '
                                     f'(ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID")}; '
                                     f'services seen: {seen})')
            self._clients[name] = client
        return self._clients[name]

    def start(self, srv_type: Any, name: str, request: Any = None) -> Call:
        """Send a request; the Call records when the answer arrived."""
        client = self.client(srv_type, name)
        call = Call(time.perf_counter())
        call.future = client.call_async(request or srv_type.Request())
        call.future.add_done_callback(call.arrived)
        return call

    def call(self, srv_type: Any, name: str, request: Any = None,
             timeout: float = 60.0) -> tuple[Any, float]:
        """(response, seconds from request to answer)."""
        call = self.start(srv_type, name, request)
        return call.wait(timeout), call.seconds

    def call_again_if_lost(self, srv_type: Any, name: str, request: Any,
                           timeout: float = 60.0, resend_s: float = 10.0) -> tuple[Any, float]:
        """
        Call an idempotent service, sending again while no answer comes.

        A request sent just after `wait_for_service` can be lost while the server's
        response writer has not yet matched this client (DDS discovery runs on): once, under
        the full suite's load, a parameter query of a freshly launched node went unanswered
        for 60 s. Only for calls that may safely run twice (parameter get and set).
        """
        deadline = time.perf_counter() + timeout
        while True:
            call = self.start(srv_type, name, request)
            left = deadline - time.perf_counter()
            if call.answered_within(max(min(resend_s, left), 0.0)):
                return call.future.result(), call.seconds
            assert time.perf_counter() < deadline, f'no answer within {timeout:g} s'

    def trigger(self, name: str, timeout: float = 60.0) -> tuple[bool, dict, float]:
        """(success, parsed JSON message, seconds) of a Trigger call."""
        from std_srvs.srv import Trigger

        response, seconds = self.call(Trigger, name, timeout=timeout)
        return response.success, json.loads(response.message), seconds

    def get_parameter(self, node: str, name: str) -> tuple[Any, float]:
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import Parameter

        response, seconds = self.call_again_if_lost(GetParameters, f'/{node}/get_parameters',
                                                    GetParameters.Request(names=[name]))
        return Parameter.from_parameter_msg(_msg(name, response.values[0])).value, seconds

    def set_parameter(self, node: str, name: str, value: Any) -> tuple[Any, float]:
        """(SetParametersResult, seconds)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        response, seconds = self.call_again_if_lost(SetParameters, f'/{node}/set_parameters',
                                                    request)
        return response.results[0], seconds

    def latched(self, topic: str, timeout: float = 10.0) -> Any:
        """First message of a transient_local topic, subscribing only now."""
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        got: list[Any] = []
        arrived = threading.Event()
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

        def keep(msg: Any) -> None:
            got.append(msg)
            arrived.set()

        subscription = self.node.create_subscription(DiagnosticArray, topic, keep, qos)
        try:
            assert arrived.wait(timeout), f'nothing latched on {topic} within {timeout:g} s'
            return got[0]
        finally:
            self.node.destroy_subscription(subscription)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown()
        self._thread.join(timeout=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.context.destroy()


def _msg(name: str, value: Any) -> Any:
    from rcl_interfaces.msg import Parameter as ParameterMsg

    return ParameterMsg(name=name, value=value)


class Call:
    """One request in flight."""

    def __init__(self, sent: float) -> None:
        self.sent = sent
        self.answered: float | None = None
        self.future: Any = None
        self._event = threading.Event()

    def arrived(self, future: Any) -> None:
        self.answered = time.perf_counter()
        self._event.set()

    @property
    def seconds(self) -> float:
        assert self.answered is not None
        return self.answered - self.sent

    def done(self) -> bool:
        return self._event.is_set()

    def answered_within(self, timeout: float) -> bool:
        return self._event.wait(timeout)

    def wait(self, timeout: float) -> Any:
        assert self._event.wait(timeout), f'no answer within {timeout:g} s'
        return self.future.result()


# -- launch files ---------------------------------------------------------------------------

@dataclass(frozen=True)
class LaunchedNode:
    """One <node> of a launch file as the command line `ros2 launch` would start it."""

    executable: str
    name: str
    arguments: tuple[str, ...]  # '--ros-args' and the node's ROS arguments

    def start(self, nodes: NodeSet) -> NodeProcess:
        """Start it as `python -m octoroach_model EXECUTABLE --ros-args ...` in `nodes`."""
        return nodes.start(self.executable, *self.arguments)


_SUBSTITUTION = re.compile(r'\$\((var|find-pkg-share) ([A-Za-z0-9_]+)\)')


def read_launch_file(path: Path, share: Path, package: str = 'octoroach_model',
                     **arguments: str) -> list[LaunchedNode]:
    """
    Read the nodes of an XML launch file, with the parameters files and remappings it names.

    `share` stands for `$(find-pkg-share PACKAGE)` (the checkout: its config/ and launch/ are
    laid out as in share/PACKAGE); launch arguments take their defaults unless given. Only the
    subset of the launch XML format that this package uses is understood (arg, node with
    ros_args, param from=..., param name=/value=, remap; substitutions var and
    find-pkg-share); anything
    else fails the test, so the launch file cannot say more than the test checks. As
    launch_ros does, name/value parameters come after the parameters files and win.
    """
    import xml.etree.ElementTree as ElementTree

    root = ElementTree.parse(path).getroot()
    assert root.tag == 'launch', f'{path}: root element is {root.tag}, not launch'
    values: dict[str, str] = {}

    def substitute(text: str) -> str:
        def one(match: re.Match[str]) -> str:
            kind, name = match.groups()
            if kind == 'var':
                assert name in values, f'{path}: $(var {name}) is not a declared <arg>'
                return values[name]
            assert name == package, f'{path}: $(find-pkg-share {name}) is another package'
            return str(share)
        return _SUBSTITUTION.sub(one, text)

    launched = []
    for element in root:
        if element.tag == 'arg':
            name = element.attrib['name']
            values[name] = arguments.get(name, element.attrib.get('default', ''))
            continue
        assert element.tag == 'node', f'{path}: <{element.tag}> is not understood here'
        assert set(element.attrib) <= {'pkg', 'exec', 'name', 'output', 'ros_args'}, \
            element.attrib
        assert element.attrib['pkg'] == package, element.attrib
        files: list[str] = []
        rules: list[str] = []
        for child in element:
            if child.tag == 'param' and 'from' in child.attrib:
                files += ['--params-file', substitute(child.attrib['from'])]
            elif child.tag == 'param':
                rules += ['-p', f'{child.attrib["name"]}:={substitute(child.attrib["value"])}']
            elif child.tag == 'remap':
                rules += ['-r', f'{substitute(child.attrib["from"])}:='
                                f'{substitute(child.attrib["to"])}']
            else:
                raise AssertionError(f'{path}: <{child.tag}> in a node is not understood here')
        name = element.attrib.get('name', element.attrib['exec'])
        extra = substitute(element.attrib.get('ros_args', '')).split()
        launched.append(LaunchedNode(
            element.attrib['exec'], name,
            ('--ros-args', '-r', f'__node:={name}', *extra, *files, *rules)))
    return launched


class InProcessValidator:
    """A Validator spun as `main` spins it (MultiThreadedExecutor), in a context of its own."""

    def __init__(self, values: dict[str, Any]) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.parameter import Parameter

        from octoroach_model.nodes import validator

        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = validator.Validator(
            context=self.context,
            parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
        self.executor = MultiThreadedExecutor(num_threads=validator.EXECUTOR_THREADS,
                                              context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def close(self) -> None:
        import rclpy

        self.node.stop_jobs()
        self.executor.shutdown(timeout_sec=10)
        self._thread.join(timeout=10)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.context.destroy()
