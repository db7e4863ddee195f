"""Vicon CSV exports: the same runs as the equivalent bag, every rotation form, bad input."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocap_helpers import (
    BODY_LAYOUT_M,
    body_rotations,
    markers_on_body,
    runs_from_chunks,
    write_marker_csv,
    write_vicon_csv,
)
import octoroach_model as om
from octoroach_model.errors import BagError
from octoroach_model.paths import Paths
from octoroach_model.recordings import read_runs, write_paths_bag
from octoroach_model.recordings.mocap.vicon_csv import iter_csv_pose_chunks, read_csv_sections
from octoroach_model.recordings.options import ReadOptions

RATE_HZ = 50.0
SEED = 12
TOLERANCE = 1e-6  # m and rad, after unit conversion


@pytest.fixture(scope='module')
def model_runs() -> Paths:
    """Four model runs of 10 cycles at 50 Hz (the package's VICON rate)."""
    return om.simulate(4, seed=SEED)


def tilt(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch of a rocking robot (a few degrees), seeded."""
    rng = np.random.default_rng(seed)
    phase = np.arange(n) / RATE_HZ * 2 * np.pi * 2.0
    return (np.radians(4.0) * np.sin(phase + rng.uniform(0, 6)),
            np.radians(3.0) * np.cos(phase + rng.uniform(0, 6)))


def object_of(poses: np.ndarray, *, roll=None, pitch=None, forward_angle: float = 0.0,
              tracked=None) -> tuple[np.ndarray, object, np.ndarray]:
    """(positions, rotations, tracked) of a rigid object carried by planar `poses`."""
    positions = np.column_stack([poses[:, 0], poses[:, 1], np.full(len(poses), 0.031)])
    rotations = body_rotations(poses[:, 2], roll, pitch, forward_angle)
    tracked = np.ones(len(poses), bool) if tracked is None else tracked
    return positions, rotations, tracked


def read_csv(path: Path, options: ReadOptions | None = None, notes: list | None = None,
             chunk_size: int = 10_000):
    notes = [] if notes is None else notes
    chunks = iter_csv_pose_chunks(path, options or ReadOptions(), notes, chunk_size)
    return runs_from_chunks(chunks)


def assert_same_runs(runs, expected) -> None:
    assert len(runs) == len(expected)
    for run, reference in zip(runs, expected):
        np.testing.assert_allclose(run.t, reference.t, atol=1e-9)
        np.testing.assert_allclose(run.poses, reference.poses, atol=TOLERANCE, rtol=0)


def test_tracker_exports_are_read_into_the_same_runs_as_the_bag(tmp_path, model_runs):
    bag_runs = read_runs(write_paths_bag(tmp_path / 'bag', model_runs)).runs
    csv_runs = []
    for index, poses in enumerate(model_runs.poses):
        path = write_vicon_csv(tmp_path / f'trial{index:02d}.csv',
                               np.arange(1, len(poses) + 1), {'hz': 50},
                               {'Global Angle octoroach:octoroach': object_of(poses)})
        notes: list[str] = []
        csv_runs += read_csv(path, notes=notes, chunk_size=64).runs
        assert any('positions in mm converted to m' in note and 'helical vector in deg '
                   'converted to rad' in note for note in notes), notes
    assert_same_runs(csv_runs, bag_runs)


@pytest.mark.parametrize('section, name, rotation, angle_unit, quaternion_first', [
    ('Segments', 'octoroach:octoroach', 'helical', 'rad', False),
    ('Objects', 'Global Angle (Euler XYZ) octoroach:octoroach', 'euler', 'deg', False),
    ('Objects', 'Global Angle (Quaternion) octoroach:octoroach', 'quaternion', '', False),
    ('Objects', 'Global Angle (Quaternion) octoroach:octoroach', 'quaternion', '', True),
])
def test_every_rotation_form_gives_the_heading_of_a_rocking_body(
        tmp_path, model_runs, section, name, rotation, angle_unit, quaternion_first):
    poses = model_runs.poses[1]
    roll, pitch = tilt(len(poses), seed=SEED)
    path = write_vicon_csv(tmp_path / 'rocking.csv', np.arange(len(poses)) + 100,
                           {'hz': 50}, {name: object_of(poses, roll=roll, pitch=pitch)},
                           section=section, rotation=rotation, angle_unit=angle_unit or 'deg',
                           quaternion_first=quaternion_first)
    runs = read_csv(path).runs
    assert len(runs) == 1
    np.testing.assert_allclose(runs[0].poses, poses, atol=TOLERANCE, rtol=0)


def test_unlabelled_rotations_are_helical_and_the_note_says_what_euler_would_change(
        tmp_path, model_runs):
    poses = model_runs.poses[0]
    roll, pitch = tilt(len(poses), seed=SEED + 1)
    rocking = write_vicon_csv(tmp_path / 'rocking.csv', np.arange(len(poses)), {'hz': 50},
                              {'octo': object_of(poses, roll=roll, pitch=pitch)})
    level = write_vicon_csv(tmp_path / 'level.csv', np.arange(len(poses)), {'hz': 50},
                            {'octo': object_of(poses)})
    rocking_notes: list[str] = []
    level_notes: list[str] = []
    np.testing.assert_allclose(read_csv(rocking, notes=rocking_notes).runs[0].poses, poses,
                               atol=TOLERANCE, rtol=0)
    read_csv(level, notes=level_notes)
    assert any('not stated in the file' in note for note in rocking_notes)
    assert any('would differ by up to' in note for note in rocking_notes), rocking_notes
    assert any('would be the same' in note for note in level_notes), level_notes


def test_forward_axis_y_reads_an_object_whose_y_axis_points_forward(tmp_path, model_runs):
    poses = model_runs.poses[2]
    sideways = object_of(poses, forward_angle=np.pi / 2)
    path = write_vicon_csv(tmp_path / 'y_forward.csv', np.arange(len(poses)), {'hz': 50},
                           {'octo:octo': sideways})
    forward_y = read_csv(path, ReadOptions(forward_axis='y')).runs[0]
    np.testing.assert_allclose(forward_y.poses, poses, atol=TOLERANCE, rtol=0)
    forward_x = read_csv(path).runs[0]
    np.testing.assert_allclose(forward_x.poses[:, 2], poses[:, 2] - np.pi / 2, atol=TOLERANCE)


def test_untracked_frames_are_dropped_and_a_long_pause_splits_runs(tmp_path, model_runs):
    poses = np.concatenate([model_runs.poses[0], np.zeros((60, 3)), model_runs.poses[1]])
    tracked = np.ones(len(poses), bool)
    tracked[251:311] = False  # 1.2 s untracked between two trials
    tracked[[20, 21, 22, 400]] = False  # dropped frames inside the trials
    path = write_vicon_csv(tmp_path / 'two_trials.csv', np.arange(1, len(poses) + 1),
                           {'hz': 50}, {'octo:octo': object_of(poses, tracked=tracked)})
    notes: list[str] = []
    run_set = read_csv(path, notes=notes, chunk_size=100)
    assert len(run_set) == 2
    for run, reference in zip(run_set.runs, model_runs.poses[:2]):
        assert run.duration_s == pytest.approx(5.0)
        keep = np.isin(np.round(model_runs.t * RATE_HZ), np.round(run.t * RATE_HZ))
        np.testing.assert_allclose(run.poses, reference[keep], atol=TOLERANCE, rtol=0)
    assert len(run_set.runs[0].t) == 251 - 3 and len(run_set.runs[1].t) == 251 - 1
    assert any('64 frame(s) with empty cells for octo:octo' in note for note in notes), notes
    assert any('missing frame(s)' in note for note in run_set.notes), run_set.notes


def test_other_sections_semicolons_and_a_cut_last_row_are_handled(tmp_path, model_runs):
    poses = model_runs.poses[3]
    path = write_vicon_csv(tmp_path / 'nexus.csv', np.arange(1, len(poses) + 1), {'hz': 50},
                           {'octo:octo': object_of(poses)}, section='Segments',
                           delimiter=';', end_with_newline=False,
                           extra_sections=['Devices', 'Model Outputs'])
    text = path.read_text()
    path.write_text(text[:-6])  # the export stopped in the middle of its last row
    delimiter, sections, cut_line = read_csv_sections(path)
    assert delimiter == ';'
    assert [section.title for section in sections] == ['Devices', 'Model Outputs', 'Segments']
    assert cut_line == len(text.splitlines())
    notes: list[str] = []
    runs = read_csv(path, notes=notes).runs
    np.testing.assert_allclose(runs[0].poses, poses[:-1], atol=TOLERANCE, rtol=0)
    assert any('last row is cut' in note for note in notes)


def test_several_subjects_need_a_subject_and_then_read_the_one_named(tmp_path, model_runs):
    objects = {'Global Angle octo:octo': object_of(model_runs.poses[0]),
               'Global Angle wand:wand': object_of(model_runs.poses[1])}
    path = write_vicon_csv(tmp_path / 'two.csv', np.arange(251), {'hz': 50}, objects)
    with pytest.raises(BagError, match=r'several subjects \(octo, wand\); pass --subject NAME'):
        read_csv(path)
    wand = read_csv(path, ReadOptions(subject='wand')).runs[0]
    np.testing.assert_allclose(wand.poses, model_runs.poses[1], atol=TOLERANCE, rtol=0)
    with pytest.raises(BagError, match="no object or subject 'robot'; it has octo:octo"):
        read_csv(path, ReadOptions(subject='robot'))


def test_a_subject_with_several_segments_needs_the_segment(tmp_path, model_runs):
    objects = {'octo:body': object_of(model_runs.poses[0]),
               'octo:head': object_of(model_runs.poses[1])}
    path = write_vicon_csv(tmp_path / 'segments.csv', np.arange(251), {'hz': 50}, objects,
                           section='Segments')
    with pytest.raises(BagError, match='several segments .*pass --subject SUBJECT:SEGMENT'):
        read_csv(path)
    head = read_csv(path, ReadOptions(subject='octo:head')).runs[0]
    np.testing.assert_allclose(head.poses, model_runs.poses[1], atol=TOLERANCE, rtol=0)


@pytest.mark.parametrize('content, reason', [
    ('time,x,y,heading\n0,1,2,3\n', 'line 1: not a Vicon CSV export header'),
    ('Objects\nfast\n,,octo\nFrame,Sub Frame,RX\n,,deg\n',
     'line 2: .*no frame rate on the line after the section name'),
    ('SECRET\nfast\n,,octo\nFrame,Sub Frame,RX\n,,deg\n', 'line 2: .*no frame rate'),
    ('Objects\n100\n,,octo\nTime,RX,RY\n,,deg\n', 'line 4: .*no "Frame" column'),
    ('Objects\n100\n', 'the header is cut short'),
    ('', 'empty file'),
    ('Objects\n0\n,,octo\nFrame,Sub Frame,RX\n,,deg\n', 'frame rate must be a positive'),
    ('Devices\n1000\n,,Plate\nFrame,Sub Frame,Fx\n,,N\n1,0,2\n', 'no pose in this export'),
    ('Objects\n100\n,,octo\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,in,in,in\n',
     r'octo: unknown length unit, text \(2 characters, not shown\); expected cm, m, mm'),
    ('Objects\n100\n,,octo\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,SECRETUNIT,'
     'SECRETUNIT,SECRETUNIT\n', r'unknown length unit, text \(10 characters, not shown\)'),
    ('Objects\n100\n,,octo\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,mm,SECRETUNIT,mm\n',
     'one length unit for TX TY .*, got 2 different units'),
    ('Objects\n100\n,,octo\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,mm,,mm\n',
     'one length unit for TX TY .*, got a unit and a column without one'),
    ('Objects\n100\n,,octo\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,rad,mm,mm,mm\n',
     'one angle unit for RX RY RZ'),
])
def test_bad_input_is_one_line_naming_what_is_expected(tmp_path, content, reason):
    path = tmp_path / 'bad.csv'
    path.write_text(content)
    with pytest.raises(BagError, match=reason) as raised:
        read_csv(path)
    assert '\n' not in str(raised.value)
    assert 'SECRET' not in str(raised.value)        # what the file says is not quoted
    if 'header' in reason:
        assert 'expected the Objects, Segments or Trajectories section name' in str(
            raised.value)


def test_names_in_the_file_are_listed_only_where_they_look_like_names(tmp_path, model_runs):
    """
    An error lists the subjects a user may choose (--subject), but no text that is not a name.

    A label with a control character or a shell's punctuation is counted, never shown.
    """
    poses = model_runs.poses[0]
    path = write_vicon_csv(tmp_path / 'two.csv', np.arange(1, 252), {'hz': 50},
                           {'octo': object_of(poses), 'SECRET;rm *\x1b[2J': object_of(poses)})
    with pytest.raises(BagError) as raised:
        read_csv(path, ReadOptions(subject='nosuch'))
    message = str(raised.value)
    assert message.endswith("no object or subject 'nosuch'; it has octo and 1 name not shown"), \
        message
    assert 'SECRET' not in message and '\x1b' not in message


def test_unreadable_rows_are_skipped_and_counted(tmp_path, model_runs):
    poses = model_runs.poses[0]
    path = write_vicon_csv(tmp_path / 'garbled.csv', np.arange(1, 252), {'hz': 50},
                           {'octo': object_of(poses)})
    lines = path.read_text().splitlines()
    lines[5 + 100] = lines[5 + 100].replace(',', ',x', 3)  # a row of text where numbers belong
    path.write_text('\n'.join(lines) + '\n')
    notes: list[str] = []
    runs = read_csv(path, notes=notes).runs
    assert len(runs[0].t) == 250
    assert any('1 unreadable row(s) skipped' in note for note in notes), notes


def test_a_trajectories_export_is_fitted_like_a_c3d_file(tmp_path, model_runs):
    poses = model_runs.poses[1]
    markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.01)
    markers['top'][50:60] = np.nan  # hidden for a while: the other three carry the fit
    labelled = {f'octo:{name}': values for name, values in markers.items()}
    labelled['*17'] = markers['front'] + 1.0  # an unlabelled trajectory is not on the body
    path = write_marker_csv(tmp_path / 'markers.csv', np.arange(1, 252), RATE_HZ, labelled)
    notes: list[str] = []
    run = read_csv(path, notes=notes).runs[0]
    # Without a layout the body frame is the world frame at the first frame, at the
    # markers' centroid: headings are relative to the first one.
    centroid = np.mean(list(BODY_LAYOUT_M.values()), axis=0)
    turn = body_rotations(poses[:, 2]).apply(centroid)
    np.testing.assert_allclose(run.poses[:, 0], poses[:, 0] + turn[:, 0], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 1], poses[:, 1] + turn[:, 1], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 2], poses[:, 2] - poses[0, 2], atol=TOLERANCE)
    assert any('10 frame(s) fitted on the markers that were seen' in note for note in notes)
    assert any('4 body markers (octo:front, octo:left, octo:right, octo:top)' in note
               for note in notes), notes


def test_markers_given_for_an_export_without_trajectories_is_a_one_line_error(
        tmp_path, model_runs):
    path = write_vicon_csv(tmp_path / 'objects.csv', np.arange(251), {'hz': 50},
                           {'octo': object_of(model_runs.poses[0])})
    with pytest.raises(BagError, match='no Trajectories section; leave --markers out'):
        read_csv(path, ReadOptions(markers=('front', 'left', 'right')))
