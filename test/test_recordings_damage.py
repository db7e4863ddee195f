"""Damaged bags and streams: bad input is a one-line BagError/DataError, damaged data a note."""
from __future__ import annotations

from pathlib import Path

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from octoroach_model.errors import BagError, DataError
from octoroach_model.paths import Paths
from octoroach_model.recordings import (
    DEFAULT_POSE_TOPIC,
    iter_pose_samples,
    load_measured,
    PoseBagWriter,
    read_runs,
    write_paths_bag,
)

RATE_HZ = 50.0
PERIOD_NS = 20_000_000
START_NS = 1_700_000_000 * 10**9


def wavy_paths(n_runs: int = 10, duration_s: float = 5.0) -> Paths:
    """Smooth, distinct runs; smooth so that linear interpolation of gaps stays close."""
    t = np.arange(int(duration_s * RATE_HZ) + 1) / RATE_HZ
    phase = np.linspace(0.0, 1.0, n_runs)[:, None]
    x = 0.05 * np.sin(1.5 * t + phase)
    y = 0.2 * t + 0.01 * phase
    heading = np.pi / 2 + 0.3 * np.sin(t + phase)
    return Paths(t, np.stack([x, y, heading], axis=-1))


def write_stream(path: Path, stamps_ns: np.ndarray, poses: np.ndarray,
                 marker_at: list[int] | None = None) -> Path:
    """Write samples in the given (arrival) order; a marker precedes each index in marker_at."""
    log_times = START_NS + np.arange(len(stamps_ns)) * PERIOD_NS  # receive clock: monotonic
    with PoseBagWriter(path, marker_topic='/octoroach/run_start' if marker_at else None) as bag:
        edges = sorted(set(marker_at or []) | {0, len(stamps_ns)})
        for run_index, (low, high) in enumerate(zip(edges[:-1], edges[1:])):
            if marker_at and low in marker_at:
                bag.write_marker(run_index, int(log_times[low]))
            bag.write_poses(stamps_ns[low:high], poses[low:high], log_time_ns=log_times[low:high])
    return path


def clean_stream(n_runs: int = 3, samples: int = 100) -> tuple[np.ndarray, np.ndarray, list]:
    """Make runs of `samples` at 50 Hz 1.5 s apart: stamps, poses, run start indices."""
    stamps, poses, starts = [], [], []
    for run in range(n_runs):
        starts.append(run * samples)
        start = START_NS + run * (samples * PERIOD_NS + 1_500_000_000)
        stamps.append(start + np.arange(samples) * PERIOD_NS)
        k = np.arange(samples)
        poses.append(np.column_stack([0.001 * k, 0.004 * k, np.full(samples, 1.0 + 0.5 * run)]))
    return np.concatenate(stamps), np.concatenate(poses), starts


@pytest.fixture(scope='module')
def truth() -> Paths:
    return wavy_paths()


@pytest.fixture(scope='module')
def bag(tmp_path_factory: pytest.TempPathFactory, truth: Paths) -> Path:
    return write_paths_bag(tmp_path_factory.mktemp('damage') / 'runs', truth)


# --- input that is not a usable bag: one-line errors naming the file


def test_a_missing_path_is_a_bag_error(tmp_path: Path) -> None:
    with pytest.raises(BagError, match=r'absent: no such file or directory'):
        read_runs(tmp_path / 'absent')


def test_a_file_that_is_not_mcap_is_a_bag_error(tmp_path: Path) -> None:
    text = tmp_path / 'notes.mcap'
    text.write_text('these are not poses')
    with pytest.raises(BagError, match=r'notes\.mcap: not an MCAP file'):
        read_runs(text)


def test_an_empty_file_is_a_bag_error(tmp_path: Path) -> None:
    (tmp_path / 'empty.mcap').touch()
    with pytest.raises(BagError, match=r'empty\.mcap: not an MCAP file \(an empty file\)'):
        read_runs(tmp_path / 'empty.mcap')


def test_an_empty_directory_is_a_bag_error(tmp_path: Path) -> None:
    (tmp_path / 'nothing').mkdir()
    with pytest.raises(BagError, match=r'nothing: empty directory'):
        read_runs(tmp_path / 'nothing')


