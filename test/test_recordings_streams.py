"""
Which streams a bag holds, decided alike by every program, and how each stream is read.

Bags are written with rosbags' rosbag2 writer. The ROS 2 motion-capture drivers' messages are
registered from their published .msg definitions (MOCAP4ROS2's `mocap4r2_msgs`,
motion_capture_tracking's `motion_capture_tracking_interfaces`), so each bag carries its own
definition, and the reader must find the array of named bodies in it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from driver_bags import Bag, mocap4r2_bag, named_pose_bag, samples, typestore
import octoroach_model as om
from octoroach_model.cli import convert_main, diagnose_main, validate_main
from octoroach_model.errors import BagError, DataError
from octoroach_model.paths import Paths
from octoroach_model.recordings import bag_topics, read_runs, ReadOptions
from octoroach_model.recordings.standard_bag.from_inputs import convert_to_bag
from octoroach_model.validation_jobs import Job, Workbench

START_NS = 1_700_000_000 * 10**9


@pytest.fixture(scope='module')
def truth() -> Paths:
    """Three model runs of 3 cycles at 50 Hz."""
    return om.simulate(3, seed=3, cycles=3)


def assert_truth(runs, paths: Paths) -> None:
    assert len(runs.runs) == paths.n_paths, runs.notes
    for run, expected in zip(runs.runs, paths.poses):
        np.testing.assert_allclose(run.poses, expected, atol=1e-6, rtol=0)


# -- arrays of named bodies ---------------------------------------------------------------

def test_a_mocap4ros2_bag_gives_the_body_that_moves_and_counts_its_occluded_frames(
        tmp_path, truth):
    source = mocap4r2_bag(tmp_path / 'mocap4r2', truth, occluded=(10, 11, 12))
    topics = bag_topics(source)
    assert topics['/rigid_bodies'].msgtype == 'mocap4r2_msgs/msg/RigidBodies'
    runs = read_runs(source)
    said = '\n'.join(runs.notes)
    assert 'poses from /rigid_bodies [mocap4r2_msgs/msg/RigidBodies], body robot' in said
    assert '3 pose(s) with an all-zero orientation (an occluded body) dropped' in said
    assert len(runs.runs) == truth.n_paths
    first = runs.runs[0]
    kept = np.setdiff1d(np.arange(len(truth.t)), [10, 11, 12])
    np.testing.assert_allclose(first.poses, truth.poses[0][kept], atol=1e-6)
    wand = read_runs(source, options=ReadOptions(topic='/rigid_bodies', subject='wand'))
    assert np.allclose(wand.runs[0].poses[:, :2], [1.0, 2.0], atol=1e-9)


def test_a_named_pose_array_of_two_moving_bodies_needs_a_subject(tmp_path, truth, capsys):
    source = named_pose_bag(tmp_path / 'crazyswarm', truth)
    with pytest.raises(BagError, match=r'several pose streams: /poses:cf1 \[motion_capture_'
                                       r'tracking_interfaces/msg/NamedPoseArray, 50 Hz\], '
                                       r'/poses:cf2 \[.*, 50 Hz\]; choose one'):
        read_runs(source)
    assert_truth(read_runs(source, options=ReadOptions(subject='cf1')), truth)
    second = read_runs(source, options=ReadOptions(topic='/poses', subject='cf2'))
    np.testing.assert_allclose(second.runs[0].poses[:, 0], truth.poses[0][:, 0] + 1.0,
                               atol=1e-6)
    with pytest.raises(BagError, match=r'several moving bodies on /poses .*\(cf1 at 50 Hz, '
                                       r'cf2 at 50 Hz\); choose one with --subject'):
        read_runs(source, options=ReadOptions(topic='/poses'))
    with pytest.raises(BagError, match=r"no stream of subject 'cf3'"):
        read_runs(source, options=ReadOptions(subject='cf3'))


# -- several streams: one decision for every program ----------------------------------------

def slam_bag(path: Path, paths: Paths) -> Path:
    """Ground truth at 50 Hz, a SLAM estimate at 10 Hz and AMCL at 2 Hz, as in a SLAM test."""
    store = typestore()
    with Bag(path, store) as bag:
        for stamp, x, y, heading in samples(paths):
            bag.write('/groundtruth', 'geometry_msgs/msg/PoseStamped', stamp,
                      bag.pose_stamped(stamp, x, y, heading))
        for stamp, x, y, heading in samples(paths, every=5):
            bag.write('/orb_slam3/pose', 'geometry_msgs/msg/PoseStamped', stamp,
                      bag.pose_stamped(stamp, x + 0.01, y, heading))
        for stamp, x, y, heading in samples(paths, every=25):
            covariance = bag.types['geometry_msgs/msg/PoseWithCovariance'](
                pose=bag.pose(x, y, heading), covariance=np.zeros(36))
            bag.write('/amcl_pose', 'geometry_msgs/msg/PoseWithCovarianceStamped', stamp,
                      bag.types['geometry_msgs/msg/PoseWithCovarianceStamped'](
                          header=bag.header(stamp, 'map'), pose=covariance))
    return path


def test_several_streams_are_listed_with_type_and_rate_and_every_program_decides_alike(
        tmp_path, truth, capsys):
    source = slam_bag(tmp_path / 'slam', truth)
    listed = (r'several pose streams: /groundtruth \[geometry_msgs/msg/PoseStamped, 50 Hz\], '
              r'/orb_slam3/pose \[geometry_msgs/msg/PoseStamped, 10 Hz\], /amcl_pose '
              r'\[geometry_msgs/msg/PoseWithCovarianceStamped, 2 Hz\]; choose one with --topic')
    lines = []
    for run in (lambda: read_runs(source),
                lambda: convert_to_bag([source], tmp_path / 'converted'),
                lambda: Workbench().measured(validator_job(source))):
        with pytest.raises(BagError, match=listed) as raised:
            run()
        lines.append(str(raised.value))
    assert validate_main([str(source)]) == 1
    assert diagnose_main([str(source), '--out', str(tmp_path / 'report')]) == 1
    assert convert_main([str(source), '--out', str(tmp_path / 'converted')]) == 1
    errors = capsys.readouterr().err.splitlines()
    assert len(errors) == 3 and all(listed.replace('\\', '')[:40] in e for e in errors), errors
    assert len(set(lines)) == 1 and not (tmp_path / 'converted').exists()
    chosen = read_runs(source, options=ReadOptions(topic='/groundtruth'))
    assert_truth(chosen, truth)


def validator_job(source: Path, **values) -> Job:
    """Make the validator node's job for `bags: [source]`, its parameters at their defaults."""
    from octoroach_model.nodes.validator import validator_specs

    defaults = {spec.name: spec.default for spec in validator_specs()}
    return Job.from_values({**defaults, **values, 'bags': [str(source)]})


