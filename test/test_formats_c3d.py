"""C3D files (written by ezc3d, read with the c3d package) and the rigid fit behind them."""
from __future__ import annotations

from pathlib import Path

from hypothesis import assume, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap_helpers import (
    BODY_LAYOUT_M,
    body_rotations,
    markers_on_body,
    runs_from_chunks,
    write_c3d,
)
import octoroach_model as om
from octoroach_model.errors import BagError
from octoroach_model.paths import Paths
from octoroach_model.recordings import read_runs, write_paths_bag
from octoroach_model.recordings.conventions.axes import headings_from_rotations
from octoroach_model.recordings.mocap.c3d_file import iter_c3d_pose_chunks
from octoroach_model.recordings.mocap.rigid import (
    fit_rigid,
    layout_from_frames,
    layout_spans_a_plane,
)
from octoroach_model.recordings.options import ReadOptions

RATE_HZ = 50.0
SEED = 21
TOLERANCE = 1e-6  # m and rad: C3D stores float32 millimetres, which still meets it


@pytest.fixture(scope='module')
def model_runs() -> Paths:
    """Four model runs of 10 cycles at 50 Hz."""
    return om.simulate(4, seed=SEED)


def labelled(markers: dict, subject: str = 'octoroach') -> dict:
    return {f'{subject}:{name}': values for name, values in markers.items()}


def read_c3d(path: Path, options: ReadOptions | None = None, notes: list | None = None,
             chunk_size: int = 10_000, layout=None):
    notes = [] if notes is None else notes
    chunks = iter_c3d_pose_chunks(path, options or ReadOptions(), notes, chunk_size,
                                  layout=layout)
    return runs_from_chunks(chunks)


def test_c3d_files_with_the_layout_are_read_into_the_same_runs_as_the_bag(tmp_path,
                                                                          model_runs):
    bag_runs = read_runs(write_paths_bag(tmp_path / 'bag', model_runs)).runs
    c3d_runs = []
    for index, poses in enumerate(model_runs.poses):
        markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.012)
        path = write_c3d(tmp_path / f'walk{index}.c3d', RATE_HZ, labelled(markers),
                         first_frame=1 + 7 * index)
        notes: list[str] = []
        c3d_runs += read_c3d(path, notes=notes, chunk_size=100, layout=BODY_LAYOUT_M).runs
        assert any('positions in mm converted to m' in note and 'the given layout' in note
                   for note in notes), notes
    assert len(c3d_runs) == len(bag_runs)
    for run, reference in zip(c3d_runs, bag_runs):
        np.testing.assert_allclose(run.t, reference.t, atol=1e-9)
        np.testing.assert_allclose(run.poses, reference.poses, atol=TOLERANCE, rtol=0)


def test_without_a_layout_the_body_frame_is_the_world_frame_at_the_first_complete_frame(
        tmp_path, model_runs):
    poses = model_runs.poses[1]
    markers = markers_on_body(poses, BODY_LAYOUT_M)
    markers['top'][:5] = np.nan  # the first complete frame is frame 6
    path = write_c3d(tmp_path / 'walk.c3d', RATE_HZ, labelled(markers))
    notes: list[str] = []
    run = read_c3d(path, notes=notes).runs[0]
    centroid = body_rotations(poses[:, 2]).apply(np.mean(list(BODY_LAYOUT_M.values()), 0))
    np.testing.assert_allclose(run.poses[:, 0], poses[:, 0] + centroid[:, 0], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 1], poses[:, 1] + centroid[:, 1], atol=TOLERANCE)
    np.testing.assert_allclose(run.poses[:, 2], poses[:, 2] - poses[5, 2], atol=TOLERANCE)
    assert any('first 10 complete frame(s) from frame 6' in note for note in notes), notes


def test_hidden_markers_are_dropped_frames_only_below_three(tmp_path, model_runs):
    poses = np.concatenate([model_runs.poses[0], np.zeros((75, 3)), model_runs.poses[2]])
    markers = markers_on_body(poses, BODY_LAYOUT_M)
    markers['left'][30:40] = np.nan  # three markers left: still a pose
    markers['front'][100:103] = np.nan
    markers['right'][100:103] = np.nan  # two left: dropped frames
    for name in ('front', 'left', 'right'):
        markers[name][251:326] = np.nan  # 1.5 s between trials: a gap that splits runs
    path = write_c3d(tmp_path / 'two_trials.c3d', RATE_HZ, labelled(markers))
    notes: list[str] = []
    run_set = read_c3d(path, notes=notes, chunk_size=64, layout=BODY_LAYOUT_M)
    assert len(run_set) == 2
    first, second = run_set.runs
    assert len(first.t) == 251 - 3 and len(second.t) == 251
    kept = np.setdiff1d(np.arange(251), [100, 101, 102])
    np.testing.assert_allclose(first.poses, model_runs.poses[0][kept], atol=TOLERANCE, rtol=0)
    np.testing.assert_allclose(second.poses, model_runs.poses[2], atol=TOLERANCE, rtol=0)
    assert any('78 of 577 frame(s) with fewer than 3 of the body markers' in note
               for note in notes), notes
    assert any('10 frame(s) fitted on the markers that were seen' in note for note in notes)


