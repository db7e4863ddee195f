"""
The same recording given twice: runs whose every sample is the same are said in the notes.

Why: a bag and its copy (or a bag given once directly and once inside a folder under another
name) double every run, and the diagnosis then reports a sharper fit and a larger gain than
the data hold ("gain 108 %"). `sources.expand_sources` refuses the same file named twice;
this check finds the same runs arriving from different files and says so in the notes (and
`diagnose` and `validate` print it). Two real runs never agree in every sample to the last
bit; synthetic ones may (the same seed twice), which is why it is a note, not an error.
"""
from __future__ import annotations

import hashlib

import numpy as np

from octoroach_model.paths import Paths

__all__ = ['REPEATED_RUNS', 'repeated_runs_note']

REPEATED_RUNS = 'hold the same samples as earlier runs'


def repeated_runs_note(paths: Paths) -> str | None:
    """Say which runs of `paths` repeat an earlier run sample for sample; None if none do."""
    first: dict[bytes, int] = {}
    repeats: list[tuple[int, int]] = []
    poses = np.ascontiguousarray(paths.poses)
    for index in range(paths.n_paths):
        key = hashlib.blake2b(poses[index].tobytes(), digest_size=16).digest()
        if key in first:
            repeats.append((index, first[key]))
        else:
            first[key] = index
    if not repeats:
        return None
    index, earlier = repeats[0]
    return (f'{len(repeats)} of {paths.n_paths} runs {REPEATED_RUNS} (run {index} = run '
            f'{earlier}): the same recording given twice, under two names? Each counts as a '
            'run of its own')
