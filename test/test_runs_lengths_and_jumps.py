"""
Runs of any length are used to their end, and a frame no robot could reach is dropped.

A damaged float (a pose 881 m away) or a marker swap must not decide a validation, and one
run that ended early (the robot left the capture volume) must not shorten every other run.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.recordings import load_measured, write_paths_bag
from octoroach_model.recordings.runs.run_set import JUMP_LIMIT_M, reachable
from octoroach_model.validation import validate_measured, ValidationSettings
from octoroach_model.validation.validate import common_duration

SMALL = ValidationSettings(k=4, seed=2)                      # n = 45: 180 of the 200 runs


def test_a_frame_far_from_its_neighbours_is_unreachable_and_nothing_else_is() -> None:
    t = np.arange(200) / 50.0
    poses = np.column_stack([0.01 * np.sin(t), 0.11 * t, np.pi / 2 + 0.1 * np.sin(4 * t)])
    assert reachable(poses).all()
    damaged = poses.copy()
    damaged[50, 0] += 881.0                               # a corrupted float
    damaged[120:122, 1] += 3 * JUMP_LIMIT_M               # a two-frame marker swap
    damaged[170, 2] += 2.0                                # a heading flipped for a frame
    assert list(np.flatnonzero(~reachable(damaged))) == [50, 120, 121, 170]


@pytest.fixture(scope='module')
def bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, om.Paths]:
    """
    Write 200 runs as an intact bag, and as one with damage.

    The damaged bag has a frame 881 m off and a run that ended at half its duration.
    """
    folder = tmp_path_factory.mktemp('damage')
    runs = om.simulate(200, seed=5, cycles=6)
    damaged = runs.poses.copy()
    damaged[7, 40, 0] += 881.0
    damaged[11, len(runs.t) // 2:] = np.nan
    intact = write_paths_bag(folder / 'intact', runs)
    hurt = write_paths_bag(folder / 'damaged', om.Paths(runs.t, damaged))
    return intact, hurt, runs


def test_the_damaged_frame_is_dropped_and_said_and_the_short_run_kept_to_its_end(bags) -> None:
    _, hurt, runs = bags
    measured = load_measured(hurt)
    assert measured.n_paths == runs.n_paths and measured.well_formed
    assert np.nanmax(np.abs(measured.positions)) < 1.0
    notes = ' '.join(measured.info['notes'])
    assert '1 frame(s) no robot could reach' in notes
    assert sorted(measured.lengths)[0] == len(runs.t) // 2
    assert (np.sort(measured.lengths)[1:] == len(runs.t)).all()   # nobody else was cut


def test_validate_gives_the_same_verdict_on_the_damaged_bag_as_on_the_intact_one(bags) -> None:
    intact, hurt, _ = bags
    results = [validate_measured(load_measured(bag), SMALL, nominal='table2',
                                 sigmas=(0.12, 0.15)) for bag in (intact, hurt)]
    # the frame 881 m off would make every multisample's region useless (violation 1.0); the
    # rest is the noise of drawing other multisamples from 199 runs instead of 200
    assert results[0].accepted == results[1].accepted
    assert abs(results[0].violation - results[1].violation) <= 0.2
    assert any('left out of the paper' in note for note in results[1].notes)


def test_the_common_duration_keeps_most_samples_rather_than_the_shortest_run() -> None:
    runs = om.simulate(40, seed=1, cycles=4)
    lengths = np.full(40, len(runs.t))
    lengths[:3] = [30, 40, 50]                            # three runs end far earlier
    kept, note = common_duration(runs.cut_to(lengths))
    assert kept.n_paths == 37 and len(kept.t) == len(runs.t)
    assert '3 of 40 runs end before' in note


def test_simulated_runs_cut_like_measured_ones_keep_their_full_duration_definitions() -> None:
    effects = {'speed_decay': {'fraction': 0.3}}
    full = om.simulate(30, seed=2, effects=effects)
    lengths = np.full(30, len(full.t))
    lengths[::4] = (0.8 * len(full.t))
    cut = full.cut_to(lengths)
    kept = np.isfinite(cut.poses[..., 0])
    np.testing.assert_array_equal(cut.poses[kept], full.poses[kept])   # T stays the full T
    assert replace(cut).lengths.tolist() == lengths.tolist()