def test_several_subjects_need_a_subject(tmp_path, model_runs):
    robot = labelled(markers_on_body(model_runs.poses[0], BODY_LAYOUT_M), 'octoroach')
    other = labelled(markers_on_body(model_runs.poses[3], BODY_LAYOUT_M), 'wand')
    path = write_c3d(tmp_path / 'two.c3d', RATE_HZ, {**robot, **other})
    with pytest.raises(BagError, match=r'several subjects \(octoroach, wand\); pass '
                                       r'--subject NAME') as raised:
        read_c3d(path)
    assert '\n' not in str(raised.value)
    wand = read_c3d(path, ReadOptions(subject='wand'), layout=BODY_LAYOUT_M).runs[0]
    np.testing.assert_allclose(wand.poses, model_runs.poses[3], atol=TOLERANCE, rtol=0)


def test_fewer_than_three_markers_on_the_body_name_what_to_pass(tmp_path, model_runs):
    markers = markers_on_body(model_runs.poses[0], BODY_LAYOUT_M)
    path = write_c3d(tmp_path / 'sparse.c3d', RATE_HZ,
                     {'octoroach:front': markers['front'], 'octoroach:left': markers['left'],
                      'wand:tip': markers['top']})
    with pytest.raises(BagError, match=r'2 marker\(s\) on the body \(octoroach:front, '
                                       r'octoroach:left\); a rigid fit needs at least 3: '
                                       r'pass --subject NAME or --markers') as raised:
        read_c3d(path, ReadOptions(subject='octoroach'))
    assert '\n' not in str(raised.value)
    with pytest.raises(BagError, match=r"no marker 'rear'; it has octoroach:front"):
        read_c3d(path, ReadOptions(markers=('front', 'left', 'rear')))


def test_named_markers_leave_out_a_loose_one(tmp_path, model_runs):
    poses = model_runs.poses[1]
    markers = markers_on_body(poses, BODY_LAYOUT_M)
    print(f'seed={SEED}')
    wobble = np.random.default_rng(SEED).normal(0, 0.01, (len(poses), 3))
    markers['cable'] = markers['top'] + wobble  # not on the rigid body
    path = write_c3d(tmp_path / 'loose.c3d', RATE_HZ, labelled(markers))
    layout = {name: BODY_LAYOUT_M[name] for name in ('front', 'left', 'right')}
    options = ReadOptions(markers=('front', 'left', 'right'))
    run = read_c3d(path, options, layout=layout).runs[0]
    np.testing.assert_allclose(run.poses, poses, atol=TOLERANCE, rtol=0)


def test_metres_forward_axis_y_and_model_outputs(tmp_path, model_runs):
    poses = model_runs.poses[2]
    sideways_layout = {name: (-y, x, z) for name, (x, y, z) in BODY_LAYOUT_M.items()}
    markers = markers_on_body(poses, BODY_LAYOUT_M)  # the same markers, body y forward
    path = write_c3d(tmp_path / 'metres.c3d', RATE_HZ, markers, units='m',
                     subjects=['octoroach'],
                     model_outputs={'octoroach:LKneeAngles': np.ones((len(poses), 3))})
    notes: list[str] = []
    run = read_c3d(path, ReadOptions(forward_axis='y'), notes,
                   layout=sideways_layout).runs[0]
    np.testing.assert_allclose(run.poses, poses, atol=TOLERANCE, rtol=0)
    assert any('positions in m;' in note and 'body y axis' in note for note in notes), notes
    notes = []
    read_c3d(path, notes=notes)  # the body is every marker of the subject, not its angles
    assert any('4 body markers (front, left, right, top)' in note for note in notes), notes


