"""
What the programs say while and after reading: progress from the first second, short runs.

In-process (the command's main function): a reading that will last shows progress lines from
its first second and a short one shows none; `validate` refusing too few runs says how many
were left out as short.
"""
from __future__ import annotations

import numpy as np

import octoroach_model as om
from octoroach_model.cli import validate_main
from octoroach_model.commands import common
from octoroach_model.paths import Paths
from octoroach_model.recordings import read_runs, save_dataset, write_paths_bag


class Clock:
    """A stand-in for time.monotonic that the test moves on."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_reading_progress_starts_in_the_first_second_of_a_long_reading_only(monkeypatch,
                                                                            capsys):
    clock = Clock()
    monkeypatch.setattr(common.time, 'monotonic', clock)
    quick = common.reading_progress('validate')
    for step in range(1, 11):          # all of it read in 1.5 s: nothing said
        clock.now += 0.15
        quick(step / 10, f'reading a.mcap: {step} poses')
    assert capsys.readouterr().err == ''
    long = common.reading_progress('validate')
    clock.now += 0.5
    long(0.02, 'reading big.mcap (1 of 1): 20000 poses')   # before the first second: quiet
    clock.now += 0.6
    long(0.04, 'reading big.mcap (1 of 1): 40000 poses')   # 1.1 s for 4 %: it will last
    clock.now += 0.1
    long(0.045, 'reading big.mcap (1 of 1): 45000 poses')  # less than a percent more
    clock.now += 6.0
    long(0.046, 'reading big.mcap (1 of 1): 46000 poses')  # but 6 s later: said again
    clock.now += 10.0
    long(1.0, 'reading big.mcap (1 of 1): 1000000 poses')
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(']')[0] for line in lines] == [
        '[validate: read   4.0%    1.1s', '[validate: read   4.6%    7.2s',
        '[validate: read 100.0%   17.2s']
    assert lines[0].endswith('reading big.mcap (1 of 1): 40000 poses')


def test_reading_reports_its_share_of_all_inputs(tmp_path):
    paths = om.simulate(4, seed=1, cycles=2)
    first = write_paths_bag(tmp_path / 'first', paths)
    second = write_paths_bag(tmp_path / 'second', paths)
    heard: list[tuple[float, str]] = []
    read_runs([first, second], progress=lambda fraction, message: heard.append(
        (fraction, message)))
    fractions = [fraction for fraction, _ in heard]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert 0.4 < fractions[len(fractions) // 2 - 1] <= 0.6 or len(fractions) == 2
    assert heard[-1][1] == f'reading second (2 of 2): {2 * 4 * len(paths.t)} poses'


def test_validate_refusing_too_few_runs_says_how_many_were_left_out_as_short(
        tmp_path, capsys):
    runs = om.simulate(19, seed=4, cycles=3)
    poses = runs.poses.copy()
    poses[3:, 10:] = np.nan       # 16 of 19 runs end early: the 3 others are compared
    dataset = save_dataset(tmp_path / 'session.npz', Paths(runs.t, poses))
    assert validate_main([str(dataset), '--k', '2', '--epsilon', '0.3', '--delta', '0.3']) == 1
    err = capsys.readouterr().err
    assert err.count('\n') == 1
    assert 'error: validate: 3 runs are too few: n x k = 11 x 2 needs 22 runs' in err
    assert '16 of 19 runs end before 1.50 s (between 0.18 and 0.18 s) and were left out' in err