def test_a_stream_too_sparse_to_form_runs_is_refused_with_its_rate(tmp_path, truth, capsys):
    source = slam_bag(tmp_path / 'slam', truth)
    sparse = r'/amcl_pose: poses at 2 Hz \(a median interval of 0.5 s\) are too sparse to ' \
             r'form runs'
    with pytest.raises(DataError, match=sparse):
        read_runs(source, options=ReadOptions(topic='/amcl_pose'))
    with pytest.raises(DataError, match=sparse):
        Workbench().measured(validator_job(source, topic='/amcl_pose'))
    assert validate_main([str(source), '--topic', '/amcl_pose']) == 1
    assert '--gap-s above 1 s' in capsys.readouterr().err
    runs = read_runs(source, options=ReadOptions(topic='/amcl_pose'), gap_s=1.5)
    assert len(runs.runs) == truth.n_paths


def vicon_robots_bag(path: Path, paths: Paths) -> Path:
    """Two robots on their VICON topics, as the recorder records the simulator's robots."""
    with Bag(path, typestore()) as bag:
        transform = bag.types['geometry_msgs/msg/TransformStamped']
        for stamp, x, y, heading in samples(paths):
            for subject, shift in (('roach_a', 0.0), ('roach_b', 2.0)):
                pose = bag.pose(x + shift, y, heading)
                bag.write(f'/vicon/{subject}/{subject}', 'geometry_msgs/msg/TransformStamped',
                          stamp, transform(
                              header=bag.header(stamp, 'vicon/world'),
                              child_frame_id=f'vicon/{subject}/{subject}',
                              transform=bag.types['geometry_msgs/msg/Transform'](
                                  translation=bag.types['geometry_msgs/msg/Vector3'](
                                      x=pose.position.x, y=pose.position.y, z=0.0),
                                  rotation=pose.orientation)))
    return path


