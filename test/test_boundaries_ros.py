"""
ROS parameters reach no further than the operator allowed; every caller gets an answer.

Real nodes over DDS (a validator spun in this process, as `main` spins it, or node processes
on a domain of their own). Each test reproduces a problem of issue 24: a recorder's `dataset`
set at run time by another process and exported over a user's file; a validator that wrote
through a `summary.md` link in `report_dir`, read any path named in `bags` and quoted a file's
first bytes in its answer; a mistyped parameter taken in silence; `~/diagnose` with the
library's validation settings instead of the node's; 300 concurrent calls of which 289 were
never answered.
"""
from __future__ import annotations

from dataclasses import replace
import json
import os
from pathlib import Path
import time
from typing import Any

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.qos import QoSProfile  # noqa: E402

import octoroach_model as om  # noqa: E402
from octoroach_model import validation_jobs  # noqa: E402
from octoroach_model.nodes import validator  # noqa: E402
from octoroach_model.recordings import save_dataset  # noqa: E402
from ros_helpers import (  # noqa: E402
    call_trigger, Client, InProcessValidator, NodeSet, ros_env, wait_until)

SMALL = {'epsilon': 0.3, 'delta': 0.3, 'k': 4, 'grid_points': 5}
FLOOD = 300


@pytest.fixture
def spun():
    started: list[InProcessValidator] = []

    def start(**values: Any) -> InProcessValidator:
        started.append(InProcessValidator(values))
        return started[-1]

    yield start
    for node in started:
        node.close()


@pytest.fixture
def client():
    made = Client()
    yield made
    made.close()


@pytest.mark.long
def test_the_recorders_dataset_is_read_only_and_only_its_own_file_is_replaced(tmp_path):
    dataset, bag = tmp_path / 'runs.npz', tmp_path / 'bag'
    with NodeSet(tmp_path) as nodes:
        recorder = nodes.start('recorder', '-o', str(bag), '--dataset', str(dataset))
        recorder.wait_for_log('recording .* to')
        simulator = nodes.start('simulator', '--ros-args', '-p', 'runs:=2', '-p', 'cycles:=1',
                                '-p', 'pause_s:=0.5', '-p', 'wait_subscribers:=1')
        assert simulator.wait(timeout=60) == 0, nodes.logs()
        other = Client(nodes.domain)
        try:
            result, _ = other.set_parameter('recorder', 'dataset', str(tmp_path / 'notes.txt'))
            assert not result.successful and 'read-only' in result.reason
            ok, message = call_trigger('/recorder/export', nodes.domain)   # its own: written
            assert ok and dataset.is_file(), message
            ok, message = call_trigger('/recorder/export', nodes.domain)   # and replaced
            assert ok, message
            dataset.unlink()
            dataset.write_text('a user put a file here meanwhile')
            ok, message = call_trigger('/recorder/export', nodes.domain)
            assert not ok and 'not written by this recorder' in message, message
        finally:
            other.close()
        assert recorder.stop() == 3, recorder.log      # the data set on exit: refused too
    assert dataset.read_text() == 'a user put a file here meanwhile'


def test_a_recorder_whose_dataset_exists_does_not_start(tmp_path, capfd):
    from octoroach_model.nodes import recorder

    taken = tmp_path / 'taken.npz'
    taken.write_text('mine')
    assert recorder.main(['-o', str(tmp_path / 'bag'), '--dataset', str(taken)]) == 3
    assert 'exists already' in capfd.readouterr().err and taken.read_text() == 'mine'
    assert not (tmp_path / 'bag').exists()


def test_report_dir_is_read_only_and_a_report_never_writes_through_a_link(
        spun, client, tmp_path, monkeypatch):
    monkeypatch.setattr(validation_jobs, 'diagnosis_settings', lambda job: om.DiagnosisSettings(
        seed=0, moment_runs=80, mean_path_runs=60, score_runs=150, bootstrap=10, workers=1,
        validate_models=False, detection_limits=False))     # the report's folder is checked
    data = save_dataset(tmp_path / 'runs.npz', om.simulate(60, seed=3))
    reports, target = tmp_path / 'reports', tmp_path / 'target.txt'
    reports.mkdir()
    target.write_text('precious')
    (reports / 'summary.md').symlink_to(target)
    (reports / 'report.json').symlink_to(target)
    spun(bags=[str(data)], report_dir=str(reports))

    result, _ = client.set_parameter('validator', 'report_dir', str(tmp_path / 'elsewhere'))
    assert not result.successful and 'read-only' in result.reason
    ok, answer, _ = client.trigger('/validator/diagnose', timeout=300)
    assert ok, answer
    folder = Path(answer['report_files']['report']).parent
    assert folder.parent == reports and folder.name.startswith('diagnosis_')
    assert (folder / 'summary.md').read_text().startswith('#')
    assert target.read_text() == 'precious'
    assert sorted(p.name for p in reports.iterdir()) == sorted(
        ['summary.md', 'report.json', folder.name])