def test_a_bag_without_a_pose_topic_lists_its_topics(tmp_path: Path) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(tmp_path / 'chatter', version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection('/chatter', 'std_msgs/msg/String', typestore=store)
        message = store.types['std_msgs/msg/String'](data='hello')
        writer.write(connection, START_NS, store.serialize_cdr(message, 'std_msgs/msg/String'))
    with pytest.raises(BagError, match=r'chatter: no pose topic .*it has /chatter '
                                       r'\[std_msgs/msg/String\]'):
        read_runs(tmp_path / 'chatter')


def test_the_vicon_topic_with_the_wrong_type_is_a_bag_error(tmp_path: Path) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(tmp_path / 'wrong', version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(DEFAULT_POSE_TOPIC, 'std_msgs/msg/String',
                                           typestore=store)
        message = store.types['std_msgs/msg/String'](data='x=1')
        writer.write(connection, START_NS, store.serialize_cdr(message, 'std_msgs/msg/String'))
    with pytest.raises(BagError, match=rf'wrong: topic {DEFAULT_POSE_TOPIC} has type '
                                       r'std_msgs/msg/String, expected'):
        read_runs(tmp_path / 'wrong')


def test_an_explicit_topic_that_is_absent_is_a_bag_error(bag: Path) -> None:
    with pytest.raises(BagError, match=r'no topic /vicon/other/other; it has '):
        read_runs(bag, topic='/vicon/other/other')


def test_a_sqlite3_bag_without_a_pose_topic_lists_its_topics(tmp_path: Path) -> None:
    with Writer(tmp_path / 'old', version=9) as writer:
        writer.add_connection('/chatter', 'std_msgs/msg/String',
                              typestore=get_typestore(Stores.ROS2_JAZZY))
    with pytest.raises(BagError, match=r'old: no pose topic .*it has /chatter '
                                       r'\[std_msgs/msg/String\]'):
        read_runs(tmp_path / 'old')


@pytest.mark.parametrize('old, new, reason', [
    ('storage_identifier: mcap', 'storage_identifier: SECRETSTORE',
     r'odd: storage_identifier, text \(11 characters, not shown\), is not supported, only mcap '
     'and sqlite3'),
    ('storage_identifier: mcap', 'storage_identifier: mcapp', r'\(did you mean mcap\?\)'),
    ('  - odd_0.mcap\n', '  - odd_0.mcap\n  - ../SECRET.mcap\n',
     'metadata.yaml: entry 2 of 2 of relative_file_paths names a file outside the bag '
     'directory'),
], ids=['unknown storage', 'a typo of a storage', 'a file outside the bag'])
def test_a_metadata_yaml_refused_says_which_entry_without_quoting_it(
        tmp_path: Path, old: str, new: str, reason: str) -> None:
    """Any process may write a bag: what its metadata.yaml says is never quoted back."""
    bag = write_paths_bag(tmp_path / 'odd', wavy_paths(1, 1.0))
    text = (bag / 'metadata.yaml').read_text()
    assert old in text
    (bag / 'metadata.yaml').write_text(text.replace(old, new))
    with pytest.raises(BagError, match=reason) as raised:
        read_runs(bag)
    assert 'SECRET' not in str(raised.value) and '\n' not in str(raised.value)


def test_a_file_metadata_yaml_lists_but_the_bag_lacks_is_noted_by_its_entry(
        tmp_path: Path) -> None:
    bag = write_paths_bag(tmp_path / 'odd', wavy_paths(1, 1.0))
    text = (bag / 'metadata.yaml').read_text()
    (bag / 'metadata.yaml').write_text(text.replace('  - odd_0.mcap\n',
                                                    '  - odd_0.mcap\n  - SECRET_1.mcap\n'))
    (said,) = [note for note in read_runs(bag).notes if 'missing' in note]
    assert said.endswith('files listed in metadata.yaml are missing: entry 2 of 2 of '
                         'relative_file_paths') and 'SECRET' not in said


def test_a_bag_whose_samples_are_all_unusable_is_a_data_error(tmp_path: Path) -> None:
    write_stream(tmp_path / 'nan', START_NS + np.arange(20) * PERIOD_NS, np.full((20, 3), np.nan))
    with pytest.raises(DataError, match=r'no runs left after cleaning in .*nan'):
        read_runs(tmp_path / 'nan')


# --- damaged files: read what is there, say what is lost


def test_a_truncated_mcap_gives_the_runs_before_the_cut(bag: Path, truth: Paths,
                                                        tmp_path: Path) -> None:
    data = (bag / 'runs_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:int(0.6 * len(data))])
    run_set = read_runs(cut)
    n_back = len(run_set.runs)
    assert 4 <= n_back < truth.n_paths
    back = run_set.to_paths(rate_hz=RATE_HZ)
    np.testing.assert_allclose(back.poses, truth.poses[:n_back], atol=1e-9)
    truncation = [note for note in run_set.notes if 'truncated MCAP' in note]
    assert len(truncation) == 1 and 'messages, the rest is lost' in truncation[0]
    assert any('cut by the truncation' in note for note in run_set.notes)


@pytest.mark.parametrize('fraction', [0.0001, 0.02, 0.3, 0.97, 0.9999])
def test_a_cut_at_any_byte_is_read_without_an_exception(bag: Path, tmp_path: Path,
                                                        fraction: float) -> None:
    data = (bag / 'runs_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:max(8, int(fraction * len(data)))])
    try:
        run_set = read_runs(cut)
    except (BagError, DataError) as error:
        assert 'truncated MCAP' in str(error) or 'no runs left' in str(error)
    else:
        assert all(np.all(np.diff(run.t) > 0) for run in run_set.runs)


def test_a_bag_without_metadata_yaml_is_read_from_its_mcap_files(bag: Path, truth: Paths,
                                                                 tmp_path: Path) -> None:
    killed = tmp_path / 'killed'
    killed.mkdir()
    data = (bag / 'runs_0.mcap').read_bytes()
    (killed / 'killed_0.mcap').write_bytes(data[:int(0.8 * len(data))])
    run_set = read_runs(killed)
    assert 0 < len(run_set.runs) < truth.n_paths
    assert any('no metadata.yaml' in note for note in run_set.notes)
    assert any('truncated MCAP' in note for note in run_set.notes)


def test_non_finite_poses_are_dropped_and_noted(tmp_path: Path) -> None:
    stamps, poses, starts = clean_stream()
    poses[[5, 6, 150], 0] = np.nan
    poses[200, 2] = np.inf
    run_set = read_runs(write_stream(tmp_path / 'nan', stamps, poses, starts))
    assert [len(run.t) for run in run_set.runs] == [98, 99, 99]
    assert any('4 non-finite pose(s) dropped' in note for note in run_set.notes)
    assert all(np.isfinite(run.poses).all() for run in run_set.runs)


def test_dropped_frames_are_interpolated_close_to_the_truth(tmp_path: Path,
                                                            truth: Paths) -> None:
    rng = np.random.default_rng(3)
    n, length = truth.poses.shape[:2]
    keep = rng.random((n, length)) > 0.05
    keep[:, [0, -1]] = True  # the run's span is known
    bag = tmp_path / 'dropped'
    offsets_ns = np.round(truth.t * 1e9).astype(np.int64)
    with PoseBagWriter(bag) as writer:
        for run in range(n):
            stamps = START_NS + run * 10**10 + offsets_ns
            writer.write_marker(run, int(stamps[0]))
            writer.write_poses(stamps[keep[run]], truth.poses[run][keep[run]])
    run_set = read_runs(bag)
    back = run_set.to_paths(rate_hz=RATE_HZ)
    np.testing.assert_allclose(back.poses, truth.poses, atol=1e-3)
    missing = int((~keep).sum())
    assert any(f'{missing} missing frame(s)' in note for note in run_set.notes)


def test_a_one_second_burst_is_bridged_in_marker_runs_and_splits_without(
        tmp_path: Path, truth: Paths) -> None:
    offsets_ns = np.round(truth.t * 1e9).astype(np.int64)
    burst = (truth.t > 2.0) & (truth.t <= 3.0)
    for name, markers in (('with', True), ('without', False)):
        with PoseBagWriter(tmp_path / name, marker_topic=None if not markers else
                           '/octoroach/run_start') as writer:
            for run in range(3):
                stamps = START_NS + run * 10**10 + offsets_ns
                if markers:
                    writer.write_marker(run, int(stamps[0]))
                writer.write_poses(stamps[~burst], truth.poses[run][~burst])
    bridged = read_runs(tmp_path / 'with')
    assert len(bridged.runs) == 3
    assert sum('bridged by interpolation' in note for note in bridged.notes) == 3
    back = bridged.to_paths(rate_hz=RATE_HZ)
    np.testing.assert_allclose(back.poses[:, ~burst], truth.poses[:3, ~burst], atol=1e-9)
    np.testing.assert_allclose(back.poses, truth.poses[:3], atol=0.05)
    split = read_runs(tmp_path / 'without')
    assert len(split.runs) == 6


def test_duplicate_and_out_of_order_stamps_are_repaired(tmp_path: Path) -> None:
    stamps, poses, starts = clean_stream()
    order = np.arange(len(stamps))
    order[[10, 11]] = order[[11, 10]]  # two samples arrive swapped
    order[[150, 151]] = order[[151, 150]]
    order = np.insert(order, 50, 49)  # one sample arrives twice
    run_set = read_runs(write_stream(tmp_path / 'jitter', stamps[order], poses[order], [
        0, 101, 201]))
    assert [len(run.t) for run in run_set.runs] == [100, 100, 100]
    for run, first in zip(run_set.runs, (0, 100, 200)):
        np.testing.assert_allclose(run.poses, poses[first:first + 100])
    assert any('2 out-of-order sample(s) sorted' in note for note in run_set.notes)
    assert any('1 sample(s) with a repeated stamp dropped' in note for note in run_set.notes)


def test_a_backwards_clock_jump_starts_a_new_run(tmp_path: Path) -> None:
    stamps, poses, starts = clean_stream(n_runs=1, samples=200)
    stamps[120:] -= 5 * 10**9  # the VICON clock is set back by 5 s mid-run
    for name, markers in (('marked', starts), ('unmarked', None)):
        run_set = read_runs(write_stream(tmp_path / name, stamps, poses, markers))
        assert [len(run.t) for run in run_set.runs] == [120, 80]
        assert any('1 backwards clock jump(s)' in note for note in run_set.notes)


def test_a_single_stray_stamp_is_dropped_without_splitting_the_run(tmp_path: Path) -> None:
    stamps, poses, _ = clean_stream(n_runs=1, samples=100)
    stamps[40] += 7 * 10**9
    run_set = read_runs(write_stream(tmp_path / 'stray', stamps, poses))
    assert [len(run.t) for run in run_set.runs] == [99]
    assert any('1 sample(s) with a stray stamp' in note for note in run_set.notes)


def test_runs_shorter_than_min_duration_are_dropped_with_a_note(
        tmp_path: Path) -> None:
    stamps, poses, starts = clean_stream(n_runs=3, samples=100)
    keep = np.ones(len(stamps), dtype=bool)
    keep[130:200] = False  # run 1 lasts 0.58 s instead of 1.98 s
    bag = write_stream(tmp_path / 'short', stamps[keep], poses[keep], [0, 100, 130])
    paths = load_measured(bag, min_duration_s=1.5)
    assert paths.n_paths == 2
    assert paths.t[-1] == pytest.approx(1.98)
    assert any('1 run(s) shorter than 1.5 s dropped' in note for note in paths.info['notes'])
    everything = load_measured(bag)
    assert everything.t[-1] == pytest.approx(1.98)      # the short run is kept to its end
    assert sorted(everything.lengths) == [30, 100, 100]


def test_a_run_with_a_single_sample_is_dropped_with_a_note(tmp_path: Path) -> None:
    stamps, poses, starts = clean_stream(n_runs=3, samples=100)
    keep = np.ones(len(stamps), dtype=bool)
    keep[101:200] = False
    run_set = read_runs(write_stream(tmp_path / 'lonely', stamps[keep], poses[keep],
                                     [0, 100, 101]))
    assert len(run_set.runs) == 2
    assert any('1 run(s) with fewer than 2 samples dropped' in note for note in run_set.notes)


# --- random damage never crashes the reader


@st.composite
def damaged_streams(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, list[int] | None]:
    stamps, poses, starts = clean_stream(n_runs=draw(st.integers(1, 3)),
                                         samples=draw(st.integers(2, 60)))
    size = len(stamps)
    index = st.integers(0, size - 1)
    order = np.arange(size)
    for i in draw(st.lists(index, max_size=4)):  # neighbours swapped
        j = min(i + 1, size - 1)
        order[[i, j]] = order[[j, i]]
    repeated = draw(st.lists(index, max_size=4))  # samples that arrive twice
    order = np.insert(order, repeated, order[repeated])
    stamps, poses = stamps[order].copy(), poses[order].copy()
    keep = np.ones(len(stamps), dtype=bool)
    keep[draw(st.lists(st.integers(0, len(stamps) - 1), max_size=20))] = False
    for i in draw(st.lists(st.integers(0, len(stamps) - 1), max_size=5)):
        poses[i, draw(st.integers(0, 2))] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    if draw(st.booleans()):
        jump_at = draw(st.integers(0, len(stamps) - 1))
        stamps[jump_at:] += draw(st.integers(-10**10, 10**10))
    for i in draw(st.lists(st.integers(0, len(stamps) - 1), max_size=3)):
        stamps[i] = draw(st.integers(0, 2 * START_NS))  # a corrupt stamp
    first_positions = [int(np.argmax(order == start)) for start in starts]
    position = np.cumsum(keep) - 1
    markers = sorted({int(position[p]) for p in first_positions if keep[p]})
    with_markers = draw(st.booleans()) and markers
    return stamps[keep], poses[keep], markers if with_markers else None


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(damaged_streams())
def test_random_damage_gives_clean_runs_or_a_domain_error(
        tmp_path_factory: pytest.TempPathFactory,
        stream: tuple[np.ndarray, np.ndarray, list[int] | None]) -> None:
    stamps, poses, markers = stream
    bag = tmp_path_factory.mktemp('random') / 'bag'
    if len(stamps) == 0:
        return
    write_stream(bag, np.maximum(stamps, 0), poses, markers)
    try:
        run_set = read_runs(bag)
        paths = run_set.to_paths()
    except (BagError, DataError):
        return
    for run in run_set.runs:
        assert np.all(np.isfinite(run.t)) and np.all(np.diff(run.t) > 0)
        assert run.t[0] == 0.0 and np.all(np.isfinite(run.poses))
    assert paths.well_formed
    assert sum(len(chunk.x) for chunk in iter_pose_samples(bag)) == len(stamps)
