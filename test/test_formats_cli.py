"""
Motion-capture files straight into the programs.

`validate`, `convert` and `diagnose` take Vicon CSV exports and C3D files like bags (one
trial per file, one run per trial).
"""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from mocap_helpers import body_rotations, markers_on_body, write_c3d, write_vicon_csv
import octoroach_model as om
from octoroach_model.recordings import read_runs

REPO = Path(__file__).resolve().parents[1]
LAYOUT_M = {'front': (0.05, 0.0, 0.03), 'left': (-0.03, 0.02, 0.03),
            'right': (-0.03, -0.02, 0.03), 'top': (0.0, 0.0, 0.05)}


def run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'octoroach_model', *map(str, args)],
                          cwd=REPO, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def trials(tmp_path_factory) -> tuple[Path, Path, om.Paths]:
    """Write 48 model runs (markers on a body) as 48 Vicon CSV trials and as 48 C3D trials."""
    folder = tmp_path_factory.mktemp('trials')
    runs = om.simulate(48, seed=4, cycles=4)
    csv_folder, c3d_folder = folder / 'csv', folder / 'c3d'
    csv_folder.mkdir()
    c3d_folder.mkdir()
    for index, poses in enumerate(runs.poses):
        positions = np.column_stack([poses[:, :2], np.full(len(poses), 0.03)])
        write_vicon_csv(csv_folder / f'trial{index:02d}.csv', np.arange(1, len(poses) + 1),
                        {'hz': 50}, {'Global Angle octoroach:octoroach': (
                            positions, body_rotations(poses[:, 2]),
                            np.ones(len(poses), bool))})
        markers = markers_on_body(poses, LAYOUT_M)
        write_c3d(c3d_folder / f'trial{index:02d}.c3d', 50.0,
                  {f'octoroach:{name}': points for name, points in markers.items()})
    return csv_folder, c3d_folder, runs


def test_validate_reads_a_folder_of_vicon_csv_trials_as_runs(trials) -> None:
    csv_folder, _, runs = trials
    result = run('validate', csv_folder, '--epsilon', 0.3, '--delta', 0.3, '--k', 4,
                 '--grid-points', 3, '--nominal', 'table2')
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer['paths_available'] == runs.n_paths
    assert any('mm converted to m' in note for note in answer['notes'])


def test_convert_turns_c3d_trials_into_the_standard_bag(trials, tmp_path) -> None:
    _, c3d_folder, runs = trials
    result = run('convert', *sorted(c3d_folder.glob('*.c3d')), '--out', tmp_path / 'bag',
                 '--subject', 'octoroach', '--markers', 'front,left,right,top')
    assert result.returncode == 0, result.stderr
    converted = read_runs(tmp_path / 'bag').runs
    assert len(converted) == runs.n_paths
    # without a layout the body frame is the first complete frame's: headings are relative
    # to the start, positions are those of the markers' centroid; the path's shape is kept
    for run_read, poses in zip(converted, runs.poses):
        turned = run_read.poses[:, 2] - run_read.poses[0, 2]
        np.testing.assert_allclose(turned, poses[:, 2] - poses[0, 2], atol=1e-6)


def test_a_c3d_with_too_few_markers_on_the_body_is_one_line_naming_what_to_pass(
        trials, tmp_path) -> None:
    _, c3d_folder, _ = trials
    result = run('validate', next(c3d_folder.glob('*.c3d')), '--markers', 'front,left')
    assert result.returncode == 1 and 'Traceback' not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and 'marker' in result.stderr