def test_bags_at_run_time_stay_inside_the_allowed_folders_and_answers_quote_no_file(
        spun, client, tmp_path):
    allowed, outside = tmp_path / 'data', tmp_path / 'private'
    allowed.mkdir()
    outside.mkdir()
    data = save_dataset(allowed / 'runs.npz', om.simulate(20, seed=1, cycles=3))
    secret = outside / 'shadow.mcap'
    secret.write_text('root:*:20000:0:99999:7:::\n')
    (allowed / 'link.mcap').symlink_to(secret)
    spun(bags=[str(data)], **SMALL)

    for name in (str(secret), str(allowed / 'link.mcap'), str(allowed / '..' / 'private')):
        result, _ = client.set_parameter('validator', 'bags', [name])
        assert not result.successful and 'outside the folders allowed' in result.reason, name
    assert client.set_parameter('validator', 'data_dirs', [str(outside)])[0].successful is False
    assert client.get_parameter('validator', 'bags')[0] == [str(data)]

    inside = allowed / 'broken.mcap'
    inside.write_text('root:*:20000:0:99999:7:::\n')
    assert client.set_parameter('validator', 'bags', [str(inside)])[0].successful
    ok, answer, _ = client.trigger('/validator/validate')
    assert not ok and 'not an MCAP file' in answer['error'], answer
    assert 'root:*' not in answer['error'], answer


def test_a_mistyped_parameter_is_warned_about_at_start(tmp_path):
    with NodeSet(tmp_path) as nodes:
        node = nodes.start('validator', '--ros-args', '-p', 'epsilonn:=0.3', '-p', 'k:=4')
        node.wait_for_log('unknown parameter.*epsilonn')
        node.wait_for_log('ready:')
        assert 'k:' not in ''.join(node.matches(r'unknown parameter\(s\) ([^:]*)'))
        assert node.stop() == 0, node.log


def test_diagnose_uses_the_validators_own_validation_settings():
    values = {spec.name: spec.default for spec in validator.validator_specs()}
    job = validation_jobs.Job.from_values({**values, 'epsilon': 0.3, 'delta': 0.25, 'k': 5,
                                           'rho': 0.4, 'grid_points': 7})
    settings = validation_jobs.diagnosis_settings(job).validation
    assert (settings.epsilon, settings.delta, settings.k, settings.rho,
            settings.grid_points) == (0.3, 0.25, 5, 0.4, 7)


def test_a_flood_of_calls_is_answered_every_one_busy_with_how_long_to_wait(
        spun, client, tmp_path):
    from std_srvs.srv import Trigger

    data = save_dataset(tmp_path / 'runs.npz', om.simulate(200, seed=2))
    node = spun(bags=[str(data)], epsilon=0.3, delta=0.3, k=4, grid_points=101,
                nominal='table2').node
    running = client.start(Trigger, '/validator/validate')          # a search of minutes
    wait_until(lambda: node.running == 'validation', 30, 'the validation to start')
    # one caller's 300 requests at once (its own queue deep enough to take every answer)
    flood = client.node.create_client(Trigger, '/validator/diagnose',
                                      qos_profile=QoSProfile(depth=FLOOD))
    assert flood.wait_for_service(timeout_sec=20)
    started = time.monotonic()
    futures = [flood.call_async(Trigger.Request()) for _ in range(FLOOD)]
    wait_until(lambda: all(f.done() for f in futures), 60,
               f'{sum(f.done() for f in futures)} of {FLOOD} answered')
    seconds = time.monotonic() - started
    answers = [json.loads(f.result().message) for f in futures]
    assert all(a.get('busy') is True and a['retry_after_s'] >= 1 for a in answers), answers[:3]
    assert 'call again in about' in answers[0]['error']
    assert seconds < 30, f'{FLOOD} answers took {seconds:.1f} s'
    node.stop_jobs()
    running.wait(timeout=30)


def test_the_launch_file_runs_each_node_in_its_sros2_enclave(tmp_path):
    from ros_helpers import read_launch_file, REPO

    launched = {node.name: node for node in read_launch_file(
        REPO / 'launch' / 'octoroach.launch.xml', REPO, enclaves='/lab')}
    for name, node in launched.items():
        at = node.arguments.index('--enclave')
        assert node.arguments[at + 1] == f'/lab/{name}'
    keystore = tmp_path / 'keystore'
    (keystore / 'enclaves').mkdir(parents=True)
    with NodeSet(tmp_path) as nodes:
        secured = ros_env(nodes.domain, ROS_SECURITY_ENABLE='true',
                          ROS_SECURITY_STRATEGY='Enforce', ROS_SECURITY_KEYSTORE=str(keystore))
        node = nodes.start('validator', *launched['validator'].arguments, env=secured)
        assert node.wait(timeout=60) != 0, node.log
    # the node asked for its own enclave, which the keystore lacks: no node joins unkeyed
    assert os.path.join('enclaves', 'lab', 'validator') in node.log, node.log
    assert 'Traceback' not in node.log


def test_diagnose_draws_the_simulations_as_often_as_the_parameter_says(
        spun, client, tmp_path, monkeypatch):
    node_settings = validation_jobs.diagnosis_settings
    monkeypatch.setattr(validation_jobs, 'diagnosis_settings', lambda job: replace(
        node_settings(job), moment_runs=80, mean_path_runs=60, score_runs=150, bootstrap=10,
        workers=1, validate_models=False, detection_limits=False))
    data = save_dataset(tmp_path / 'runs.npz', om.simulate(60, seed=3, cycles=6))
    spun(bags=[str(data)], simulation_draws=2)

    result, _ = client.set_parameter('validator', 'simulation_draws', 21)
    assert not result.successful and 'out of range' in result.reason   # its descriptor's
    ok, answer, _ = client.trigger('/validator/diagnose', timeout=300)
    assert ok, answer
    draws = answer['simulation_draws']
    assert draws['count'] == 2 and draws['seeds'] == [0, 1] and draws['split_seed'] == 0
    assert draws['named'][0] == [c['cause'] for c in answer['causes']] + [
        e['term'] for e in answer['extensions']]
