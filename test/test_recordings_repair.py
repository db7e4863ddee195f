"""`repair`: a damaged bag becomes complete for every tool, and nothing is lost on the way."""
from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import make_reader
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader, ReaderError

from octoroach_model import simulate
from octoroach_model.cli import repair_main
from octoroach_model.errors import OutputError
from octoroach_model.recordings import BagReader, read_runs, write_paths_bag
from octoroach_model.recordings.bagio.repair import repair_bag


@pytest.fixture(scope='module')
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Write a complete bag of 10 runs (several chunks)."""
    return write_paths_bag(tmp_path_factory.mktemp('whole') / 'runs', simulate(10, seed=8))


def killed_copy(whole: Path, folder: Path, fraction: float = 0.7) -> Path:
    """Copy the bag as a killed recorder leaves it: the .mcap cut, no metadata.yaml."""
    bag = folder / 'runs'
    bag.mkdir(parents=True)
    data = (whole / 'runs_0.mcap').read_bytes()
    (bag / 'runs_0.mcap').write_bytes(data[:int(fraction * len(data))])
    return bag


def stored(bag: Path) -> list[tuple[str, int, bytes]]:
    return [(m.topic, m.log_time_ns, bytes(m.data)) for m in BagReader(bag).messages()]


def any_reader(bag: Path) -> list[tuple[str, int, bytes]]:
    with AnyReader([bag]) as reader:
        return [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]


def indexed(file: Path) -> list[tuple[str, int, bytes]]:
    with file.open('rb') as stream:
        reader = make_reader(stream)
        assert reader.get_summary().chunk_indexes  # read through the index, not a scan
        return [(c.topic, m.log_time, bytes(m.data))
                for _, c, m in reader.iter_messages(log_time_order=False)]


def test_a_cut_bag_is_made_complete_with_every_surviving_message(whole: Path,
                                                                 tmp_path: Path) -> None:
    bag = killed_copy(whole, tmp_path)
    damaged_bytes = (bag / 'runs_0.mcap').read_bytes()
    survivors = stored(bag)
    with pytest.raises((ReaderError, FileNotFoundError), match='metadata'):
        Reader(bag).open()  # what other tools say before the repair
    report = repair_bag(bag)
    assert report.repaired and report.messages == len(survivors) > 0
    assert 'truncated MCAP' in report.files[0].damage
    assert (bag / 'runs_0.mcap.damaged').read_bytes() == damaged_bytes  # nothing lost
    assert any_reader(bag) == survivors
    assert indexed(bag / 'runs_0.mcap') == survivors
    with Reader(bag) as reader:
        assert reader.message_count == len(survivors) and reader.ros_distro == 'jazzy'
        assert all(c.digest.startswith('RIHS01_') and c.ext.offered_qos_profiles
                   for c in reader.connections)


def test_the_repaired_bag_reads_as_the_damaged_one_did(whole: Path, tmp_path: Path) -> None:
    bag = killed_copy(whole, tmp_path)
    before = read_runs(bag)
    repair_bag(bag)
    after = read_runs(bag)
    assert len(after.runs) == len(before.runs) < 10
    for old, new in zip(before.runs, after.runs):
        np.testing.assert_array_equal(new.poses, old.poses)
    assert any('cut by the truncation' in note for note in after.notes)
    assert any('repaired after a truncation' in note for note in after.notes)


def test_repair_to_a_new_path_leaves_the_input_untouched(whole: Path, tmp_path: Path) -> None:
    bag = killed_copy(whole, tmp_path / 'in')
    listing, data = sorted(p.name for p in bag.iterdir()), (bag / 'runs_0.mcap').read_bytes()
    report = repair_bag(bag, tmp_path / 'fixed')
    assert sorted(p.name for p in bag.iterdir()) == listing
    assert (bag / 'runs_0.mcap').read_bytes() == data
    assert report.bag == tmp_path / 'fixed'
    assert any_reader(tmp_path / 'fixed') == stored(bag)
    with pytest.raises(OutputError, match=r'fixed: exists already'):
        repair_bag(bag, tmp_path / 'fixed')


def test_a_bare_cut_file_becomes_a_bag_directory(whole: Path, tmp_path: Path) -> None:
    data = (whole / 'runs_0.mcap').read_bytes()
    (tmp_path / 'take.mcap').write_bytes(data[:len(data) // 2])
    report = repair_bag(tmp_path / 'take.mcap')
    assert report.bag == tmp_path / 'take'
    assert any_reader(tmp_path / 'take') == stored(tmp_path / 'take.mcap')


def test_a_complete_bag_is_left_alone(whole: Path) -> None:
    before = {p.name: p.stat().st_mtime_ns for p in whole.iterdir()}
    report = repair_bag(whole)
    assert not report.repaired and 'complete already' in report.notes[-1]
    assert {p.name: p.stat().st_mtime_ns for p in whole.iterdir()} == before


def test_a_complete_file_without_metadata_gets_metadata_only(
        whole: Path, tmp_path: Path) -> None:
    bag = killed_copy(whole, tmp_path, fraction=1.0)
    report = repair_bag(bag)
    assert report.repaired and not report.files[0].damage and not report.files[0].kept
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'runs_0.mcap']
    assert any_reader(bag) == any_reader(whole)


def test_an_unreadable_chunk_is_skipped_and_said(whole: Path, tmp_path: Path) -> None:
    with (whole / 'runs_0.mcap').open('rb') as stream:
        chunk = make_reader(stream).get_summary().chunk_indexes[1]
    bag = killed_copy(whole, tmp_path, fraction=1.0)
    data = bytearray((bag / 'runs_0.mcap').read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 8] = b'\xff' * 8  # the chunk's checksum no longer matches
    (bag / 'runs_0.mcap').write_bytes(bytes(data))
    notes: list[str] = []
    kept = list(BagReader(bag, notes).messages())
    assert 0 < len(kept) < len(stored(whole))
    assert any('1 unreadable chunk(s) skipped' in note for note in notes)
    report = repair_bag(bag)
    assert '1 unreadable chunk(s) skipped' in report.files[0].damage
    assert len(any_reader(bag)) == len(kept)


def test_repair_on_the_command_line(whole: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture) -> None:
    bag = killed_copy(whole, tmp_path)
    assert repair_main([str(bag)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['repaired'] and summary['files'][0]['damaged_original'].endswith('.damaged')
    for argv, reason in (([str(tmp_path / 'absent')], 'no such bag'),
                         ([str(bag), '--out', str(bag)], 'exists already')):
        assert repair_main(argv) != 0
        err = capsys.readouterr().err
        assert err.startswith('error: ') and reason in err and err.count('\n') == 1
    (tmp_path / 'old.bag').write_bytes(b'#ROSBAG V2.0\n')
    assert repair_main([str(tmp_path / 'old.bag')]) == 1
    assert 'rosbag reindex' in capsys.readouterr().err


def test_a_repair_killed_midway_is_run_again(whole: Path, tmp_path: Path) -> None:
    """A killed repair left NAME.mcap.partial (and, later, only NAME.mcap.damaged): re-run."""
    bag = killed_copy(whole, tmp_path / 'in')
    survivors = stored(bag)
    damaged = (bag / 'runs_0.mcap').read_bytes()
    (bag / 'runs_0.mcap.partial').write_bytes(damaged[:1000])       # killed while copying
    report = repair_bag(bag)
    assert report.repaired and any('started over' in note for note in report.notes)
    assert any_reader(bag) == survivors and not (bag / 'runs_0.mcap.partial').exists()

    again = killed_copy(whole, tmp_path / 'again')                # killed between the renames
    (again / 'runs_0.mcap').rename(again / 'runs_0.mcap.damaged')
    (again / 'runs_0.mcap.partial').write_bytes(b'half a copy')
    assert repair_main([str(again)]) == 0
    assert any_reader(again) == survivors
    assert (again / 'runs_0.mcap.damaged').read_bytes() == damaged

    linked = killed_copy(whole, tmp_path / 'linked')               # never written through
    victim = tmp_path / 'victim.txt'
    victim.write_text('keep')
    (linked / 'runs_0.mcap.partial').symlink_to(victim)
    with pytest.raises(OutputError, match='not a file a repair left'):
        repair_bag(linked)
    assert victim.read_text() == 'keep'


def test_a_repair_to_a_new_path_killed_midway_leaves_no_path_behind(
        whole: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from octoroach_model.recordings.bagio import repair

    bag = killed_copy(whole, tmp_path / 'in')

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(repair, 'write_metadata_yaml', killed)
    with pytest.raises(KeyboardInterrupt):
        repair_bag(bag, tmp_path / 'fixed')
    monkeypatch.undo()
    assert not (tmp_path / 'fixed').exists()
    assert repair_bag(bag, tmp_path / 'fixed').repaired           # so it runs again
