"""Runs: splitting, the common grid, and data sets that keep the result."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from octoroach_model.errors import DataError
from octoroach_model.paths import Paths
from octoroach_model.recordings import (
    load_dataset,
    load_measured,
    PoseBagWriter,
    read_runs,
    Run,
    RunSet,
    save_dataset,
    write_paths_bag,
)

RATE_HZ = 50.0
START_NS = 1_700_000_000 * 10**9


def straight_run(duration_s: float, rate_hz: float = RATE_HZ, speed: float = 0.2) -> Run:
    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    poses = np.column_stack([np.zeros_like(t), speed * t, np.full_like(t, np.pi / 2)])
    return Run(t, poses, f'test run {duration_s}', 0.0)


def test_runs_of_unequal_length_each_keep_all_their_samples() -> None:
    run_set = RunSet([straight_run(3.0), straight_run(2.0), straight_run(2.5)])
    paths = run_set.to_paths(rate_hz=RATE_HZ)
    assert paths.t[-1] == pytest.approx(3.0)
    assert paths.poses.shape == (3, 151, 3)
    assert list(paths.lengths) == [151, 101, 126] and paths.well_formed and paths.ragged
    np.testing.assert_allclose(paths.poses[1, 100], run_set.runs[1].poses[-1])
    assert np.isnan(paths.poses[1, 101:]).all()
    assert any('2 of 3 runs end before the longest' in note for note in paths.info['notes'])


def test_min_duration_drops_shorter_runs_with_a_note() -> None:
    run_set = RunSet([straight_run(3.0), straight_run(0.4), straight_run(2.5)])
    paths = run_set.to_paths(rate_hz=RATE_HZ, min_duration_s=2.0)
    assert paths.n_paths == 2
    assert paths.t[-1] == pytest.approx(3.0) and list(paths.lengths) == [151, 126]
    assert any('1 run(s) shorter than 2 s dropped' in note for note in paths.info['notes'])


def test_no_run_long_enough_is_a_data_error() -> None:
    with pytest.raises(DataError, match='no run lasts 5 s'):
        RunSet([straight_run(1.0)]).to_paths(min_duration_s=5.0)


def test_an_empty_run_set_cannot_be_resampled() -> None:
    with pytest.raises(DataError, match='no runs to resample'):
        RunSet().to_paths()


def test_a_bad_rate_is_a_data_error() -> None:
    with pytest.raises(DataError, match='positive number of Hz'):
        RunSet([straight_run(1.0)]).to_paths(rate_hz=0.0)


def test_resampling_at_another_rate_interpolates_linearly() -> None:
    paths = RunSet([straight_run(2.0, rate_hz=100.0)]).to_paths(rate_hz=10.0)
    np.testing.assert_allclose(paths.t, np.arange(21) / 10.0)
    np.testing.assert_allclose(paths.poses[0, :, 1], 0.2 * paths.t, atol=1e-12)
    assert paths.rate_hz == pytest.approx(10.0)


def test_paths_info_records_sources_notes_and_rate() -> None:
    run_set = RunSet([straight_run(1.0)], notes=['something was repaired'])
    info = run_set.to_paths().info
    assert info['sources'] == ['test run 1.0']
    assert info['notes'] == ['something was repaired']
    assert info['rate_hz'] == RATE_HZ


def test_heading_stays_continuous_across_plus_minus_pi(tmp_path: Path) -> None:
    t = np.arange(301) / RATE_HZ
    spinning = np.pi / 2 + 2.0 * t  # turns through +-pi twice
    poses = np.stack([np.zeros_like(t), np.zeros_like(t), spinning], axis=-1)[None]
    bag = write_paths_bag(tmp_path / 'spin', Paths(t, poses))
    (run,) = read_runs(bag).runs
    np.testing.assert_allclose(run.poses[:, 2], spinning, atol=1e-9)


def test_a_gap_inside_a_marker_run_is_bridged_and_noted(tmp_path: Path) -> None:
    stamps = START_NS + np.arange(200) * 20_000_000
    stamps[100:] += 1_000_000_000  # 1 s of nothing in the middle of the run
    poses = np.column_stack([np.zeros(200), np.arange(200) * 0.01, np.zeros(200)])
    with PoseBagWriter(tmp_path / 'burst') as writer:
        writer.write_marker(0, int(stamps[0]))
        writer.write_poses(stamps, poses)
    run_set = read_runs(tmp_path / 'burst')
    (run,) = run_set.runs
    assert run.duration_s == pytest.approx(199 * 0.02 + 1.0)
    assert any('run 0: 1 gap(s) longer than 0.5 s (up to 1.02 s) bridged' in note
               for note in run_set.notes)


def test_the_same_gap_without_markers_splits_the_run(tmp_path: Path) -> None:
    stamps = START_NS + np.arange(200) * 20_000_000
    stamps[100:] += 1_000_000_000
    poses = np.column_stack([np.zeros(200), np.arange(200) * 0.01, np.zeros(200)])
    with PoseBagWriter(tmp_path / 'burst', marker_topic=None) as writer:
        writer.write_poses(stamps, poses)
    assert [len(run.t) for run in read_runs(tmp_path / 'burst').runs] == [100, 100]


def test_samples_before_the_first_marker_are_ignored_with_a_note(tmp_path: Path) -> None:
    stamps = START_NS + np.arange(100) * 20_000_000
    poses = np.zeros((100, 3))
    with PoseBagWriter(tmp_path / 'late_marker') as writer:
        writer.write_poses(stamps[:30], poses[:30])
        writer.write_marker(0, int(stamps[30]))
        writer.write_poses(stamps[30:], poses[30:])
    run_set = read_runs(tmp_path / 'late_marker')
    assert [len(run.t) for run in run_set.runs] == [70]
    assert any('30 sample(s) before the first run marker ignored' in note
               for note in run_set.notes)


def test_a_gap_shorter_than_gap_s_is_not_a_split(tmp_path: Path) -> None:
    stamps = START_NS + np.arange(100) * 20_000_000
    stamps[50:] += 300_000_000
    with PoseBagWriter(tmp_path / 'short_gap', marker_topic=None) as writer:
        writer.write_poses(stamps, np.zeros((100, 3)))
    assert len(read_runs(tmp_path / 'short_gap', gap_s=0.5).runs) == 1
    assert len(read_runs(tmp_path / 'short_gap', gap_s=0.2).runs) == 2


def test_a_data_set_round_trips_with_its_provenance(tmp_path: Path) -> None:
    paths = RunSet([straight_run(2.0), straight_run(2.0)], notes=['a note']).to_paths()
    saved = save_dataset(tmp_path / 'measured.npz', paths)
    loaded = load_dataset(saved)
    np.testing.assert_array_equal(loaded.t, paths.t)
    np.testing.assert_array_equal(loaded.poses, paths.poses)
    assert loaded.info['notes'] == ['a note']
    assert loaded.info['format_version'] == 1
    assert loaded.info['rate_hz'] == pytest.approx(RATE_HZ)
    with np.load(saved, allow_pickle=False) as archive:
        assert sorted(archive.files) == ['info_json', 'poses', 't']


def test_a_data_set_keeps_numpy_values_in_its_info(tmp_path: Path) -> None:
    paths = Paths(np.arange(3) / RATE_HZ, np.zeros((1, 3, 3)),
                  {'seed': np.int64(7), 'sigma': np.array([0.1, 0.2]), 'path': tmp_path})
    loaded = load_dataset(save_dataset(tmp_path / 'x.npz', paths))
    assert loaded.info['seed'] == 7 and loaded.info['sigma'] == [0.1, 0.2]
    assert loaded.info['path'] == str(tmp_path)


@pytest.mark.parametrize('content, reason', [
    (b'plain text', 'not a multisample data set'),
    (None, 'missing info_json'),
])
def test_a_wrong_file_is_not_loaded_as_a_data_set(tmp_path: Path, content: bytes | None,
                                                  reason: str) -> None:
    path = tmp_path / 'wrong.npz'
    if content is None:
        np.savez(path, t=np.zeros(3), poses=np.zeros((1, 3, 3)))
    else:
        path.write_bytes(content)
    with pytest.raises(DataError, match=reason):
        load_dataset(path)


def test_a_missing_data_set_is_a_data_error(tmp_path: Path) -> None:
    with pytest.raises(DataError, match='no such data set file'):
        load_dataset(tmp_path / 'absent.npz')


def test_load_measured_mixes_bags_and_data_sets_on_one_grid(tmp_path: Path) -> None:
    t = np.arange(151) / RATE_HZ
    poses = np.stack([np.zeros_like(t), 0.2 * t, np.full_like(t, np.pi / 2)], axis=-1)
    bag = write_paths_bag(tmp_path / 'bag', Paths(t, np.stack([poses, poses])))
    coarse = Paths(t[::5], poses[None, ::5], {'notes': ['from the lab']})
    dataset = save_dataset(tmp_path / 'set.npz', coarse)
    paths = load_measured([bag, dataset], rate_hz=RATE_HZ)
    assert paths.n_paths == 3
    np.testing.assert_allclose(paths.poses[2], poses, atol=1e-12)
    assert any(note.endswith('set.npz: from the lab') for note in paths.info['notes'])
    assert str(bag) in paths.info['inputs'] and str(dataset) in paths.info['inputs']
