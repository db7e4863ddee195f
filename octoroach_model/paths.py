"""
`Paths`: runs of the robot on one common time grid, the currency between all layers.

Model output, measured runs after splitting and resampling, and everything the validation and
the diagnosis consume are `Paths`. Poses are planar: x [m], y [m], heading [rad], with heading
pi/2 meaning motion along +y (the robot's forward axis maps to (cos heading, sin heading)).

Runs may differ in length (a robot that leaves the capture volume early): a run that ends
before the grid does is NaN after its last sample. NaN appears only in such tails; every run
has at least its first sample. `lengths` says how many samples each run has.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from octoroach_model.arrays import BoolArray, FloatArray, IntArray
from octoroach_model.errors import ShapeError

X, Y, HEADING = 0, 1, 2
# info entries with one value per run, in the runs' order
PER_RUN_INFO = ('sources', 'start_stamps_s')


@dataclass(frozen=True)
class Paths:
    """
    n runs sampled at the same times (each from its own start, some ending early).

    Attributes
    ----------
    t : (T,) seconds from each run's first sample, increasing.
    poses : (n, T, 3) x [m], y [m], heading [rad] (unwrapped along time); NaN after the end
        of a run shorter than the grid.
    info : provenance (seed, parameters, source bags, notes on skipped data); JSON-ready.

    """

    t: FloatArray
    poses: FloatArray
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ('t', 'poses'):         # a user's lists of numbers, as arrays of floats
            value = getattr(self, name)
            if not isinstance(value, np.ndarray):
                try:
                    object.__setattr__(self, name, np.asarray(value, dtype=float))
                except (TypeError, ValueError):
                    from octoroach_model.settings import shown

                    raise ShapeError(f'{name} must be an array of numbers, got '
                                     f'{shown(value)}') from None
        if self.t.ndim != 1:
            raise ShapeError(f't must be (T,), got {self.t.shape}')
        if self.poses.ndim != 3 or self.poses.shape[2] != 3:
            raise ShapeError(f'poses must be (n, T, 3), got {self.poses.shape}')
        if self.poses.shape[1] != self.t.shape[0]:
            raise ShapeError(f'{self.t.shape[0]} times but {self.poses.shape[1]} samples per run')

    @property
    def n_paths(self) -> int:
        return self.poses.shape[0]

    @property
    def rate_hz(self) -> float:
        return float((len(self.t) - 1) / (self.t[-1] - self.t[0])) if len(self.t) > 1 else 0.0

    @property
    def positions(self) -> FloatArray:
        """(n, T, 2) x, y in metres."""
        return self.poses[..., :2]

    @property
    def lengths(self) -> IntArray:
        """(n,) number of samples of each run (the grid's length for a complete run)."""
        return np.isfinite(self.poses[..., 0]).sum(axis=1)

    @property
    def ragged(self) -> bool:
        """Whether some run ends before the grid does."""
        return bool(np.isnan(self.poses[:, -1, 0]).any()) if self.n_paths else False

    @property
    def well_formed(self) -> bool:
        """Every run has its first sample and is NaN only after its end (no holes)."""
        finite: BoolArray = np.asarray(np.isfinite(self.poses).all(axis=2), dtype=bool)
        return bool(finite[:, 0].all() and (finite[:, :-1] >= finite[:, 1:]).all()
                    and (np.isfinite(self.poses).any(axis=2) == finite).all())

    def recording_positions(self) -> tuple[FloatArray, bool]:
        """
        Return each run's place in the recording, 0 (first) to 1 (last), and whether it is known.

        The place is the rank of the run's start time (`info['start_stamps_s']`, which every
        bag reader and data set carries); runs without start times (simulated, or from files
        that have none) are taken in the order they were read, and the flag is False.
        """
        n = self.n_paths
        stamps = self.info.get('start_stamps_s')
        known = (isinstance(stamps, (list, tuple, np.ndarray)) and len(stamps) == n
                 and all(isinstance(s, (int, float, np.number)) and np.isfinite(s)
                         for s in stamps))
        if known:
            ranks = np.empty(n)
            ranks[np.argsort(np.asarray(stamps, dtype=float), kind='stable')] = np.arange(n)
        else:
            ranks = np.arange(n, dtype=float)
        return (ranks / (n - 1) if n > 1 else np.zeros(n)), bool(known)

    def subset(self, index) -> Paths:
        """
        Return the runs selected by `index` (an index array, slice or boolean mask).

        The info lists that hold one entry per run (PER_RUN_INFO) are selected alike.
        """
        info = dict(self.info)
        picks = np.arange(self.n_paths)[index]
        for key in PER_RUN_INFO:
            values = info.get(key)
            if isinstance(values, (list, tuple)) and len(values) == self.n_paths:
                info[key] = [values[i] for i in picks]
        return Paths(self.t, self.poses[index], info)

    def truncated(self, duration_s: float) -> Paths:
        """Return the runs cut to their first `duration_s` seconds (inclusive)."""
        keep = self.t <= duration_s + 1e-9
        return Paths(self.t[keep], self.poses[:, keep], dict(self.info))

    def cut_to(self, lengths: IntArray) -> Paths:
        """
        Return the runs with run i ending after lengths[i] samples (NaN after).

        Measured runs that left the capture volume early end so; lengths beyond the grid
        change nothing.
        """
        index = np.arange(len(self.t))
        cut = index[None, :] >= np.asarray(lengths)[:, None]
        poses = np.where(cut[..., None], np.nan, self.poses)
        return Paths(self.t, poses, dict(self.info))


def check_paths(value: object) -> None:
    """Refuse what is not Paths in one line: the API's entry points take runs, not file names."""
    if not isinstance(value, Paths):
        from octoroach_model.errors import ParameterError
        from octoroach_model.settings import shown

        raise ParameterError(f'the runs must be Paths (om.load_measured reads them from files, '
                             f'om.simulate makes them), got {shown(value)}')
