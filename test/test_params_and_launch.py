"""
Params files (config/NODE.yaml) and the launch file (launch/octoroach.launch.xml).

There is no `ros2 launch` on PyPI, so the launch test reads the launch file, starts exactly the
nodes it names with the parameters files and remappings it names (`read_launch_file`), and
checks that the graph comes up as the file promises: topics, the validator's services, the
parameters in force. Every node is its own process on a ROS domain of the test's own.
"""
from __future__ import annotations

import math
import signal
from typing import Any

import pytest
import yaml

pytest.importorskip('rclpy')

from octoroach_model.nodes import recorder, replay, simulator, validator  # noqa: E402

from ros_helpers import Client, NodeSet, read_launch_file, REPO, wait_until  # noqa: E402

LAUNCH_FILE = REPO / 'launch' / 'octoroach.launch.xml'
SPECS = {
    'simulator': simulator.simulator_specs(),
    'recorder': recorder.recorder_specs(),
    'validator': [*validator.ARRAYS, *validator.validator_specs()],
    'replay': replay.replay_specs(),
}


def flatten(parameters: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested params-file keys as ROS names (effect_params: {x: 1} -> effect_params.x)."""
    flat: dict[str, Any] = {}
    for key, value in parameters.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f'{prefix}{key}.'))
        else:
            flat[f'{prefix}{key}'] = value
    return flat


def params_file(node: str) -> dict[str, Any]:
    """Read the parameters of config/NODE.yaml, checked for the ROS params-file shape."""
    content = yaml.safe_load((REPO / 'config' / f'{node}.yaml').read_text())
    assert list(content) == [node], f'config/{node}.yaml must hold only `{node}:`'
    assert list(content[node]) == ['ros__parameters'], content[node].keys()
    return flatten(content[node]['ros__parameters'])


@pytest.mark.parametrize('node', sorted(SPECS))
def test_params_file_holds_every_parameter_at_its_default(node):
    values = params_file(node)
    specs = SPECS[node]

    assert list(values) == [spec.name for spec in specs]   # all of them, in --help order
    for spec in specs:
        value = values[spec.name]
        assert type(value) is type(spec.default), (spec.name, value, spec.default)  # 50.0
        if isinstance(value, float):
            assert value == spec.default or math.isclose(value, spec.default, rel_tol=1e-15)
        else:
            assert value == spec.default, spec.name


def test_the_paper_values_in_the_simulator_file_are_the_models():
    from octoroach_model.model import ModelParameters, nominal_sigmas

    values = params_file('simulator')
    nominal = ModelParameters.nominal()
    assert (values['sigma1'], values['sigma2']) == nominal_sigmas()
    assert values['stride_frequency'] == nominal.stride_frequency
    assert values['rate'] == nominal.sample_rate


def test_launch_file_starts_simulator_recorder_and_validator_and_the_graph_comes_up(
        tmp_path, client_on):
    launched = read_launch_file(LAUNCH_FILE, REPO)
    assert sorted(n.executable for n in launched) == ['recorder', 'simulator', 'validator']
    with NodeSet(tmp_path) as nodes:
        processes = {n.name: n.start(nodes) for n in launched}
        client = client_on(nodes.domain)

        def graph() -> tuple[dict[str, list[str]], set[str]]:
            return (dict(client.node.get_topic_names_and_types()),
                    {name for name, _ in client.node.get_service_names_and_types()})

        wanted_topics = {
            '/vicon/octoroach/octoroach': ['geometry_msgs/msg/TransformStamped'],
            '/octoroach/run_start': ['std_msgs/msg/UInt32'],
            '/validator/violation': ['diagnostic_msgs/msg/DiagnosticArray']}
        wanted_services = {'/validator/validate', '/validator/diagnose', '/recorder/export'}

        def up() -> bool:
            topics, services = graph()
            return (all(topics.get(t) == types for t, types in wanted_topics.items())
                    and wanted_services <= services)

        wait_until(up, 60, f'the launched graph\n{graph()}\n{nodes.logs()}')
        # the parameters of the launch file are in force, over the params files' defaults
        assert client.get_parameter('validator', 'bags')[0] == ['octoroach_runs']
        assert client.get_parameter('validator', 'min_duration_s')[0] == 4.9
        assert client.get_parameter('validator', 'rho')[0] == 0.35
        assert client.get_parameter('recorder', 'output')[0] == 'octoroach_runs'
        assert client.get_parameter('simulator', 'wait_subscribers')[0] == 1
        # the simulator waited for the recorder: run 0 goes to the bag
        processes['recorder'].wait_for_log(r'recording /vicon/octoroach/octoroach', 30)
        processes['simulator'].wait_for_log(r'run 0: 1 x 251 poses', 30)
        for name in ('simulator', 'validator', 'recorder'):
            assert processes[name].stop(signal.SIGINT) == 0, nodes.logs()
    assert (tmp_path / 'octoroach_runs' / 'metadata.yaml').is_file(), nodes.logs()


def test_replay_params_file_loads_and_a_flag_beats_its_default(tmp_path):
    """replay.yaml says bag: '' (the default); the BAG argument on the command line wins."""
    from octoroach_model import simulate
    from octoroach_model.recordings import write_paths_bag

    bag = tmp_path / 'two_runs'
    write_paths_bag(bag, simulate(2, seed=3, cycles=1))
    with NodeSet(tmp_path) as nodes:
        played = nodes.start('replay', str(bag), '--rate', '20.0', '--ros-args',
                             '--params-file', str(REPO / 'config' / 'replay.yaml'))
        assert played.wait(timeout=60) == 0, played.log
    assert played.matches(r'published (\d+) messages') == ['54'], played.log


@pytest.mark.parametrize(('line', 'message'), [
    ('rate: 50', 'error: rate must be a double, got 50 (write doubles with a decimal point, '
                 'e.g. 50.0)'),
    ('sigma1: 5.0', 'error: sigma1 = 5.0 rad is outside [0, 1.5)'),
])
def test_a_bad_value_in_a_params_file_is_one_error_line(tmp_path, line, message):
    bad = tmp_path / 'simulator.yaml'
    bad.write_text(f'simulator:\n  ros__parameters:\n    {line}\n')
    with NodeSet(tmp_path) as nodes:
        node = nodes.start('simulator', '--ros-args', '--params-file', str(bad))
        assert node.wait(timeout=60) == 2, node.log
    assert node.log.strip().splitlines()[-1] == message, node.log
    assert 'Traceback' not in node.log


@pytest.fixture
def client_on():
    """Clients on the domain of a NodeSet, closed after the test."""
    made: list[Client] = []

    def make(domain: int) -> Client:
        made.append(Client(domain))
        return made[-1]

    yield make
    for client in made:
        client.close()


def test_the_ros_docs_list_every_parameter_of_every_node():
    text = (REPO / 'docs' / 'ros.md').read_text()
    for node, specs in SPECS.items():
        assert f'config/{node}.yaml' in text, node
        missing = [spec.name for spec in specs if f'| `{spec.name}` |' not in text]
        assert not missing, f'docs/ros.md lacks {node} parameters {missing}'


def test_the_validator_starts_on_its_params_file_alone_with_no_bags(tmp_path, client_on):
    """`bags: []` in a params file is an unset string array, as the node's own default."""
    with NodeSet(tmp_path) as nodes:
        node = nodes.start('validator', '--ros-args', '--params-file',
                           str(REPO / 'config' / 'validator.yaml'))
        node.wait_for_log(r'ready: 0 source\(s\) in bags')
        client = client_on(nodes.domain)
        assert client.get_parameter('validator', 'k')[0] == 11
        ok, answer, _ = client.trigger('/validator/validate')
        assert not ok and 'set the parameter bags' in answer['error']
        assert node.stop(signal.SIGTERM) == 0, node.log
