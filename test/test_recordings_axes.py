"""
Up is not always z: every reader turns its input's world to z up, and says when up looks wrong.

The same model runs are written in a y-up world (OptiTrack Motive's default), in a camera's
optical frame (y down, z forward) and in a z-up world; each must read back into the same runs
with the matching --up-axis / --forward-axis, and a y-up file read as z up must get one note
naming the axis that fits. What is written (convert) is z up, as REP 103 wants.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from driver_bags import Bag, samples, typestore
from mocap_helpers import BODY_LAYOUT_M, markers_on_body, runs_from_chunks, write_c3d
import octoroach_model as om
from octoroach_model.cli import validate_main
from octoroach_model.errors import ParameterError
from octoroach_model.paths import Paths
from octoroach_model.recordings import bag_topics, read_runs, ReadOptions
from octoroach_model.recordings.conventions.axes import (
    QUATERNION_NORM_TOLERANCE,
    to_z_up,
    UP_ROTATIONS,
)
from octoroach_model.recordings.mocap.c3d_file import iter_c3d_pose_chunks
from octoroach_model.recordings.standard_bag.from_inputs import convert_to_bag
from trajectory_writers import EPOCH_S, planar_pose, write_tum

TOLERANCE = 1e-6
# a camera's optical axes in the body frame of a robot (x forward, z up): z forward, x right,
# y down
CAMERA_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@pytest.fixture(scope='module')
def truth() -> Paths:
    return om.simulate(3, seed=9, cycles=4)


def session(paths: Paths) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (ns), planar positions and headings of every run, 4 s apart."""
    stamps = np.concatenate([EPOCH_S * 10**9 + run * 4 * 10**9
                             + np.round(paths.t * 1e9).astype(np.int64)
                             for run in range(paths.n_paths)])
    poses = paths.poses.reshape(-1, 3)
    return stamps, poses, poses[:, 2]


def in_world(up_axis: str, positions: np.ndarray, rotations: Rotation
             ) -> tuple[np.ndarray, Rotation]:
    """Express z-up positions and orientations in a world whose up axis is `up_axis`."""
    back = UP_ROTATIONS[up_axis].T  # z-up world -> that world
    return positions @ back.T, Rotation.from_matrix(back) * rotations


def assert_truth(runs, paths: Paths) -> None:
    assert len(runs.runs) == paths.n_paths, runs.notes
    for run, expected in zip(runs.runs, paths.poses):
        np.testing.assert_allclose(run.poses, expected, atol=TOLERANCE, rtol=0)


def test_a_y_up_trajectory_reads_with_up_axis_y_and_says_when_up_looks_wrong(
        tmp_path, truth, capsys):
    stamps, poses, _ = session(truth)
    positions, rotations = in_world('y', *planar_pose(poses, height_m=0.05))
    path = write_tum(tmp_path / 'motive.txt', stamps, positions, rotations)
    assert_truth(read_runs(path, options=ReadOptions(up_axis='y')), truth)
    side_view = read_runs(path)
    (said,) = [note for note in side_view.notes if 'the up axis looks wrong' in note]
    assert "with --up-axis z; the motion is flattest along the input's y axis: --up-axis y " \
           '(or -y if it points down) fits' in said
    validate_main([str(path), '--k', '2'])
    err = capsys.readouterr().err
    assert 'note: ' in err and 'the up axis looks wrong' in err   # printed, one line
    upright = read_runs(path, options=ReadOptions(up_axis='y'))
    assert not [note for note in upright.notes if 'the up axis looks wrong' in note]


def test_a_camera_frame_reads_with_its_forward_and_up_axes(tmp_path, truth):
    """Camera poses (z forward, y down) in a world whose y points down, as camera SLAM has."""
    stamps, poses, _ = session(truth)
    positions, rotations = planar_pose(poses, height_m=0.3)
    camera = rotations * Rotation.from_matrix(CAMERA_IN_BODY)
    positions, camera = in_world('-y', positions, camera)
    path = write_tum(tmp_path / 'orb_slam.txt', stamps, positions, camera)
    runs = read_runs(path, options=ReadOptions(up_axis='-y', forward_axis='z'))
    assert_truth(runs, truth)


