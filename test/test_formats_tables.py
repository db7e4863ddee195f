"""
Trajectory tables: TUM trajectories, EuRoC/ASL CSV and CSV with a header, read like bags.

Each file is written from its format's published layout (`trajectory_writers`), with odd but
valid variants: comments, missing frames, extra columns, other units and delimiters. The runs
read back must be the model runs written, to 1e-6 m and rad, their stamps exact to the ns.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.cli import validate_main
from octoroach_model.errors import BagError
from octoroach_model.paths import Paths
from octoroach_model.recordings import load_measured, read_runs
from octoroach_model.recordings.sources import input_kind, InputKind
from trajectory_writers import (
    EPOCH_S,
    planar_pose,
    write_euroc,
    write_pose_csv,
    write_tum,
)

TOLERANCE = 1e-6
PERIOD_NS = 4 * 10**9  # a run every 4 s: 1.5 s of poses, then a pause


@pytest.fixture(scope='module')
def truth() -> Paths:
    """Three model runs of 3 cycles at 50 Hz."""
    return om.simulate(3, seed=11, cycles=3)


def stamps(paths: Paths, run: int) -> np.ndarray:
    return EPOCH_S * 10**9 + run * PERIOD_NS + np.round(paths.t * 1e9).astype(np.int64)


def all_samples(paths: Paths, keep=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps, positions and headings of every run one after another (rows `keep` only)."""
    times = np.concatenate([stamps(paths, run) for run in range(paths.n_paths)])
    poses = paths.poses.reshape(-1, 3)
    keep = np.ones(len(times), bool) if keep is None else keep
    return times[keep], poses[keep], keep


def assert_truth(runs, paths: Paths, keep=None) -> None:
    keep = np.ones(paths.poses.shape[:2], bool) if keep is None else keep.reshape(
        paths.poses.shape[:2])
    assert len(runs.runs) == paths.n_paths, runs.notes
    for run, expected, kept in zip(runs.runs, paths.poses, keep):
        np.testing.assert_allclose(run.poses, expected[kept], atol=TOLERANCE, rtol=0)
        first = np.flatnonzero(kept)[0]
        np.testing.assert_allclose(run.t, paths.t[kept] - paths.t[first], atol=1e-12)


def test_a_tum_trajectory_with_comments_and_missing_frames_reads_into_the_runs(
        tmp_path, truth):
    keep = np.ones(truth.poses.shape[0] * truth.poses.shape[1], bool)
    keep[[5, 6, 7, 90]] = False  # frames the tracker lost: absent lines
    times, poses, keep = all_samples(truth, keep)
    positions, rotations = planar_pose(poses)
    path = write_tum(tmp_path / 'groundtruth.txt', times, positions, rotations,
                     extra_comment_at=40)
    assert input_kind(path) is InputKind.TABLE
    runs = read_runs(path)
    assert_truth(runs, truth, keep)
    assert runs.runs[0].start_stamp_s == EPOCH_S    # the time is read to the nanosecond
    said = '\n'.join(runs.notes)
    assert 'TUM trajectory separated by spaces: time timestamp in s, position tx ty tz in m, ' \
           'quaternion qx qy qz qw' in said
    assert "clock: the file's own times, 50 Hz" in said
    assert '4 missing frame(s)' in said


def test_a_tum_file_without_header_is_told_by_its_eight_columns(tmp_path, truth):
    times, poses, _ = all_samples(truth)
    positions, rotations = planar_pose(poses)
    path = write_tum(tmp_path / 'estimate', times, positions, rotations, comments=())
    assert_truth(read_runs(path), truth)


@pytest.mark.parametrize('unit_on_time', [True, False])
def test_an_euroc_state_csv_reads_into_the_runs_and_ignores_its_other_columns(
        tmp_path, truth, unit_on_time):
    times, poses, _ = all_samples(truth)
    positions, rotations = planar_pose(poses, height_m=0.78)
    path = write_euroc(tmp_path / 'data.csv', times, positions, rotations,
                       units_on_time=unit_on_time)
    runs = read_runs(path)
    assert_truth(runs, truth)
    said = '\n'.join(runs.notes)
    assert 'EuRoC/ASL CSV separated by commas: time timestamp' in said
    assert 'quaternion q_RS_x [] q_RS_y [] q_RS_z [] q_RS_w []; 9 other column(s) ignored' \
        in said


def _rows(truth: Paths, columns) -> list[list[str]]:
    times, poses, _ = all_samples(truth)
    positions, rotations = planar_pose(poses)
    quaternions = rotations.as_quat()
    values = {'t': (times - times[0]) / 1e9, 'x': positions[:, 0], 'y': positions[:, 1],
              'z': positions[:, 2], 'yaw': poses[:, 2], 'qx': quaternions[:, 0],
              'qy': quaternions[:, 1], 'qz': quaternions[:, 2], 'qw': quaternions[:, 3],
              'quality': np.full(len(times), 3.0)}
    return [[format_cell(values[role][index], scale) for role, scale in columns]
            for index in range(len(times))]


def format_cell(value: float, scale) -> str:
    if scale == 'ns':
        return str(int(round(value * 1e9)))
    return f'{value * scale:.9f}'


