"""
Runs: pose streams cut into runs, cleaned, and resampled onto one common time grid.

Policies (also in the package README):

- Splitting. A stream whose bag has a run-marker topic (``/S/run_start`` for ``/vicon/S/S``)
  is cut where each marker arrived; samples before the first marker are ignored. Without
  markers (or with ``use_markers=False``) a run ends at every gap in the stamps longer than
  `gap_s`. Each run's time starts at its first sample.
- Gaps. Inside a marker run a gap longer than `gap_s` (a burst of dropped frames) is bridged
  by linear interpolation and noted; without markers the same gap splits the run. Shorter
  gaps (dropped frames) are always interpolated when resampling.
- Damage. Non-finite poses, frames no robot could reach (a position more than
  JUMP_LIMIT_M, or a heading more than JUMP_LIMIT_RAD, away from the median of the frame and
  its two neighbours on each side: a corrupted float or a marker swap), samples whose stamp
  is far from both neighbours (stray stamps) and repeated stamps are dropped; small
  out-of-order jitter is sorted; a backwards clock jump longer than `gap_s` starts a new run;
  runs with fewer than 2 samples are dropped. In a truncated bag the run cut by the damage is
  dropped when it is shorter than the others. All of it is counted in `RunSet.notes`, never
  raised.
- Lengths. Runs keep all their samples: on the common grid a run that ends before the
  longest one is NaN after its end (see `Paths`), and the notes say how many ended early.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from octoroach_model.errors import DataError
from octoroach_model.paths import HEADING, Paths
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.recordings.poses.readers import iter_pose_samples
from octoroach_model.recordings.poses.streams import median_of_five, Progress
from octoroach_model.recordings.runs.dataset import is_dataset_file, load_dataset
from octoroach_model.recordings.runs.duplicates import repeated_runs_note
from octoroach_model.recordings.sources import expand_sources, MEASURED_SUFFIXES, Sources
from octoroach_model.settings import check_callable, flag, number

DEFAULT_GAP_S = 0.5
DEFAULT_RATE_HZ = 50.0
# A frame this far from the median of its neighbourhood was not reached by the robot: the
# OctoRoACH walks about 11 cm/s (0.4 cm a frame at 30 Hz), the fastest small legged robots a
# few m/s; 5 cm or 30 deg in one frame is a damaged value, not motion.
JUMP_LIMIT_M = 0.05
JUMP_LIMIT_RAD = 0.5236
JUMP_WINDOW = 5


class Run(NamedTuple):
    """
    One run: times from its first sample (strictly increasing), finite poses.

    `poses` is (T, 3) x [m], y [m], heading [rad] unwrapped along the run; `source` names the
    bag, topic and run index; `start_stamp_s` is the absolute stamp of the first sample (NaN
    when unknown, e.g. runs from a data set).
    """

    t: np.ndarray
    poses: np.ndarray
    source: str
    start_stamp_s: float

    @property
    def duration_s(self) -> float:
        return float(self.t[-1]) if len(self.t) else 0.0


@dataclass
class RunSet:
    """Runs read from one or many sources, and plain-word notes on what was skipped/repaired."""

    runs: list[Run] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.runs)

    @classmethod
    def combine(cls, sets: Iterable[RunSet]) -> RunSet:
        """All runs and notes of `sets`, in order."""
        combined = cls()
        for run_set in sets:
            combined.runs.extend(run_set.runs)
            combined.notes.extend(run_set.notes)
        return combined

    @classmethod
    def from_paths(cls, paths: Paths, source: str = 'paths') -> RunSet:
        """Each path as a run; non-finite samples are dropped (and interpolated later)."""
        run_set = cls(notes=[f'{source}: {note}' for note in paths.info.get('notes', [])])
        stamps = paths.info.get('start_stamps_s')
        if not (isinstance(stamps, list) and len(stamps) == paths.n_paths):
            stamps = [None] * paths.n_paths
        dropped_samples = 0
        for index in range(paths.n_paths):
            finite = np.isfinite(paths.poses[index]).all(axis=1) & np.isfinite(paths.t)
            dropped_samples += int((~finite).sum())
            if finite.sum() < 2:
                run_set.notes.append(f'{source}: path {index} has fewer than 2 finite samples;'
                                     ' dropped')
                continue
            times, poses = paths.t[finite], paths.poses[index][finite].copy()
            poses[:, HEADING] = np.unwrap(poses[:, HEADING])
            stamp = stamps[index]
            start = float(stamp) + float(times[0]) if isinstance(stamp, (int, float)) \
                else float('nan')
            run_set.runs.append(Run(times - times[0], poses, f'{source} path {index}', start))
        if dropped_samples:
            run_set.notes.append(f'{source}: {dropped_samples} non-finite samples dropped')
        return run_set

    def to_paths(self, rate_hz: float = DEFAULT_RATE_HZ,
                 min_duration_s: float | None = None) -> Paths:
        """
        Put the runs on one grid t = 0, 1/rate_hz, ... up to the longest run's end.

        Every run keeps all of its samples; one that ends earlier is NaN after its end. With
        `min_duration_s`, shorter runs are dropped (with a note) first. Each coordinate is
        interpolated linearly (heading is unwrapped already), which fills dropped frames.
        """
        check_grid(rate_hz, min_duration_s)
        runs, notes = list(self.runs), list(self.notes)
        if not runs:
            raise DataError('no runs to resample')
        if min_duration_s is not None:
            short = [run for run in runs if run.duration_s < min_duration_s - 1e-9]
            if short:
                names = ', '.join(run.source for run in short[:3])
                more = f' and {len(short) - 3} more' if len(short) > 3 else ''
                notes.append(f'{len(short)} run(s) shorter than {min_duration_s:g} s dropped: '
                             f'{names}{more}')
                runs = [run for run in runs if run.duration_s >= min_duration_s - 1e-9]
            if not runs:
                longest = max(run.duration_s for run in self.runs)
                raise DataError(f'no run lasts {min_duration_s:g} s (the longest lasts '
                                f'{longest:.3f} s)')
        durations = np.array([run.duration_s for run in runs])
        # a quarter sample of slack: live stamps jitter, and a 2 s run must not lose its end
        lengths = np.floor(durations * rate_hz + 0.25).astype(int) + 1
        if lengths.max() < 2:
            raise DataError(f'the longest run lasts {durations.max():.3f} s, less than one '
                            f'sample at {rate_hz:g} Hz')
        grid = np.arange(int(lengths.max())) / rate_hz
        poses = np.full((len(runs), len(grid), 3), np.nan)
        for index, (run, length) in enumerate(zip(runs, lengths)):
            for column in range(3):
                poses[index, :length, column] = np.interp(grid[:length], run.t,
                                                          run.poses[:, column])
        early = lengths < lengths.max()
        if early.any():
            notes.append(f'{int(early.sum())} of {len(runs)} runs end before the longest '
                         f'({durations.max():.3f} s), between {durations[early].min():.3f} and '
                         f'{durations[early].max():.3f} s; each is used to its end')
        info = {
            'sources': [run.source for run in runs],
            'start_stamps_s': [run.start_stamp_s for run in runs],
            'notes': notes,
            'rate_hz': float(rate_hz),
            'duration_s': float(grid[-1]),
        }
        return Paths(grid, poses, info)


def reachable(poses: np.ndarray) -> np.ndarray:
    """
    Return a (k,) mask, False for the frames a robot could not have reached.

    Those are more than JUMP_LIMIT_M / JUMP_LIMIT_RAD away from the median of the JUMP_WINDOW
    frames around them (themselves included): a single damaged frame, or two in a row,
    cannot move that median.
    """
    if len(poses) < 3:
        return np.ones(len(poses), dtype=bool)
    half = JUMP_WINDOW // 2
    padded = np.concatenate([np.repeat(poses[:1], half, axis=0), poses,
                             np.repeat(poses[-1:], half, axis=0)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, JUMP_WINDOW, axis=0)
    heading = poses[:, HEADING]
    around = np.angle(np.exp(1j * (windows[:, HEADING] - heading[:, None])))
    # x, y and the heading's turn from the frame: each frame's medians in one call
    medians = median_of_five(np.concatenate([windows[:, :2], around[:, None]], axis=1))
    centre = medians[:, :2]                                             # (k, 2)
    off_heading = np.abs(medians[:, 2])
    off_position = np.hypot(*(poses[:, :2] - centre).T)
    return (off_position <= JUMP_LIMIT_M) & (off_heading <= JUMP_LIMIT_RAD)


class _StreamSplitter:
    """Cuts one pose stream into runs chunk by chunk, holding only the run still open."""

    def __init__(self, chunk: PoseChunk, marker_mode: bool, gap_s: float) -> None:
        self.label = f'{chunk.source} {chunk.topic}'
        self.marker_topic = chunk.marker_topic
        self.marker_mode = marker_mode
        self.gap_s = gap_s
        self.gap_ns = int(round(gap_s * 1e9))
        self.sequence = np.zeros(0, dtype=np.int64)
        self.stamp = np.zeros(0, dtype=np.int64)
        self.poses = np.zeros((0, 3))
        self.open_run_counts = not marker_mode  # in marker mode: only after a marker
        self.runs: list[Run] = []
        self.notes: list[str] = []
        self.counts: Counter[str] = Counter()
        self.runs_with_missing_frames = 0

    def feed(self, chunk: PoseChunk) -> None:
        poses = chunk.poses
        finite = np.isfinite(poses).all(axis=1)
        self.counts['non-finite'] += int((~finite).sum())
        sequence = np.concatenate([self.sequence, chunk.sequence[finite]])
        stamp = np.concatenate([self.stamp, chunk.stamp_ns[finite]])
        poses = np.concatenate([self.poses, poses[finite]])
        sequence, stamp, poses = self._drop_strays(sequence, stamp, poses)

        if self.marker_mode:
            marker_starts = np.searchsorted(sequence, chunk.marker_sequence, side='right')
        else:
            marker_starts = np.zeros(0, dtype=np.int64)
        step = np.diff(stamp)
        backwards = step < -self.gap_ns
        self.counts['clock jumps'] += int(backwards.sum())
        cuts = backwards if self.marker_mode else backwards | (step > self.gap_ns)
        starts = np.union1d(marker_starts, np.flatnonzero(cuts) + 1).astype(np.int64)
        starts_at_marker = np.isin(starts, marker_starts)
        edges = np.concatenate([[0], starts, [len(stamp)]])
        counts = self.open_run_counts
        for segment in range(len(edges) - 1):
            if segment > 0 and starts_at_marker[segment - 1]:
                counts = True
            low, high = int(edges[segment]), int(edges[segment + 1])
            if segment == len(edges) - 2 and not chunk.is_last:
                self.sequence, self.stamp = sequence[low:high], stamp[low:high]
                self.poses, self.open_run_counts = poses[low:high], counts
            else:
                self._close(stamp[low:high], poses[low:high], counts)
        if chunk.is_last:
            if chunk.truncated:
                self._drop_cut_run()
            self._write_notes()

    def _drop_strays(self, sequence: np.ndarray, stamp: np.ndarray,
                     poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Drop single samples whose stamp jumps away and straight back (a corrupt stamp)."""
        if len(stamp) < 3:
            return sequence, stamp, poses
        before = np.abs(stamp[1:-1] - stamp[:-2])
        after = np.abs(stamp[2:] - stamp[1:-1])
        around = np.abs(stamp[2:] - stamp[:-2])
        stray = (before > self.gap_ns) & (after > self.gap_ns) & (around <= self.gap_ns)
        if not stray.any():
            return sequence, stamp, poses
        self.counts['stray'] += int(stray.sum())
        keep = np.concatenate([[True], ~stray, [True]])
        return sequence[keep], stamp[keep], poses[keep]

    def _close(self, stamp: np.ndarray, poses: np.ndarray, counts: bool) -> None:
        if len(stamp) == 0:
            return
        if not counts:
            self.counts['before marker'] += len(stamp)
            return
        step = np.diff(stamp)
        if (step < 0).any():
            self.counts['out of order'] += int((step < 0).sum())
            order = np.argsort(stamp, kind='stable')
            stamp, poses = stamp[order], poses[order]
        fresh = np.concatenate([[True], np.diff(stamp) > 0])
        self.counts['duplicate'] += int((~fresh).sum())
        stamp, poses = stamp[fresh], poses[fresh].copy()
        reached = reachable(poses)
        self.counts['jump'] += int((~reached).sum())
        stamp, poses = stamp[reached], poses[reached]
        if len(stamp) < 2:
            self.counts['short'] += 1
            return
        poses[:, HEADING] = np.unwrap(poses[:, HEADING])
        index = len(self.runs)
        step = np.diff(stamp)
        long_gaps = step[step > self.gap_ns]
        if len(long_gaps):
            self.notes.append(f'{self.label} run {index}: {len(long_gaps)} gap(s) longer than '
                              f'{self.gap_s:g} s (up to {long_gaps.max() / 1e9:.2f} s) bridged '
                              'by interpolation')
        period = float(np.median(step))
        late = step > 1.5 * period
        if late.any():
            self.counts['missing frames'] += int(np.round(step[late] / period).sum()
                                                 - late.sum())
            self.runs_with_missing_frames += 1
        self.runs.append(Run((stamp - stamp[0]) / 1e9, poses, f'{self.label} run {index}',
                             stamp[0] / 1e9))

    def _drop_cut_run(self) -> None:
        """In a truncated bag the last run is cut short by the damage: drop it if it shows."""
        if len(self.runs) < 2:
            return
        last = self.runs[-1]
        usual = float(np.median([run.duration_s for run in self.runs[:-1]]))
        period = float(np.median(np.diff(last.t)))
        if last.duration_s < usual - 1.5 * period:
            self.runs.pop()
            self.notes.append(f'{last.source}: cut by the truncation ({last.duration_s:.2f} s '
                              f'of the usual {usual:.2f} s); dropped')

    def _write_notes(self) -> None:
        label, counts = self.label, self.counts
        how = (f'split by run markers on {self.marker_topic}' if self.marker_mode
               else f'split by gaps longer than {self.gap_s:g} s')
        summary = [f'{label}: {len(self.runs)} run(s), {how}']
        plain = {
            'non-finite': '{} non-finite pose(s) dropped',
            'jump': ('{} frame(s) no robot could reach (more than '
                     f'{JUMP_LIMIT_M * 100:g} cm or {np.degrees(JUMP_LIMIT_RAD):.0f} deg from '
                     'their neighbours) dropped'),
            'stray': '{} sample(s) with a stray stamp (far from both neighbours) dropped',
            'out of order': '{} out-of-order sample(s) sorted back into time order',
            'duplicate': '{} sample(s) with a repeated stamp dropped',
            'clock jumps': '{} backwards clock jump(s) longer than the gap: new run at each',
            'before marker': '{} sample(s) before the first run marker ignored',
            'short': '{} run(s) with fewer than 2 samples dropped',
        }
        summary += [f'{label}: ' + text.format(counts[key])
                    for key, text in plain.items() if counts[key]]
        if counts['missing frames']:
            summary.append(f'{label}: {counts["missing frames"]} missing frame(s) in '
                           f'{self.runs_with_missing_frames} run(s), interpolated when '
                           'resampled')
        self.notes[:0] = summary