def nexus_trial(tmp_path, poses: np.ndarray, *, swing_m: float = 0.0) -> Path:
    """
    Write a Nexus trial of subject SI02, its labels without prefix.

    Its points: the plate's four markers, a knee and an ankle marker on a leg that swings by
    `swing_m`, and two points the model computed (a segment origin and a joint centre,
    listed in POINT:MODELED_MARKERS).
    """
    markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.01)
    phase = np.arange(len(poses)) * 2 * np.pi / 25
    leg = np.column_stack([swing_m * np.sin(phase), np.zeros(len(poses)),
                           0.3 * swing_m * np.cos(phase)])
    markers['LKNE'] = markers['left'] + [0.02, 0.03, -0.01] + leg
    markers['LANK'] = markers['left'] + [0.05, 0.04, -0.02] + 2 * leg
    markers['PELO'] = markers['front'] + np.column_stack([np.sin(phase), np.cos(phase),
                                                          np.zeros(len(poses))]) * 0.05
    markers['LKJC'] = markers['LKNE'] * 0.5 + markers['LANK'] * 0.5
    return write_c3d(tmp_path / 'SI02_walk.c3d', RATE_HZ, markers, subjects=['SI02'],
                     modelled=['PELO', 'LKJC'], uses_prefixes=False)


def test_a_nexus_trial_leaves_modelled_markers_out_and_takes_subject_prefixed_names(
        tmp_path, model_runs):
    poses = model_runs.poses[0]
    path = nexus_trial(tmp_path, poses)   # the leg does not swing: one rigid body
    notes: list[str] = []
    read_c3d(path, notes=notes)
    said = '\n'.join(notes)
    assert '2 modelled or virtual marker(s) left out of the body (POINT:MODELED_MARKERS): ' \
           'PELO, LKJC' in said
    assert '6 body markers (front, left, right, top, LKNE, LANK)' in said
    named = ReadOptions(markers=('SI02:front', 'SI02:left', 'SI02:right', 'top'))
    run = read_c3d(path, named, layout={name: BODY_LAYOUT_M[name]
                                        for name in ('front', 'left', 'right', 'top')}).runs[0]
    np.testing.assert_allclose(run.poses, poses, atol=TOLERANCE, rtol=0)
    with pytest.raises(BagError, match=r"no marker 'SI03:front'"):
        read_c3d(path, ReadOptions(markers=('SI03:front', 'left', 'right')))


def test_markers_that_are_not_one_rigid_body_are_refused_naming_those_that_fit_best(
        tmp_path, model_runs):
    path = nexus_trial(tmp_path, model_runs.poses[0], swing_m=0.04)
    with pytest.raises(BagError, match=r'the 6 body markers do not move as one rigid body: '
                                       r"the rigid fit's typical residual is [\d.]+ mm, above "
                                       r'the 5 mm a rigid body allows; the markers that keep '
                                       r'their distances best are front, left, right, top '
                                       r'\(within [\d.e-]+ mm\): pass them with --markers, or '
                                       r'--accept-loose-fit') as raised:
        read_c3d(path)
    assert '\n' not in str(raised.value)
    notes: list[str] = []
    runs = read_c3d(path, ReadOptions(accept_loose_fit=True), notes=notes)
    assert len(runs.runs) == 1
    assert any('rigid fit rms residual' in note for note in notes)


def test_unreadable_files_are_one_line_errors(tmp_path):
    garbage = tmp_path / 'garbage.c3d'
    garbage.write_bytes(b'not a c3d file at all' * 40)
    with pytest.raises(BagError, match='not a readable C3D file') as raised:
        read_c3d(garbage)
    assert '\n' not in str(raised.value)
    with pytest.raises(BagError, match='cannot open'):
        read_c3d(tmp_path / 'missing.c3d')


def test_a_layout_on_one_line_is_refused(tmp_path, model_runs):
    markers = markers_on_body(model_runs.poses[0], BODY_LAYOUT_M)
    path = write_c3d(tmp_path / 'walk.c3d', RATE_HZ, labelled(markers))
    line = {'front': (0.1, 0, 0), 'left': (0.0, 0, 0), 'right': (-0.1, 0, 0)}
    with pytest.raises(BagError, match='does not span a plane'):
        read_c3d(path, layout=line)
    with pytest.raises(BagError, match=r'layout of marker left must be \(x, y, z\) in metres, '
                                       'got a tuple'):
        read_c3d(path, layout={'front': (0.1, 0, 0), 'left': (0.0, 1), 'right': (0, 0, 1)})


def test_a_body_never_seen_whole_has_no_layout(tmp_path, model_runs):
    markers = markers_on_body(model_runs.poses[0], BODY_LAYOUT_M)
    markers['front'][::2] = np.nan
    markers['top'][1::2] = np.nan
    path = write_c3d(tmp_path / 'walk.c3d', RATE_HZ, labelled(markers))
    with pytest.raises(BagError, match='no frame shows all of'):
        read_c3d(path)


# ---------------------------------------------------------------------------------------------
# The rigid fit itself: any rotation and translation, noise-free markers give the exact pose.