VARIANTS = {
    'seconds, metres and a yaw': (',', ['t', 'x', 'y', 'yaw'],
                                  [('t', 1), ('x', 1), ('y', 1), ('yaw', 1)]),
    'ms, mm and degrees after comments': (';', ['time [ms]', 'x (mm)', 'y [mm]', 'heading [deg]'],
                                          [('t', 1e3), ('x', 1e3), ('y', 1e3),
                                           ('yaw', 180 / math.pi)]),
    'a quaternion and an extra column': (' ', ['timestamp', 'x', 'y', 'z', 'quality', 'qx',
                                               'qy', 'qz', 'qw'],
                                         [('t', 1), ('x', 1), ('y', 1), ('z', 1),
                                          ('quality', 1), ('qx', 1), ('qy', 1), ('qz', 1),
                                          ('qw', 1)]),
    'ns by suffix, w first, tabs': ('\t', ['time_ns', 'pos_x', 'pos_y', 'pos_z', 'qw', 'qx',
                                           'qy', 'qz'],
                                    [('t', 'ns'), ('x', 1), ('y', 1), ('z', 1), ('qw', 1),
                                     ('qx', 1), ('qy', 1), ('qz', 1)]),
}


@pytest.mark.parametrize('variant', sorted(VARIANTS))
def test_a_csv_with_a_header_naming_its_columns_reads_into_the_runs(tmp_path, truth, variant):
    delimiter, header, columns = VARIANTS[variant]
    rows = _rows(truth, columns)
    rows[30] = [rows[30][0]] + [''] * (len(header) - 2) + [rows[30][-1]]  # untracked: empty
    keep = np.ones(len(rows), bool)
    keep[30] = False
    path = write_pose_csv(tmp_path / 'poses.csv', header, rows, delimiter=delimiter,
                          preamble=('# exported by a lab script', '# units in the header'))
    runs = read_runs(path)
    assert_truth(runs, truth, keep)
    said = '\n'.join(runs.notes)
    assert 'CSV table separated by' in said and '1 row(s) without a full pose' in said


@pytest.mark.parametrize('content, reason', [
    ('t,x,y\n0,0,0\n', 'without an orientation: it needs quaternion columns qx qy qz qw or a '
                       'heading column'),
    ('t,x,y,qx,qy\n0,0,0,0,0\n', 'it has only qx, qy'),
    ('time [h],x,y,yaw\n0,0,0,0\n',
     r'unknown time unit, text \(1 character, not shown\); expected s, sec, ms, us, ns'),
    ('t,x [in],y [in],yaw\n0,0,0,0\n', r'unknown length unit, text \(2 characters, not shown\)'),
    ('time [SECRETUNIT],x,y,yaw\n0,0,0,0\n', 'unknown time unit, text'),
    ('t,x [SECRETUNIT],y,yaw\n0,0,0,0\n', r'unknown length unit, text \(10 characters'),
    ('t,x,y,yaw [SECRETUNIT]\n0,0,0,0\n', 'unknown angle unit, text .*; expected rad or deg'),
    ('t,x [mm],y [SECRETUNIT],yaw\n0,0,0,0\n', '2 different length units; expected m, cm or mm'),
    ('t,x,y,yaw [degs]\n0,0,0,0\n', r'text \(4 characters, not shown\) \(did you mean deg\?\)'),
    ('t,x,y,yaw\nnoon,1,2,3\n', 'without a single readable pose row'),
])
def test_a_table_that_cannot_give_a_pose_is_one_line_naming_what_it_needs(tmp_path, content,
                                                                          reason):
    path = tmp_path / 'bad.csv'
    path.write_text(content)
    with pytest.raises(BagError, match=reason) as raised:
        read_runs(path)
    assert '\n' not in str(raised.value)
    assert 'SECRET' not in str(raised.value).upper()     # a unit the file gives is not quoted


def test_a_folder_of_tables_is_read_like_a_folder_of_bags(tmp_path, truth):
    folder = tmp_path / 'session'
    (folder / 'euroc').mkdir(parents=True)
    times, poses, _ = all_samples(truth)
    positions, rotations = planar_pose(poses)
    write_tum(folder / 'groundtruth.txt', times, positions, rotations)
    write_euroc(folder / 'euroc' / 'data.csv', times, positions, rotations)
    (folder / 'README.txt').write_text('Recorded on the lab floor, robot 3.\n')
    measured = load_measured([folder])
    assert measured.n_paths == 2 * truth.n_paths
    assert sorted(Path(p).name for p in measured.info['inputs']) == ['data.csv',
                                                                     'groundtruth.txt']


def test_an_unknown_file_is_one_line_listing_what_is_read(tmp_path, capsys):
    path = tmp_path / 'session.dat'
    path.write_text('robot 3, floor B\nall good\n')
    with pytest.raises(BagError, match='not a file this package reads') as raised:
        read_runs(path)
    for name in ('rosbag2', 'ROS 1', 'Vicon CSV', 'C3D', 'Qualisys TSV', 'TUM', 'EuRoC/ASL',
                 'CSV with a header naming time and pose columns'):
        assert name in str(raised.value)
    assert 'floor B' not in str(raised.value)    # never the file's content
    assert validate_main([str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith('error: validate: ') and err.count('\n') == 1