def checked_gap(gap_s: float) -> float:
    """Return `gap_s` as a float; ParameterError or DataError unless a positive number."""
    gap_s = number('gap_s', gap_s)
    if not (np.isfinite(gap_s) and gap_s > 0):
        raise DataError(f'gap_s must be a positive number of seconds, got {gap_s}')
    return gap_s


def check_grid(rate_hz: float, min_duration_s: float | None) -> None:
    """Raise DataError unless the grid's rate is positive and a shortest duration finite."""
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f'sample rate must be a positive number of Hz, got {rate_hz}')
    if min_duration_s is not None and not (np.isfinite(min_duration_s) and min_duration_s >= 0):
        raise DataError(f'min_duration_s must be a non-negative number of seconds, got '
                        f'{min_duration_s}')


def read_runs(sources: Sources, *, topic: str | None = None, gap_s: float = DEFAULT_GAP_S,
              use_markers: bool = True, options: ReadOptions | None = None,
              progress: Progress | None = None) -> RunSet:
    """
    Read the runs of every pose stream in `sources` (bags, motion-capture files, folders).

    `options` says where the pose is (topic, /tf frame, subject, axes); `topic` is the same
    as ``ReadOptions(topic=...)``. Splitting, cleaning and what is noted: see the module
    docstring; a stream too sparse to form runs at `gap_s` is refused (`streams`).
    `progress(fraction, message)` hears how far the reading has got. Raises BagError for an
    unreadable source and DataError when no run is left.
    """
    check_callable('progress', progress)
    use_markers = flag('use_markers', use_markers)
    gap_s = checked_gap(gap_s)
    notes: list[str] = []
    splitters: dict[tuple[str, str], _StreamSplitter] = {}
    for chunk in iter_pose_samples(sources, topic=topic, notes=notes, options=options,
                                   gap_s=gap_s, progress=progress):
        key = (chunk.source, chunk.topic)
        splitter = splitters.get(key)
        if splitter is None:
            marker_mode = use_markers and bool(chunk.marker_topic)
            splitter = splitters[key] = _StreamSplitter(chunk, marker_mode, gap_s)
        splitter.feed(chunk)
        if chunk.is_last:
            notes.extend(splitter.notes)
    runs = [run for splitter in splitters.values() for run in splitter.runs]
    if not runs:
        names = ', '.join(sorted({source for source, _ in splitters})) or str(sources)
        reasons = '; '.join(notes[-3:]) or 'no pose samples'
        raise DataError(f'no runs left after cleaning in {names} ({reasons})')
    return RunSet(runs, notes)