unit_floats = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = st.tuples(unit_floats, unit_floats, unit_floats, unit_floats).filter(
    lambda q: np.linalg.norm(q) > 0.1)
translations = st.tuples(*[st.floats(-50.0, 50.0, allow_nan=False)] * 3)
layouts = st.lists(st.tuples(*[st.floats(-0.3, 0.3, allow_nan=False)] * 3), min_size=3,
                   max_size=8)


@settings(max_examples=200, deadline=None)
@given(quaternion=quaternions, translation=translations, layout=layouts,
       hidden=st.lists(st.integers(0, 7), max_size=5))
def test_rigid_fit_recovers_any_pose_exactly(quaternion, translation, layout, hidden):
    layout = np.array(layout)
    assume(_well_spread(layout))
    rotation = Rotation.from_quat(quaternion)
    seen = np.ones(len(layout), bool)
    seen[[index for index in hidden if index < len(layout)]] = False
    assume(seen.sum() >= 3 and _well_spread(layout[seen]))
    markers = rotation.apply(layout) + np.array(translation)
    markers[~seen] = np.nan
    fit = fit_rigid(layout, markers[None])
    assert fit.valid[0]
    np.testing.assert_allclose(fit.rotation[0], rotation.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(fit.translation[0], translation, atol=1e-9)
    assert fit.rms_residual[0] < 1e-9


@settings(max_examples=100, deadline=None)
@given(heading=st.floats(-np.pi, np.pi), roll=st.floats(-1.0, 1.0),
       pitch=st.floats(-1.0, 1.0), axis=st.sampled_from(['x', 'y', '-x', '-y']))
def test_heading_is_the_yaw_of_the_forward_axis(heading, roll, pitch, axis):
    options = ReadOptions(forward_axis=axis)
    rotation = body_rotations(np.array([heading]), np.array([roll]), np.array([pitch]),
                              options.heading_offset_rad)
    found = headings_from_rotations(rotation.as_matrix(), 'z', axis)[0]
    assert abs(np.angle(np.exp(1j * (found - heading)))) < 1e-9


def _well_spread(layout: np.ndarray) -> bool:
    """Markers far enough from one line that the fit is well conditioned."""
    spread = np.linalg.svd(layout - layout.mean(axis=0), compute_uv=False)
    return bool(spread[1] > 0.02 and spread[1] > 0.05 * spread[0])


def test_too_few_or_collinear_markers_are_not_a_pose():
    layout = np.array([[0.0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.2, 0, 0]])
    markers = np.repeat(layout[None], 3, axis=0)
    markers[0, [1, 2]] = np.nan  # two seen
    markers[1, 2] = np.nan  # three seen, on one line
    fit = fit_rigid(layout, markers)
    assert fit.valid.tolist() == [False, False, True]
    assert np.isnan(fit.rotation[:2]).all()
    assert layout_spans_a_plane(layout) and not layout_spans_a_plane(layout[[0, 1, 3]])


def test_layout_from_noisy_frames_averages_in_the_body_frame():
    seed = 5
    print(f'seed={seed}')
    rng = np.random.default_rng(seed)
    layout = np.array(list(BODY_LAYOUT_M.values()))
    rotations = Rotation.random(10, random_state=seed)
    frames = np.stack([r.apply(layout) for r in rotations]) + rng.normal(0, 1e-4, (10, 4, 3))
    found = layout_from_frames(frames)
    # The body frame is the first frame's orientation at the centroid: compare shapes.
    fit = fit_rigid(found, (layout - layout.mean(0))[None])
    assert fit.rms_residual[0] < 1e-4


def test_a_cut_file_is_read_up_to_the_cut_and_its_shortened_run_dropped(
        tmp_path, model_runs):
    poses = np.concatenate([model_runs.poses[0], np.zeros((60, 3)), model_runs.poses[1]])
    markers = markers_on_body(poses, BODY_LAYOUT_M)
    for values in markers.values():
        values[251:311] = np.nan
    path = write_c3d(tmp_path / 'cut.c3d', RATE_HZ, labelled(markers))
    frame_bytes = 4 * 4 * len(markers)  # float32 x, y, z, residual per marker
    data = path.read_bytes()
    path.write_bytes(data[:len(data) - (len(data) % 512) - 100 * frame_bytes])
    notes: list[str] = []
    run_set = read_c3d(path, notes=notes, layout=BODY_LAYOUT_M)
    assert any('truncated' in note for note in notes), notes
    assert len(run_set) == 1
    np.testing.assert_allclose(run_set.runs[0].poses, model_runs.poses[0], atol=TOLERANCE,
                               rtol=0)
    assert any('cut by the truncation' in note for note in run_set.notes), run_set.notes
