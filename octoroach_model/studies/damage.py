"""
Damage like a lab's: runs that end early, frames the motion capture dropped.

A run that leaves the capture volume early is written as poses NaN after its end (the runs of
a `Paths` share one time grid). A dropped frame is filled the way the bag readers fill it: by
linear interpolation between the neighbouring frames that were kept.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from octoroach_model.paths import Paths
from octoroach_model.studies.spec import DamageSpec, Draw


class DamageDone(NamedTuple):
    """What `damage_paths` did: the damaged runs and counts for the table."""

    paths: Paths
    runs_cut: int
    frames_dropped: int


def cut_runs_short(poses: np.ndarray, t: np.ndarray, share: float, cut_at: Draw,
                   rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """
    End round(share * n) runs, chosen at random, at a drawn share of the duration.

    Their poses after that time are NaN. Returns the new poses and how many runs were cut.
    """
    n_runs = poses.shape[0]
    n_cut = int(round(share * n_runs))
    chosen = rng.permutation(n_runs)[:n_cut]
    ends = np.array([cut_at.at(u) for u in rng.random(n_cut)]) * float(t[-1])
    out = poses.copy()
    for run, end in zip(chosen, ends):
        out[run, t > end + 1e-12] = np.nan
    return out, n_cut


def drop_frames(poses: np.ndarray, share: float,
                rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """
    Lose each inner frame with probability `share`, filled as the readers fill it.

    A lost frame is replaced by linear interpolation between the kept frames around it; the
    first and last frames of a run are always kept.
    """
    n_runs, n_samples, _ = poses.shape
    lost = rng.random((n_runs, n_samples)) < share
    lost[:, 0] = lost[:, -1] = False
    out = poses.copy()
    index = np.arange(n_samples)
    for run in np.flatnonzero(lost.any(axis=1)):
        kept = ~lost[run]
        for column in range(poses.shape[2]):
            out[run, ~kept, column] = np.interp(index[~kept], index[kept],
                                                poses[run, kept, column])
    return out, int(lost.sum())


def damage_paths(paths: Paths, damage: DamageSpec, seed: np.random.SeedSequence) -> DamageDone:
    """
    Apply the spec's damage to `paths`: frames dropped first, then runs cut.

    The damage is drawn from `seed`, the replicate's damage seed, so every arm of a
    replicate gets the same damage.
    """
    if not damage.active:
        return DamageDone(paths, 0, 0)
    drop_seed, cut_seed = seed.spawn(2)
    poses, dropped = drop_frames(paths.poses, damage.dropped_frames,
                                 np.random.default_rng(drop_seed))
    poses, cut = cut_runs_short(poses, paths.t, damage.cut_share, damage.cut_at,
                                np.random.default_rng(cut_seed))
    info = {**paths.info, 'damage': {'runs_cut': cut, 'frames_dropped': dropped}}
    return DamageDone(Paths(paths.t, poses, info), cut, dropped)
