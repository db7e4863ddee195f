"""
The offline programs as a user runs them: `python -m octoroach_model X ...` in a subprocess.

CONTRACT.md: `simulate` writes bags any reader can split (>= 1 s between runs), `validate`
prints the paper's validation as JSON, and bad input exits non-zero with one line on stderr,
never a traceback. Independent commands are started together to keep the wall time down.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from octoroach_model.recordings import read_runs

REPO = Path(__file__).resolve().parents[1]
TIMEOUT_S = 300
VALIDATE_KEYS = {'n', 'k', 'sigma1', 'sigma2', 'violation', 'rho', 'epsilon', 'delta', 'gamma',
                 'paths_used', 'guarantee'}
SLIP = ['--effect', 'lateral_slip', '--effect-param', 'velocity_cm_s=2']
TWO_EFFECTS = ['--effect', 'lateral_slip', '--effect', 'initial_pose_error',
               '--effect-param', 'lateral_slip.velocity_cm_s=2',
               '--effect-param', 'heading_std_deg=5', '--effect-param', 'position_std_cm=0.5']


def launch(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'octoroach_model', *map(str, args)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen) -> subprocess.CompletedProcess:
    try:
        stdout, stderr = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        stdout, stderr = process.communicate()
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def run_all(commands: dict[str, list]) -> dict[str, subprocess.CompletedProcess]:
    """Start every command at once and wait for all of them."""
    processes = {name: launch(*args) for name, args in commands.items()}
    return {name: finish(process) for name, process in processes.items()}


def run(*args) -> subprocess.CompletedProcess:
    return finish(launch(*args))


def assert_one_line_error(result: subprocess.CompletedProcess) -> str:
    assert result.returncode != 0, result.stdout
    assert 'Traceback' not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert result.stderr.startswith('error:'), result.stderr
    return lines[0]


# --------------------------------------------------------------------------------------------
# simulate

@pytest.fixture(scope='module')
def simulated(tmp_path_factory):
    """
    Write bags with `simulate`.

    Plain (twice), with lateral slip, with two effects, and 60 runs for `validate`.
    """
    folder = tmp_path_factory.mktemp('simulated')
    common = ['--paths', 30, '--seed', 1]
    commands = {
        'plain': ['simulate', *common, '--out', folder / 'plain'],
        'again': ['simulate', *common, '--out', folder / 'again'],
        'slip': ['simulate', *common, '--out', folder / 'slip', *SLIP],
        'two': ['simulate', *common, '--out', folder / 'two', *TWO_EFFECTS],
        'sixty': ['simulate', '--paths', 60, '--seed', 2, '--out', folder / 'sixty'],
    }
    results = run_all(commands)
    for name, result in results.items():
        assert result.returncode == 0, f'{name}: {result.stderr}'
    return {name: (folder / name, results[name]) for name in commands}


def runs_of(bag: Path) -> list:
    return read_runs(bag).runs


def test_simulate_writes_a_rosbag2_directory_with_metadata_and_an_mcap_file(simulated):
    bag, result = simulated['plain']
    assert (bag / 'metadata.yaml').is_file()
    assert len(list(bag.glob('*.mcap'))) == 1
    summary = json.loads(result.stdout)
    assert summary['paths'] == 30 and summary['seed'] == 1
    assert summary['samples_per_run'] == 251


def test_the_simulated_bag_splits_into_30_runs_of_251_samples_at_50_hz(simulated):
    runs = runs_of(simulated['plain'][0])
    assert len(runs) == 30
    for run in runs:
        assert len(run.t) == 251
        np.testing.assert_allclose(np.diff(run.t), 0.02, atol=1e-9)
        assert run.t[0] == 0.0


def test_every_simulated_run_starts_at_the_origin_heading_along_y(simulated):
    starts = np.array([run.poses[0] for run in runs_of(simulated['plain'][0])])
    np.testing.assert_allclose(starts[:, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(starts[:, 2], math.pi / 2, atol=1e-9)
    # ... and moves forward: about 56 cm after 10 cycles (NOTES.md section 1)
    ends = np.array([run.poses[-1] for run in runs_of(simulated['plain'][0])])
    assert 0.4 < ends[:, 1].mean() < 0.7


def test_simulated_runs_are_separated_by_at_least_one_second(simulated):
    runs = runs_of(simulated['plain'][0])
    starts = np.array([run.start_stamp_s for run in runs])
    ends = starts + np.array([run.duration_s for run in runs])
    assert np.all(np.diff(starts) > 0)
    assert np.all(starts[1:] - ends[:-1] >= 1.0 - 1e-9)


def test_the_same_seed_gives_the_same_bag_contents(simulated):
    first, second = runs_of(simulated['plain'][0]), runs_of(simulated['again'][0])
    for one, other in zip(first, second, strict=True):
        np.testing.assert_array_equal(one.poses, other.poses)


def slip_drift(run, velocity: float) -> np.ndarray:
    """(T, 2) integral of v r(theta) ds, r = (sin theta, -cos theta) (trapezoid rule)."""
    heading = run.poses[:, 2]
    right = np.stack([np.sin(heading), -np.cos(heading)], axis=1)
    steps = 0.5 * (right[1:] + right[:-1]) * np.diff(run.t)[:, None]
    return velocity * np.concatenate([[[0.0, 0.0]], np.cumsum(steps, axis=0)])


def test_lateral_slip_moves_every_run_sideways_and_leaves_its_heading(simulated):
    plain, slip = runs_of(simulated['plain'][0]), runs_of(simulated['slip'][0])
    assert len(slip) == len(plain) == 30
    for before, after in zip(plain, slip):
        np.testing.assert_allclose(after.poses[:, 2], before.poses[:, 2], atol=1e-9)
        np.testing.assert_allclose(after.poses[:, :2] - before.poses[:, :2],
                                   slip_drift(before, 0.02), atol=1e-9)
    # heading near +y: the right axis is +x, about 2 cm/s * 5 s = 10 cm to the right
    sideways = np.array([after.poses[-1, 0] - before.poses[-1, 0]
                         for before, after in zip(plain, slip)])
    assert np.all((0.05 < sideways) & (sideways <= 0.1 + 1e-9))
    assert json.loads(simulated['slip'][1].stdout)['effects'] == {
        'lateral_slip': {'velocity_cm_s': 2.0}}


def test_two_effects_in_one_call_are_both_applied(simulated):
    summary = json.loads(simulated['two'][1].stdout)
    assert summary['effects'] == {'lateral_slip': {'velocity_cm_s': 2.0},
                                  'initial_pose_error': {'heading_std_deg': 5.0,
                                                         'position_std_cm': 0.5}}
    plain, both = runs_of(simulated['plain'][0]), runs_of(simulated['two'][0])
    # initial pose error: every run turned by its own constant angle and shifted
    turns = np.array([after.poses[:, 2] - before.poses[:, 2]
                      for before, after in zip(plain, both)])
    np.testing.assert_allclose(turns - turns[:, :1], 0.0, atol=1e-9)
    assert 2.5 < np.degrees(turns[:, 0].std(ddof=1)) < 8.0
    shifts = np.array([run.poses[0, :2] for run in both])
    assert 0.002 < shifts.std(ddof=1) < 0.01
    # ... of the run with lateral slip: the slipped run, rotated about its start and shifted
    for before, after, turn, shift in zip(plain, both, turns[:, 0], shifts):
        slipped = before.poses[:, :2] + slip_drift(before, 0.02)
        rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
        np.testing.assert_allclose(after.poses[:, :2], shift + slipped @ rotation.T, atol=1e-9)


@pytest.mark.parametrize('program, options', [
    ('simulate', ['--paths', '--seed', '--out', '--cycles', '--sigma1', '--sigma2', '--effect',
                  '--effect-param']),
    ('validate', ['--rho', '--epsilon', '--delta', '--k', '--gamma', '--seed']),
    ('diagnose', ['--out', '--seed']),
])
def test_help_of_each_offline_program_exits_0_and_lists_the_contract_options(program, options):
    result = run(program, '--help')
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith('usage:')
    for option in options:
        assert option in result.stdout, option


# --------------------------------------------------------------------------------------------
# validate

@pytest.fixture(scope='module')
def validated(simulated):
    bag = simulated['sixty'][0]
    small = ['validate', bag, '--epsilon', 0.3, '--delta', 0.3, '--k', 4, '--grid-points', 5,
             '--seed', 3]
    return run_all({'first': small, 'second': small, 'paper': ['validate', bag]})


def test_validate_prints_the_papers_validation_as_json(validated):
    result = validated['first']
    assert result.returncode == 0, result.stderr
    output = json.loads(result.stdout)
    assert VALIDATE_KEYS <= set(output)
    # n = ceil(ln(2 / 0.3) / (2 * 0.3^2)) = ceil(10.54) = 11
    assert (output['n'], output['k'], output['paths_used']) == (11, 4, 44)
    assert (output['epsilon'], output['delta'], output['rho'], output['gamma']) == \
        (0.3, 0.3, 0.35, 0.95)
    assert output['accepted'] == (output['violation'] <= output['rho'])
    assert 0.0 <= output['sigma1'] <= 0.4 and 0.0 <= output['sigma2'] <= 0.4
    assert 'delta' in output['guarantee'] and 'epsilon' in output['guarantee']
    assert 'Traceback' not in result.stderr


def test_validate_gives_the_same_answer_for_the_same_seed(validated):
    first, second = (json.loads(validated[name].stdout) for name in ('first', 'second'))
    for key in ('sigma1', 'sigma2', 'violation'):
        assert first[key] == second[key], key
    assert first['grid'] == second['grid']


def test_validate_with_the_papers_constants_on_60_runs_says_495_are_needed(validated):
    result = validated['paper']
    assert result.returncode == 1
    line = assert_one_line_error(result)
    assert 'needs 495 runs' in line
    assert '60 runs' in line
    assert result.stdout == ''


# --------------------------------------------------------------------------------------------
# Bad input

# In a subprocess, as a user meets them: (arguments, words the error line must contain).
BAD_INPUT = {
    'missing_path': (['validate', '{tmp}/no_such_bag'], 'no such file'),
    'random_bytes': (['validate', '{tmp}/random.mcap'], 'not an MCAP file'),
    'text_file': (['validate', '{tmp}/notes.txt'], 'not a file this package reads'),
    'rho_above_one': (['validate', '{bag}', '--rho', '2'], 'rho'),
    'paths_not_a_number': (['simulate', '--paths', 'abc', '--out', '{tmp}/out_a'], '--paths'),
    'unknown_effect': (['simulate', '--paths', '3', '--out', '{tmp}/out_b', '--effect',
                        'wobble'], 'unknown effect'),
    'effect_param_out_of_range': (['simulate', '--paths', '3', '--out', '{tmp}/out_c',
                                   '--effect', 'lateral_slip', '--effect-param',
                                   'velocity_cm_s=500'], 'outside'),
}

# The same path in-process (cheaper): octoroach_model.cli.dispatch is what __main__ calls.
MORE_BAD_INPUT = {
    'random_bytes_without_suffix': (['validate', '{tmp}/random'],
                                    'not a file this package reads'),
    'empty_directory': (['validate', '{tmp}/empty'], 'empty directory'),
    'paths_zero': (['simulate', '--paths', '0', '--out', '{tmp}/out_d'], '--paths'),
    'epsilon_zero': (['validate', '{bag}', '--epsilon', '0'], 'epsilon'),
    'delta_one': (['validate', '{bag}', '--delta', '1'], 'delta'),
    'k_one': (['validate', '{bag}', '--k', '1'], 'k must'),
    'k_not_a_number': (['validate', '{bag}', '--k', 'four'], '--k'),
    'gamma_not_finite': (['validate', '{bag}', '--gamma', 'nan'], '--gamma'),
    'only_one_sigma': (['validate', '{bag}', '--sigma1', '0.1'], 'sigma2'),
    'effect_param_unknown_key': (['simulate', '--paths', '3', '--out', '{tmp}/out_e',
                                  '--effect', 'lateral_slip', '--effect-param', 'speed=2'],
                                 'has no parameter text (5 characters, not shown)'),
    'effect_param_not_a_number': (['simulate', '--paths', '3', '--out', '{tmp}/out_f',
                                   '--effect', 'lateral_slip', '--effect-param',
                                   'velocity_cm_s=fast'], 'not a number'),
    'effect_param_without_value': (['simulate', '--paths', '3', '--out', '{tmp}/out_g',
                                    '--effect', 'lateral_slip', '--effect-param',
                                    'velocity_cm_s'], 'KEY=VALUE'),
    'effect_param_before_effect': (['simulate', '--paths', '3', '--out', '{tmp}/out_h',
                                    '--effect-param', 'velocity_cm_s=2'], '--effect'),
    'sigma_out_of_range': (['simulate', '--paths', '3', '--out', '{tmp}/out_i', '--sigma1',
                            '2'], 'sigma1'),
    'cycles_zero': (['simulate', '--paths', '3', '--out', '{tmp}/out_j', '--cycles', '0'],
                    'cycles'),
    'out_exists': (['simulate', '--paths', '3', '--out', '{bag}'], 'exists'),
    'missing_required_option': (['simulate', '--paths', '3'], '--out'),
    'limits_of_no_term': (['diagnose', '{bag}', '--out', '{tmp}/out_k', '--limits',
                           'lateral_slip,wobble'], 'text (6 characters, not shown) is no term'),
}


@pytest.fixture(scope='module')
def bad_inputs(tmp_path_factory, simulated):
    """Make a folder of things that are not bags, and the plain simulated bag."""
    folder = tmp_path_factory.mktemp('bad_input')
    (folder / 'random.mcap').write_bytes(np.random.default_rng(0).bytes(4096))
    (folder / 'random').write_bytes(np.random.default_rng(1).bytes(4096))
    (folder / 'notes.txt').write_text('this is not a bag\n')
    (folder / 'empty').mkdir()
    return folder, simulated['plain'][0]


def arguments(case_table, case, bad_inputs) -> list[str]:
    folder, bag = bad_inputs
    return [str(arg).format(tmp=folder, bag=bag) for arg in case_table[case][0]]


@pytest.fixture(scope='module')
def bad_input_results(bad_inputs):
    return run_all({case: arguments(BAD_INPUT, case, bad_inputs) for case in BAD_INPUT})


@pytest.mark.parametrize('case', sorted(BAD_INPUT))
def test_bad_input_exits_non_zero_with_one_error_line_and_no_traceback(case,
                                                                       bad_input_results):
    result = bad_input_results[case]
    line = assert_one_line_error(result)
    assert BAD_INPUT[case][1] in line
    assert result.stdout == ''


@pytest.mark.parametrize('case', sorted(MORE_BAD_INPUT))
def test_more_bad_input_is_refused_with_one_error_line(case, bad_inputs, capsys):
    from octoroach_model.cli import dispatch

    try:
        code = dispatch(arguments(MORE_BAD_INPUT, case, bad_inputs))
    except SystemExit as stop:          # argparse's usage errors leave through sys.exit
        code = stop.code
    captured = capsys.readouterr()
    result = subprocess.CompletedProcess([], code, captured.out, captured.err)
    line = assert_one_line_error(result)
    assert MORE_BAD_INPUT[case][1] in line
    assert result.stdout == ''


def test_a_rejected_simulate_writes_no_bag(bad_inputs, bad_input_results):
    folder, _ = bad_inputs
    assert bad_input_results['unknown_effect'].returncode != 0
    assert not any(path.name.startswith('out_') for path in folder.iterdir())


# --------------------------------------------------------------------------------------------
# The dispatcher

def test_no_executable_exits_non_zero_with_the_usage_on_stderr():
    result = run()
    assert result.returncode != 0
    assert 'usage' in result.stderr
    assert 'simulate' in result.stderr and 'validate' in result.stderr


def test_an_unknown_executable_exits_non_zero_with_the_usage_on_stderr():
    result = run('no_such_program')
    assert result.returncode != 0
    assert 'no_such_program' in result.stderr
    assert 'usage' in result.stderr
    assert 'Traceback' not in result.stderr


def test_help_exits_0_and_lists_every_executable():
    result = run('--help')
    assert result.returncode == 0
    for name in ('simulator', 'recorder', 'validator', 'replay', 'simulate', 'validate',
                 'diagnose'):
        assert name in result.stdout