def test_several_vicon_subjects_are_several_robots_for_every_program(tmp_path, truth):
    source = vicon_robots_bag(tmp_path / 'robots', truth)
    runs = read_runs(source)
    assert len(runs.runs) == 2 * truth.n_paths
    assert any('2 pose streams, read as 2 robots' in note for note in runs.notes)
    report = convert_to_bag([source], tmp_path / 'standard')
    assert set(bag_topics(report.bag)) == {'/vicon/roach_a/roach_a', '/roach_a/run_start',
                                           '/vicon/roach_b/roach_b', '/roach_b/run_start'}
    converted = read_runs(report.bag)
    assert len(converted.runs) == 2 * truth.n_paths
    only_b = read_runs(source, options=ReadOptions(subject='roach_b'))
    assert len(only_b.runs) == truth.n_paths
    np.testing.assert_allclose(only_b.runs[0].poses[:, 0], truth.poses[0][:, 0] + 2.0,
                               atol=1e-9)


# -- clocks ---------------------------------------------------------------------------------

def clock_bag(path: Path, paths: Paths, bursty_logs: bool) -> Path:
    """
    Poses whose header stamps and log times disagree, as drivers stamp them.

    bursty_logs: stamps are the camera's (steady), log times arrive in bursts of five 0.1 ms
    apart. Otherwise stamps jitter by +-6 ms (a receive clock on a busy machine) and the
    log times are steady.
    """
    rng = np.random.default_rng(7)
    with Bag(path, typestore()) as bag:
        for index, (stamp, x, y, heading) in enumerate(samples(paths)):
            if bursty_logs:
                header, log = stamp, stamp - stamp % (5 * 20_000_000) + 100_000 * (index % 5) \
                    + 80_000_000
            else:
                header, log = stamp + int(rng.uniform(-6e6, 6e6)), stamp + 1_000_000
            bag.write('/mocap/robot', 'geometry_msgs/msg/PoseStamped', log,
                      bag.pose_stamped(header, x, y, heading))
    return path


@pytest.mark.parametrize('bursty_logs', [True, False])
def test_the_steadier_clock_is_used_and_the_notes_say_which(tmp_path, truth, bursty_logs):
    source = clock_bag(tmp_path / 'clocks', truth, bursty_logs)
    runs = read_runs(source)
    (clock,) = [note for note in runs.notes if ': clock: ' in note]
    if bursty_logs:
        assert 'clock: header stamps used, the steadier: 50 Hz (median interval 20 ms, ' \
               'jitter 0 ms); log (receive) times: median interval 0.1 ms' in clock
        assert_truth(runs, truth)
    else:
        assert 'clock: log (receive) times used, the steadier: 50 Hz (median interval 20 ms' \
               in clock and 'header stamps: median interval' in clock
        for run in runs.runs:   # the log times are the true sample times plus 1 ms
            np.testing.assert_allclose(run.t, truth.t, atol=1e-9)
