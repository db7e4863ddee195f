"""
Whole studies as a user runs them.

In this process, on a 2-worker Dask LocalCluster (with a worker killed mid-study), interrupted
and resumed from the command line, bad specs refused before any work, and `plan` from data set
to answer. Data sets are tiny (40 runs of 5 cycles, small diagnosis settings) to keep the
suite's time.
"""
from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import time

from hidden_effects import FEW_SIMULATED_RUNS
import pytest
import yaml

import octoroach_model as om
from octoroach_model.errors import ParameterError
from octoroach_model.studies.table import TIMING_COLUMNS

REPO = Path(__file__).resolve().parents[1]
TIMEOUT_S = 300


def suite_seed() -> int:
    seed = int(os.environ.get('OCTOROACH_TEST_SEED', random.SystemRandom().randrange(10**6)))
    print(f'OCTOROACH_TEST_SEED={seed}')
    return seed


SEED = suite_seed()


def tiny_spec(replicates: int = 1) -> dict:
    """
    Null data sets, a strong turning spread, and a slip at twice the reported limit.

    The nulls compute the slip's whole limit alone (limit_terms), the one the spec reads.
    """
    return {'name': 'tiny', 'seed': SEED, 'replicates': replicates, 'runs': [40],
            'robot': {'cycles': 5, 'stride_frequency_hz': {'low': 1.8, 'high': 2.2}},
            'causes': ['none', {'cause': 'persistent_turning', 'sizes': [20]},
                       {'cause': 'lateral_slip', 'limit_multiples': [2], 'sign': 'both'}],
            'diagnosis': {**FEW_SIMULATED_RUNS, 'limit_terms': ['lateral_slip']}}


def table_rows(path: Path, with_timing: bool = False) -> list[dict]:
    with open(path, newline='') as stream:
        rows = list(csv.DictReader(stream))
    if not with_timing:
        for row in rows:
            for column in TIMING_COLUMNS:
                del row[column]
    return rows


@pytest.mark.long
def test_a_study_gives_the_same_table_in_process_and_on_a_cluster_even_when_a_worker_dies(
        tmp_path):
    from distributed import Client, LocalCluster

    spec = tiny_spec()
    alone = om.run_study(spec, tmp_path / 'alone', workers=0)
    expected = table_rows(alone.table)
    assert {row['status'] for row in expected} == {'ok'}, expected
    assert [row['key'] for row in expected] == [
        'none/n40/r0', 'persistent_turning=20/n40/r0', 'lateral_slip@+-2x/n40/r0']
    # the slip was put in at twice the limit the null data set of its replicate reported
    null, slip = expected[0], expected[2]
    assert abs(float(slip['true_lateral_slip'])) == 2 * float(null['limit_lateral_slip'])
    # of the whole decision (a held-out test's power at the limit), and no other term's
    assert float(null['test_power_lateral_slip']) > 0 and null['test_power_speed_decay'] == ''
    assert null['seed'] == slip['seed'] and null['stride_frequency_hz'] == \
        slip['stride_frequency_hz']

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        killed = {}

        def kill_a_busy_worker(done, total, row):
            if row is None or killed:
                return
            busy = [address for address, keys in client.processing().items() if keys]
            pids = client.run(os.getpid)
            address = busy[0]
            os.kill(pids[address], signal.SIGKILL)
            killed.update(address=address, pid=pids[address], done=done)

        hurt = om.run_study(spec, tmp_path / 'killed', client=client,
                            progress=kill_a_busy_worker)
        assert killed and killed['done'] < 3, 'a worker was killed while tasks were running'
        assert table_rows(hurt.table) == expected
        assert hurt.computed == 3
        summary = json.loads(hurt.summary_path.read_text())
        assert summary['false_positive']['data_sets'] == 1
        assert summary['power_at_limit_multiples'][0]['limit_multiple'] == 2.0
    plots = {path.name for path in alone.plots}
    assert plots >= {'false_positive.png', 'power.png', 'power_at_limit.png'}