def load_measured(sources: Sources, *, rate_hz: float = DEFAULT_RATE_HZ,
                  gap_s: float = DEFAULT_GAP_S, topic: str | None = None,
                  min_duration_s: float | None = None, use_markers: bool = True,
                  options: ReadOptions | None = None,
                  progress: Progress | None = None) -> Paths:
    """
    Measured runs from bags, motion-capture files and/or data sets (.npz), on one grid.

    `options` (and `topic`): where the pose is, see `read_runs`; `progress` hears how far the
    reading has got. Notes on everything converted, skipped or repaired are in
    ``.info['notes']``.
    """
    check_callable('progress', progress)
    use_markers = flag('use_markers', use_markers)
    check_grid(number('rate_hz', rate_hz), None if min_duration_s is None
               else number('min_duration_s', min_duration_s))    # before reading anything
    checked_gap(gap_s)
    found = expand_sources(sources, suffixes=MEASURED_SUFFIXES)
    datasets = [path for path in found if is_dataset_file(path)]
    bags = [path for path in found if not is_dataset_file(path)]
    sets = [read_runs(bags, topic=topic, gap_s=gap_s, use_markers=use_markers,
                      options=options, progress=progress)] if bags else []
    sets += [RunSet.from_paths(load_dataset(path), source=str(path)) for path in datasets]
    paths = RunSet.combine(sets).to_paths(rate_hz, min_duration_s)
    repeated = repeated_runs_note(paths)    # the same recording under two names
    if repeated:
        paths.info.setdefault('notes', []).append(repeated)
    paths.info['inputs'] = [str(Path(path)) for path in found]
    return paths