def test_a_y_up_bag_converts_to_the_z_up_standard_bag(tmp_path, truth):
    with Bag(tmp_path / 'motive_bag', typestore()) as bag:
        for stamp, x, y, heading in samples(truth):
            where, turned = in_world('y', np.array([x, y, 0.04]),
                                     Rotation.from_euler('z', heading))
            bag.write('/natnet/robot', 'geometry_msgs/msg/PoseStamped', stamp,
                      bag.pose_stamped(stamp, where[0], where[1], 0.0, where[2],
                                       quaternion=turned.as_quat()))
    options = ReadOptions(up_axis='y')
    assert_truth(read_runs(tmp_path / 'motive_bag', options=options), truth)
    report = convert_to_bag([tmp_path / 'motive_bag'], tmp_path / 'standard', options=options)
    assert set(bag_topics(report.bag)) == {'/vicon/octoroach/octoroach',
                                           '/octoroach/run_start'}
    assert_truth(read_runs(report.bag), truth)   # z up: read without any axis option


def test_c3d_markers_in_a_y_up_world_are_fitted_after_the_turn(tmp_path, truth):
    poses = truth.poses[0]
    markers = markers_on_body(poses, BODY_LAYOUT_M, height_m=0.02)
    turned = {f'robot:{name}': to_z_up(points, '-y') * 1.0 for name, points in markers.items()}
    # to_z_up(., '-y') is the turn from a y-up world to z up's inverse: it writes y up
    np.testing.assert_allclose(to_z_up(turned['robot:front'], 'y'), markers['front'],
                               atol=1e-12)
    path = write_c3d(tmp_path / 'yup.c3d', 50.0, turned)
    notes: list[str] = []
    chunks = iter_c3d_pose_chunks(path, ReadOptions(up_axis='y'), notes,
                                  layout=BODY_LAYOUT_M)
    run = runs_from_chunks(chunks).runs[0]
    np.testing.assert_allclose(run.poses, poses, atol=TOLERANCE, rtol=0)
    assert any("the input's y axis turned to up (z)" in note for note in notes), notes


def test_a_frame_that_only_spins_moves_and_non_unit_quaternions_are_dropped(tmp_path, truth):
    """A wheel spinning in place on /tf is the moving frame; a scaled quaternion is no pose."""
    with Bag(tmp_path / 'wheel', typestore()) as bag:
        transform = bag.types['geometry_msgs/msg/TransformStamped']
        for index, (stamp, _, _, _) in enumerate(samples(truth)):
            spin = Rotation.from_euler('y', 0.2 * index).as_quat()   # about its axle
            scale = 1.5 if index == 20 else 1.0 + QUATERNION_NORM_TOLERANCE / 2
            frames = [('chassis', (0.0, 0.0, 0.0, 1.0)), ('wheel', tuple(spin * scale))]
            message = bag.types['tf2_msgs/msg/TFMessage'](transforms=[transform(
                header=bag.header(stamp, 'world'), child_frame_id=child,
                transform=bag.types['geometry_msgs/msg/Transform'](
                    translation=bag.types['geometry_msgs/msg/Vector3'](x=0.5, y=0.0, z=0.1),
                    rotation=bag.types['geometry_msgs/msg/Quaternion'](
                        x=q[0], y=q[1], z=q[2], w=q[3]))) for child, q in frames])
            bag.write('/tf', 'tf2_msgs/msg/TFMessage', stamp, message)
    runs = read_runs(tmp_path / 'wheel')
    said = '\n'.join(runs.notes)
    assert 'child frame wheel' in said
    assert '1 pose(s) whose orientation is not a rotation' in said
    assert sum(len(run.t) for run in runs.runs) == truth.n_paths * len(truth.t) - 1


def test_an_unknown_axis_is_refused(capsys):
    with pytest.raises(ParameterError, match='up axis must be one of z, y, -y, x, -x, -z'):
        ReadOptions(up_axis='up')
    with pytest.raises(SystemExit) as stopped:
        validate_main(['bags/', '--up-axis', 'w'])
    assert stopped.value.code == 2 and "invalid choice: 'w'" in capsys.readouterr().err
    assert math.isclose(ReadOptions(forward_axis='-y').heading_offset_rad, -math.pi / 2)