def test_a_worker_started_with_dasks_malloc_setting_gets_large_malloc_thresholds_back():
    """Dask's default MALLOC_TRIM_THRESHOLD_ makes a diagnosis 2.2 times slower in a worker."""
    from distributed import Client, LocalCluster

    from octoroach_model.studies.replicate import use_large_malloc_thresholds

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        environments = client.run(os.environ.get, 'MALLOC_TRIM_THRESHOLD_')
        applied = client.run(use_large_malloc_thresholds)
    assert list(environments.values()) == ['65536'], environments   # Dask's default
    assert list(applied.values()) == [True], applied


def launch(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'octoroach_model', *map(str, args)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


# Python keeps SIGINT ignored when it starts with it ignored, as every background job of a
# non-interactive shell does (`make test &`): the child Ctrl-C is tested on gets Python's
# default handler, as in a terminal.
WITH_CTRL_C = ('import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); '
               "runpy.run_module('octoroach_model', run_name='__main__', alter_sys=True)")


def launch_with_ctrl_c(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-c', WITH_CTRL_C, *map(str, args)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen) -> subprocess.CompletedProcess:
    try:
        stdout, stderr = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        stdout, stderr = process.communicate()
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def one_line_error(result: subprocess.CompletedProcess) -> str:
    assert result.returncode != 0, result.stdout
    assert 'Traceback' not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith('error:'), result.stderr
    return lines[0]


@pytest.mark.long
def test_an_interrupted_study_keeps_its_rows_and_resume_completes_it(tmp_path):
    spec_file = tmp_path / 'tiny.yaml'
    spec_file.write_text(yaml.safe_dump(tiny_spec()))
    out = tmp_path / 'study'
    process = launch_with_ctrl_c('study', spec_file, '--out', out, '--workers', 0)
    table = out / 'table.csv'
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline and process.poll() is None:
        if table.exists() and len(table.read_text().splitlines()) >= 2:
            break
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    stopped = finish(process)
    assert stopped.returncode == 130, stopped.stderr
    assert '--resume completes the study' in stopped.stderr
    kept = table_rows(table, with_timing=True)
    assert 1 <= len(kept) < 3, 'the study was stopped after its first row'

    refused = finish(launch('study', spec_file, '--out', out, '--workers', 0))
    assert 'add --resume' in one_line_error(refused)
    other_spec = tmp_path / 'other.yaml'
    other_spec.write_text(yaml.safe_dump({**tiny_spec(), 'seed': SEED + 1}))
    assert 'another spec' in one_line_error(
        finish(launch('study', other_spec, '--out', out, '--resume', '--workers', 0)))

    resumed = finish(launch('study', spec_file, '--out', out, '--resume', '--workers', 0))
    assert resumed.returncode == 0, resumed.stderr
    assert '3/3 data sets' in resumed.stderr          # the progress bar reached the end
    assert f'table: {table}' in resumed.stdout and 'summary: ' in resumed.stdout
    rows = table_rows(table, with_timing=True)
    assert [row['key'] for row in rows] == [
        'none/n40/r0', 'persistent_turning=20/n40/r0', 'lateral_slip@+-2x/n40/r0']
    # the rows that were kept are those rows, not recomputed ones (same elapsed time)
    for row in kept:
        assert row in rows
    assert json.loads((out / 'summary.json').read_text())['status']['rows'] == 3


BAD_SPECS = {
    'unknown cause': ({'causes': [{'cause': 'wobble', 'sizes': [1]}]}, 'unknown cause, text'),
    'negative size': ({'causes': [{'cause': 'speed_decay', 'sizes': [-0.1]}]}, 'positive'),
    'bad range': ({'robot': {'cycles': {'low': 9, 'high': 3}}}, 'bad range'),
}


def test_a_script_that_starts_a_study_at_its_top_level_is_told_to_guard_it(tmp_path):
    """
    Dask's local workers are spawned, and each imports the main script again (Python's rule).

    A script that calls run_study outside `if __name__ == '__main__':` starts the cluster once
    more in every worker, which fails: the error says why and what to write.
    """
    spec_file = tmp_path / 'tiny.yaml'
    spec_file.write_text(yaml.safe_dump(tiny_spec()))
    script = tmp_path / 'unguarded.py'
    script.write_text(
        'import sys\n'
        'import octoroach_model as om\n'
        'from octoroach_model.errors import OctoroachError\n'
        'try:\n'
        f'    om.run_study({str(spec_file)!r}, {str(tmp_path / "out")!r}, workers=1,\n'
        '                 plots=False)\n'
        'except OctoroachError as error:\n'
        '    sys.exit(f"error: {error}")\n')
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                            text=True, timeout=TIMEOUT_S)
    assert result.returncode != 0, result.stdout
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith('error: cannot start a local Dask cluster of 1 worker:'), last
    assert "a script makes its calls under `if __name__ == '__main__':`" in last, last
    assert not (tmp_path / 'out' / 'rows.jsonl').exists()


def test_bad_specs_and_an_unreachable_scheduler_stop_before_any_work(tmp_path):
    commands = {}
    for name, (spec, _) in BAD_SPECS.items():
        path = tmp_path / f'{name.replace(" ", "_")}.yaml'
        path.write_text(yaml.safe_dump(spec))
        commands[name] = ['study', path, '--out', tmp_path / name.replace(' ', '_')]
    good = tmp_path / 'good.yaml'
    good.write_text(yaml.safe_dump(tiny_spec()))
    commands['scheduler'] = ['study', good, '--out', tmp_path / 'nowhere', '--scheduler',
                             'tcp://127.0.0.1:9', '--connect-timeout-s', 2]
    commands['no out'] = ['study', good]
    commands['negative workers'] = ['study', good, '--out', tmp_path / 'w', '--workers', -1]
    commands['plan size'] = ['plan', '--cause', 'persistent_turning', '--size', -1]
    commands['plan power'] = ['plan', '--cause', 'persistent_turning', '--size', 1,
                              '--power', 1.5]
    commands['plan cause'] = ['plan', '--cause', 'wobble', '--size', 1]
    commands['plan robot'] = ['plan', '--cause', 'speed_decay', '--size', 0.1,
                              '--stride-frequency-hz', 30]
    commands['plan budget'] = ['plan', '--cause', 'speed_decay', '--size', 0.1,
                               '--budget-s', 0]
    commands['plan method'] = ['plan', '--cause', 'speed_decay', '--size', 0.1,
                               '--method', 'guess']
    started = time.monotonic()
    results = {name: launch(*args) for name, args in commands.items()}
    results = {name: finish(process) for name, process in results.items()}
    for name, (_, reason) in BAD_SPECS.items():
        assert results[name].returncode == 1
        assert reason in one_line_error(results[name]), name
        assert not (tmp_path / name.replace(' ', '_')).exists(), 'nothing written'
    assert results['scheduler'].returncode == 1
    assert 'cannot reach the Dask scheduler at tcp://127.0.0.1:9' in one_line_error(
        results['scheduler'])
    assert not (tmp_path / 'nowhere').exists()
    for name in ('no out', 'negative workers', 'plan cause', 'plan method'):
        assert results[name].returncode == 2, name
        one_line_error(results[name])
    for name in ('plan size', 'plan power', 'plan robot', 'plan budget'):
        assert results[name].returncode == 1, name
        one_line_error(results[name])
    assert time.monotonic() - started < 120


@pytest.mark.long
def test_plan_answers_with_a_power_curve_a_plot_and_json(tmp_path):
    progress = []
    result = om.plan_runs('persistent_turning', 20.0, robot={'cycles': 5}, replicates=2,
                          run_counts=[40, 80], max_runs=80, rounds=1,
                          diagnosis=FEW_SIMULATED_RUNS, method='simulate',
                          seed=SEED, workers=0, out=tmp_path / 'plan',
                          progress=lambda fraction, message: progress.append(message))
    assert result.status in ('found', 'at_min_runs', 'above_max_runs')
    counts = [point.runs for point in result.curve]
    assert counts[0] == 40 and counts[-1] == 80 and counts == sorted(counts)
    for point in result.curve:
        assert point.data_sets == 2 and point.named == round(point.power * 2)
        assert point.interval_95[0] <= point.power <= point.interval_95[1]
    if result.status == 'found':
        assert 40 < result.runs_needed <= 80
    if result.status == 'above_max_runs':
        assert result.runs_needed is None and 'more than 80 runs' in result.statement
    written = json.loads((tmp_path / 'plan' / 'plan.json').read_text())
    assert written['cause'] == 'persistent_turning' and written['size'] == 20.0
    assert len(written['curve']) == len(result.curve)
    assert (tmp_path / 'plan' / 'power_curve.png').stat().st_size > 10_000
    assert len(table_rows(tmp_path / 'plan' / 'table.csv')) == sum(
        point.data_sets for point in result.curve)
    assert any('coarse grid' in message for message in progress)
    with pytest.raises(ParameterError, match='power must lie'):
        om.plan_runs('persistent_turning', 1.0, power=1.0, workers=0)

    # the model (the default method) answers within the full simulation's stated interval:
    # here a noise 20 times its floor, which 40 runs name (benchmarks/bench_plan.py compares
    # the two where the answers take minutes)
    simulated = om.plan_runs('measurement_noise', 0.2, robot={'cycles': 5}, replicates=2,
                             run_counts=[40], max_runs=80, rounds=0,
                             diagnosis=FEW_SIMULATED_RUNS, method='simulate', seed=SEED,
                             workers=0)
    steps: list[str] = []
    model = om.plan_runs('measurement_noise', 0.2, robot={'cycles': 5}, max_runs=80,
                         diagnosis=FEW_SIMULATED_RUNS, seed=SEED, workers=0, budget_s=2.0,
                         out=tmp_path / 'model',
                         progress=lambda fraction, message: steps.append(message))
    low, high = simulated.runs_needed_interval_95
    assert (low or 40) <= model.runs_needed <= (high or math.inf), (
        SEED, model.statement, simulated.statement)
    assert model.method == 'model' and any('pilots done' in step for step in steps)
    written = json.loads((tmp_path / 'model' / 'plan.json').read_text())
    assert written['method'] == 'model' and written['fit']['curve']
    header = (tmp_path / 'model' / 'checks.csv').read_text().splitlines()[0].split(',')
    assert header[:2] == ['runs', 'replicate'] and {'se', 'clears_floor', 'test_z'} <= set(header)
    assert (tmp_path / 'model' / 'power_curve.png').stat().st_size > 10_000
    with pytest.raises(ParameterError, match='--method simulate'):
        om.plan_runs('persistent_turning', 1.0, run_counts=[40, 80], workers=0)
    # a number of checks instead of a time budget: the same answer, check for check, again
    again = [om.plan_runs('measurement_noise', 0.2, robot={'cycles': 5}, max_runs=80,
                          diagnosis=FEW_SIMULATED_RUNS, seed=SEED, workers=2, checks=3)
             for _ in range(2)]
    assert [len(plan.checks) for plan in again] == [3, 3]
    assert again[0].runs_needed == again[1].runs_needed and \
        again[0].runs_needed_interval_95 == again[1].runs_needed_interval_95
    assert [(c.runs, c.named, c.estimate) for c in again[0].checks] == \
        [(c.runs, c.named, c.estimate) for c in again[1].checks]
    # each check says why it was named or not: the size bound and the held-out test
    for check in again[0].checks:
        assert check.se > 0 and math.isfinite(check.test_z), check
        assert not check.named or (check.clears_floor and check.test_passed), check
    with pytest.raises(ParameterError, match='goes with --method model'):
        om.plan_runs('persistent_turning', 1.0, run_counts=[40, 80], workers=0, checks=3,
                     method='simulate')
    with pytest.raises(ParameterError, match='checks must lie in'):
        om.plan_runs('persistent_turning', 1.0, workers=0, checks=-1)
    with pytest.raises(ParameterError, match='checks must be a whole number'):
        om.plan_runs('persistent_turning', 1.0, workers=0, checks=2.5)
