"""
Qualisys QTM TSV exports (6DOF bodies and 3D markers), written from QTM's published layout.

The 6DOF rotation is read from Rot[0..8] (the matrix column by column) and the heading must
be the yaw of the body's forward axis, also for a tilted body; 3D markers are fitted like a
C3D file's. Odd but valid variants: no column names, no FILE_VERSION, missing data as NaN,
as empty cells or as zeros, EVENT lines, an external timebase, virtual trajectories.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap_helpers import BODY_LAYOUT_M, body_rotations, markers_on_body
import octoroach_model as om
from octoroach_model.errors import BagError
from octoroach_model.paths import Paths
from octoroach_model.recordings import read_runs, ReadOptions
from octoroach_model.recordings.mocap.shared import first_complete_frames, LAYOUT_FRAMES
from octoroach_model.recordings.sources import input_kind, InputKind
from trajectory_writers import write_qtm_3d, write_qtm_6d

RATE_HZ = 100.0
PAUSE = 80  # untracked frames between runs (0.8 s at 100 Hz): a gap that splits runs
TOLERANCE = 1e-6


@pytest.fixture(scope='module')
def truth() -> Paths:
    """Three model runs of 3 cycles at 100 Hz."""
    return om.simulate(3, seed=5, cycles=3, t=np.arange(151) / RATE_HZ)


def session(paths: Paths, tilt_rad: float = 0.0):
    """Every run one after another with PAUSE untracked frames between: poses and tracking."""
    blocks, tracked = [], []
    for poses in paths.poses:
        blocks += [poses, np.zeros((PAUSE, 3))]
        tracked += [np.ones(len(poses), bool), np.zeros(PAUSE, bool)]
    poses = np.concatenate(blocks[:-1])
    seen = np.concatenate(tracked[:-1])
    wobble = tilt_rad * np.sin(np.arange(len(poses)) / 7.0)
    rotations = body_rotations(poses[:, 2], roll=wobble, pitch=-0.5 * wobble)
    positions = np.column_stack([poses[:, :2], 0.04 + 0.002 * np.sin(np.arange(len(poses)))])
    return positions, rotations, seen


def assert_runs(runs, paths: Paths, atol: float = TOLERANCE) -> None:
    assert len(runs.runs) == paths.n_paths, runs.notes
    for run, expected in zip(runs.runs, paths.poses):
        np.testing.assert_allclose(run.poses, expected, atol=atol, rtol=0)
        np.testing.assert_allclose(run.t, np.arange(len(expected)) / RATE_HZ, atol=1e-9)


@pytest.mark.parametrize('missing, column_names, file_version', [
    ('NaN', True, False), ('0', True, True), ('', False, True)])
def test_a_6dof_export_reads_into_the_runs_from_its_rotation_matrix(tmp_path, truth, missing,
                                                                    column_names,
                                                                    file_version):
    positions, rotations, seen = session(truth, tilt_rad=0.2)
    path = write_qtm_6d(tmp_path / 'walk_6d.tsv', RATE_HZ, {'robot': (positions, rotations,
                                                                      seen)},
                        missing=missing, column_names=column_names, file_version=file_version)
    assert input_kind(path) is InputKind.QUALISYS_TSV
    notes: list[str] = []
    runs = read_runs(path)
    notes = runs.notes
    assert_runs(runs, truth)   # the yaw of the tilted body's x axis, exactly
    said = '\n'.join(notes)
    assert 'Qualisys TSV 6DOF export, body robot at 100 Hz' in said
    if missing == '0':   # null data written as zeros: no rotation, counted
        assert f'{2 * PAUSE} pose(s) with an all-zero orientation (an occluded body) dropped' \
            in said


def test_several_bodies_need_a_subject_and_an_external_timebase_uses_the_time_column(
        tmp_path, truth):
    positions, rotations, seen = session(truth)
    other = (positions + [1.0, 0.0, 0.0], rotations, seen)
    times = np.arange(len(positions)) * 0.01 + 3.25
    path = write_qtm_6d(tmp_path / 'two_6d.tsv', 'EXT', {'robot': (positions, rotations, seen),
                                                         'wand': other}, times_s=times)
    with pytest.raises(BagError, match=r'several bodys \(robot, wand\); pass --subject'):
        read_runs(path)
    wand = read_runs(path, options=ReadOptions(subject='wand'))
    assert len(wand.runs) == truth.n_paths
    for run, expected in zip(wand.runs, truth.poses):
        np.testing.assert_allclose(run.poses[:, 0], expected[:, 0] + 1.0, atol=TOLERANCE)
        np.testing.assert_allclose(run.t, np.arange(len(expected)) * 0.01, atol=1e-6)
    with pytest.raises(BagError, match=r"no body 'robo'; it has robot, wand"):
        read_runs(path, options=ReadOptions(subject='robo'))


@pytest.mark.parametrize('missing, column_names', [('', True), ('0.000', False)])
def test_a_3d_export_is_fitted_like_a_c3d_file_and_leaves_virtual_trajectories_out(
        tmp_path, truth, missing, column_names):
    poses = truth.poses[1]
    markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.02)
    markers['top'][40:45] = np.nan      # hidden a while: fitted on the other three
    markers['robot_origin'] = np.column_stack([poses[:, :2], np.full(len(poses), 0.3)])
    path = write_qtm_3d(tmp_path / 'walk.tsv', RATE_HZ, markers, missing=missing,
                        types={'robot_origin': 'Virtual'}, column_names=column_names)
    notes: list[str] = []
    runs = read_runs(path)
    notes = runs.notes
    run = runs.runs[0]
    centroid = np.mean(list(BODY_LAYOUT_M.values()), axis=0)
    turn = body_rotations(poses[:, 2]).apply(centroid)
    np.testing.assert_allclose(run.poses[:, 0], poses[:, 0] + turn[:, 0], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 1], poses[:, 1] + turn[:, 1], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 2], poses[:, 2] - poses[0, 2], atol=TOLERANCE)
    said = '\n'.join(notes)
    assert '1 virtual trajectory(ies) left out of the body: robot_origin' in said
    assert '4 body markers (front, left, right, top)' in said
    assert '5 frame(s) fitted on the markers that were seen' in said


@pytest.mark.filterwarnings('error')
@pytest.mark.parametrize('far', [1e300, np.inf])
def test_a_marker_at_an_impossible_position_is_a_marker_not_seen(tmp_path, truth, far):
    """A coordinate no capture volume holds is read as a gap, with no arithmetic warning."""
    poses = truth.poses[1]
    markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.02)
    path = write_qtm_3d(tmp_path / 'walk.tsv', RATE_HZ, markers)
    lines = path.read_text().splitlines()
    for row in range(len(lines) - len(poses) + 40, len(lines) - len(poses) + 43):
        cells = lines[row].split('\t')
        cells[2] = repr(far)          # the first marker's X, in mm
        lines[row] = '\t'.join(cells)
    path.write_text('\n'.join(lines) + '\n')
    runs = read_runs(path)
    assert len(runs.runs) == 1
    assert np.isfinite(runs.runs[0].poses).all()
    assert '3 frame(s) fitted on the markers that were seen' in '\n'.join(runs.notes)


def test_the_layout_comes_from_the_first_complete_frames_wherever_they_start():
    """
    A first block of frames without one complete frame does not hide where they begin.

    Every marker reader (TSV, CSV, C3D) takes the body's layout this way, block by block.
    """
    seen = np.random.default_rng(0).normal(0.0, 0.05, (1500, 3, 3))
    markers = seen.copy()
    markers[:1200, 1] = np.nan          # the second marker unseen for the first 1200 frames
    blocks = [(np.arange(start, start + 500) + 1, markers[start:start + 500])
              for start in range(0, 1500, 500)]
    frames_m, first_frame = first_complete_frames(iter(blocks), 3)
    assert first_frame == 1201
    np.testing.assert_array_equal(frames_m, seen[1200:1200 + LAYOUT_FRAMES])
    frames_m, first_frame = first_complete_frames(iter(blocks[:2]), 3)
    assert frames_m.shape == (0, 3, 3)


@pytest.mark.parametrize('content, reason', [
    ('NO_OF_FRAMES\t1\nDATA_INCLUDED\t2D\nFrame\tTime\n1\t0\n', 'of 2D camera data'),
    ('NO_OF_FRAMES\t1\nFREQUENCY\tfast\nDATA_INCLUDED\t6D\nBODY_NAMES\tb\n1\t0\n',
     'FREQUENCY must be a number of Hz or EXT'),
    ('NO_OF_FRAMES\t1\nthis is not qtm\n1\t0\n', 'line 2: not a Qualisys TSV header line'),
    ('NO_OF_FRAMES\t1\nFREQUENCY\t100\nDATA_INCLUDED\t6D\nBODY_NAMES\tb\n1\t0\t1\n',
     'the data rows have 3 columns'),
    ('NO_OF_FRAMES\t1\nFREQUENCY\t100\n1\t0\n', 'without DATA_INCLUDED 3D or 6D'),
])
def test_a_tsv_export_that_cannot_give_a_pose_is_one_line(tmp_path, content, reason):
    path = tmp_path / 'bad.tsv'
    path.write_text(content)
    with pytest.raises(BagError, match=reason) as raised:
        read_runs(path)
    assert '\n' not in str(raised.value)


def test_the_rotation_matrix_columns_are_the_body_axes(tmp_path):
    """A body turned 90 deg about z: Rot[0..2] is its x axis (world y), heading pi/2."""
    rotations = Rotation.from_euler('z', np.full((30, 1), np.pi / 2))
    positions = np.column_stack([np.linspace(0, 0.3, 30), np.zeros(30), np.zeros(30)])
    path = write_qtm_6d(tmp_path / 'turned_6d.tsv', RATE_HZ,
                        {'b': (positions, rotations, np.ones(30, bool))})
    line = path.read_text().splitlines()[-1].split('\t')
    assert [round(float(v), 6) + 0.0 for v in line[9:12]] == [0.0, 1.0, 0.0]   # Rot[0..2]
    np.testing.assert_allclose(read_runs(path).runs[0].poses[:, 2], np.pi / 2, atol=1e-9)
